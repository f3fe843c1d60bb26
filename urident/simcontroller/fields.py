"""The RTDE field tables: which output and input names the simulated controller knows, their RTDE
types, and from which controller version on they exist.

Types follow UR's RTDE guide. ur_rtde ignores the types a controller declares and decodes each
output with its own table, so for every name ur_rtde knows the type here must equal ur_rtde's
(``tests/test_simcontroller_protocol.py`` checks this against a copy of ur_rtde 1.6.5's table).
Names not listed, or not yet available in the served version, are answered ``NOT_FOUND`` as a real
controller does.

Output values come from a snapshot object (:class:`urident.simcontroller.snapshot.Snapshot`):
field ``name`` reads attribute ``name``; ``output_int_register_N`` / ``output_double_register_N``
read index ``N`` of ``output_int_registers`` / ``output_double_registers``.
"""

from __future__ import annotations

from dataclasses import dataclass
from operator import attrgetter
from typing import Callable

Version = tuple[int, ...]


@dataclass(frozen=True)
class FieldInfo:
    rtde_type: str
    cb3_since: Version | None = (3, 0)        # None: not on CB3 controllers
    e_series_since: Version | None = (5, 0)   # None: not on e-Series controllers

    def available(self, version: Version) -> bool:
        since = self.cb3_since if version[0] < 5 else self.e_series_since
        return since is not None and tuple(version) >= since


_V6D, _V3D, _D = "VECTOR6D", "VECTOR3D", "DOUBLE"

OUTPUT_FIELDS: dict[str, FieldInfo] = {
    "timestamp": FieldInfo(_D),
    "target_q": FieldInfo(_V6D),
    "target_qd": FieldInfo(_V6D),
    "target_qdd": FieldInfo(_V6D),
    "target_current": FieldInfo(_V6D),
    "target_moment": FieldInfo(_V6D),
    "actual_q": FieldInfo(_V6D),
    "actual_qd": FieldInfo(_V6D),
    "actual_current": FieldInfo(_V6D),
    "actual_current_window": FieldInfo(_V6D),
    "actual_current_as_torque": FieldInfo(_V6D, None, (5, 23)),   # 10.11 on PolyScope X
    "target_gravity": FieldInfo(_V3D, None, (5, 26)),             # 10.12 on PolyScope X
    "joint_control_output": FieldInfo(_V6D),
    "actual_TCP_pose": FieldInfo(_V6D),
    "actual_TCP_speed": FieldInfo(_V6D),
    "actual_TCP_force": FieldInfo(_V6D),
    "target_TCP_pose": FieldInfo(_V6D),
    "target_TCP_speed": FieldInfo(_V6D),
    "tcp_offset": FieldInfo(_V6D),
    "actual_digital_input_bits": FieldInfo("UINT64"),
    "actual_configurable_digital_input_bits": FieldInfo("UINT64"),
    "joint_temperatures": FieldInfo(_V6D),
    "actual_execution_time": FieldInfo(_D),
    "robot_mode": FieldInfo("INT32"),
    "joint_mode": FieldInfo("VECTOR6INT32"),
    "safety_mode": FieldInfo("INT32"),
    "safety_status": FieldInfo("INT32", (3, 10), (5, 4)),
    "actual_tool_accelerometer": FieldInfo(_V3D),
    "speed_scaling": FieldInfo(_D),
    "target_speed_fraction": FieldInfo(_D),
    "actual_momentum": FieldInfo(_D),
    "actual_main_voltage": FieldInfo(_D),
    "actual_robot_voltage": FieldInfo(_D),
    "actual_robot_current": FieldInfo(_D),
    "actual_joint_voltage": FieldInfo(_V6D),
    "actual_digital_output_bits": FieldInfo("UINT64"),
    "actual_configurable_digital_output_bits": FieldInfo("UINT64"),
    "runtime_state": FieldInfo("UINT32"),
    "elbow_position": FieldInfo(_V3D, (3, 5), (5, 0)),
    "elbow_velocity": FieldInfo(_V3D, (3, 5), (5, 0)),
    "robot_status_bits": FieldInfo("UINT32"),
    "safety_status_bits": FieldInfo("UINT32"),
    "analog_io_types": FieldInfo("UINT32"),
    "standard_analog_input0": FieldInfo(_D),
    "standard_analog_input1": FieldInfo(_D),
    "standard_analog_output0": FieldInfo(_D),
    "standard_analog_output1": FieldInfo(_D),
    "io_current": FieldInfo(_D),
    "output_bit_registers0_to_31": FieldInfo("UINT32"),
    "output_bit_registers32_to_63": FieldInfo("UINT32"),
    "tool_mode": FieldInfo("UINT32"),
    "tool_temperature": FieldInfo(_D),
    "tool_output_voltage": FieldInfo("INT32"),
    "tool_output_current": FieldInfo(_D),
    "tool_analog_input0": FieldInfo(_D),
    "tool_analog_input1": FieldInfo(_D),
    "tool_analog_input_types": FieldInfo("UINT32"),
    "tcp_force_scalar": FieldInfo(_D),
    "ft_raw_wrench": FieldInfo(_V6D, None, (5, 9)),
    "payload": FieldInfo(_D, (3, 11), (5, 5)),
    "payload_cog": FieldInfo(_V3D, (3, 11), (5, 5)),
    "payload_inertia": FieldInfo(_V6D, (3, 15), (5, 11)),
    "script_control_line": FieldInfo("UINT32"),
    "target_execution_time": FieldInfo(_D, None, (5, 0)),
    "control_step": FieldInfo("UINT64", None, (5, 0)),
}


def _add_registers(table: dict[str, FieldInfo], prefix: str) -> None:
    """General-purpose registers: int and double 0-23 since 3.4 / 5.0, 24-47 since 3.9 / 5.3;
    bits 64-127 since 3.4 / 5.0."""
    for n in range(48):
        old, new = ((3, 4), (5, 0)) if n < 24 else ((3, 9), (5, 3))
        table[f"{prefix}_int_register_{n}"] = FieldInfo("INT32", old, new)
        table[f"{prefix}_double_register_{n}"] = FieldInfo(_D, old, new)
    for n in range(64, 128):
        table[f"{prefix}_bit_register_{n}"] = FieldInfo("BOOL", (3, 4), (5, 0))


_add_registers(OUTPUT_FIELDS, "output")

INPUT_FIELDS: dict[str, FieldInfo] = {
    "speed_slider_mask": FieldInfo("UINT32"),
    "speed_slider_fraction": FieldInfo(_D),
    "standard_digital_output_mask": FieldInfo("UINT8"),
    "standard_digital_output": FieldInfo("UINT8"),
    "configurable_digital_output_mask": FieldInfo("UINT8"),
    "configurable_digital_output": FieldInfo("UINT8"),
    "tool_digital_output_mask": FieldInfo("UINT8"),
    "tool_digital_output": FieldInfo("UINT8"),
    "standard_analog_output_mask": FieldInfo("UINT8"),
    "standard_analog_output_type": FieldInfo("UINT8"),
    "standard_analog_output_0": FieldInfo(_D),
    "standard_analog_output_1": FieldInfo(_D),
    "input_bit_registers0_to_31": FieldInfo("UINT32"),
    "input_bit_registers32_to_63": FieldInfo("UINT32"),
    "external_force_torque": FieldInfo(_V6D),
}
_add_registers(INPUT_FIELDS, "input")


def output_type(name: str, version: Version) -> str | None:
    """RTDE type of output ``name`` on a controller of ``version``; None if it does not exist."""
    info = OUTPUT_FIELDS.get(name)
    return info.rtde_type if info is not None and info.available(version) else None


def input_type(name: str, version: Version) -> str | None:
    """RTDE type of input ``name`` on a controller of ``version``; None if it does not exist."""
    info = INPUT_FIELDS.get(name)
    return info.rtde_type if info is not None and info.available(version) else None


def _register_getter(attribute: str, index: int) -> Callable:
    def get(snapshot):
        return getattr(snapshot, attribute)[index]
    return get


def _bit_register_getter(index: int) -> Callable:
    def get(snapshot):
        return bool(snapshot.output_bit_registers >> index & 1)
    return get


def output_getter(name: str) -> Callable:
    """A callable ``snapshot -> value`` for output ``name`` (which must be in OUTPUT_FIELDS)."""
    for prefix, attribute in (("output_int_register_", "output_int_registers"),
                              ("output_double_register_", "output_double_registers")):
        if name.startswith(prefix):
            return _register_getter(attribute, int(name[len(prefix):]))
    if name.startswith("output_bit_register_"):
        return _bit_register_getter(int(name[len("output_bit_register_"):]))
    if name == "output_bit_registers0_to_31":
        return lambda s: s.output_bit_registers & 0xFFFFFFFF
    if name == "output_bit_registers32_to_63":
        return lambda s: s.output_bit_registers >> 32 & 0xFFFFFFFF
    return attrgetter(name)
