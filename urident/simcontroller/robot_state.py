"""Controller-wide state codes (robot mode, safety, runtime state) and the RTDE registers.

Values follow UR's RTDE guide and the dashboard server's vocabulary.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

# robot_mode
ROBOT_MODE_POWER_OFF = 3
ROBOT_MODE_POWER_ON = 4
ROBOT_MODE_IDLE = 5
ROBOT_MODE_RUNNING = 7
ROBOT_MODE_NAMES = {-1: "NO_CONTROLLER", 0: "DISCONNECTED", 1: "CONFIRM_SAFETY", 2: "BOOTING",
                    3: "POWER_OFF", 4: "POWER_ON", 5: "IDLE", 6: "BACKDRIVE", 7: "RUNNING",
                    8: "UPDATING_FIRMWARE"}

# safety_mode
SAFETY_MODE_NORMAL = 1
SAFETY_MODE_PROTECTIVE_STOP = 3
SAFETY_MODE_ROBOT_EMERGENCY_STOP = 7
SAFETY_MODE_NAMES = {1: "NORMAL", 2: "REDUCED", 3: "PROTECTIVE_STOP", 4: "RECOVERY",
                     5: "SAFEGUARD_STOP", 6: "SYSTEM_EMERGENCY_STOP", 7: "ROBOT_EMERGENCY_STOP",
                     8: "VIOLATION", 9: "FAULT"}

# safety_status_bits
SAFETY_BIT_NORMAL = 1 << 0
SAFETY_BIT_PROTECTIVE_STOPPED = 1 << 2
SAFETY_BIT_ROBOT_EMERGENCY_STOPPED = 1 << 6
SAFETY_BIT_EMERGENCY_STOPPED = 1 << 7
SAFETY_BIT_STOPPED_DUE_TO_SAFETY = 1 << 10

# robot_status_bits
ROBOT_STATUS_POWER_ON = 1 << 0
ROBOT_STATUS_PROGRAM_RUNNING = 1 << 1

# runtime_state
RUNTIME_STOPPING = 0
RUNTIME_STOPPED = 1
RUNTIME_PLAYING = 2
RUNTIME_PAUSING = 3
RUNTIME_PAUSED = 4
RUNTIME_RESUMING = 5

JOINT_MODE_RUNNING = 253
JOINT_MODE_POWER_OFF = 239

N_REGISTERS = 48


@dataclass
class Registers:
    """RTDE general-purpose registers. Inputs are written by connection threads under ``lock``;
    outputs only by the controller thread."""

    input_int: list[int] = field(default_factory=lambda: [0] * N_REGISTERS)
    input_double: list[float] = field(default_factory=lambda: [0.0] * N_REGISTERS)
    input_bits: int = 0
    output_int: list[int] = field(default_factory=lambda: [0] * N_REGISTERS)
    output_double: list[float] = field(default_factory=lambda: [0.0] * N_REGISTERS)
    output_bits: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)


@dataclass
class IOState:
    """Standard/configurable/tool digital and analog I/O as set through RTDE inputs."""

    digital_output_bits: int = 0       # bits 0-7 standard, 8-15 configurable, 16-17 tool
    analog_output: list[float] = field(default_factory=lambda: [0.0, 0.0])
    analog_output_types: int = 0
    speed_slider_fraction: float = 1.0
    external_force_torque: list[float] = field(default_factory=lambda: [0.0] * 6)

    def apply(self, values: dict) -> None:
        """Apply the I/O-related names of one RTDE input package."""
        bits = self.digital_output_bits
        for shift, mask_name, value_name in ((0, "standard_digital_output_mask", "standard_digital_output"),
                                             (8, "configurable_digital_output_mask", "configurable_digital_output"),
                                             (16, "tool_digital_output_mask", "tool_digital_output")):
            mask = int(values.get(mask_name, 0))
            if mask:
                level = int(values.get(value_name, 0))
                bits = (bits & ~(mask << shift)) | ((level & mask) << shift)
        self.digital_output_bits = bits
        analog_mask = int(values.get("standard_analog_output_mask", 0))
        analog_type = int(values.get("standard_analog_output_type", 0))
        for k in (0, 1):
            if analog_mask >> k & 1:
                self.analog_output[k] = float(values.get(f"standard_analog_output_{k}", 0.0))
                self.analog_output_types = (self.analog_output_types & ~(1 << (k + 2))) | (
                    (analog_type >> k & 1) << (k + 2))
        if int(values.get("speed_slider_mask", 0)) & 1:
            self.speed_slider_fraction = min(max(float(values.get("speed_slider_fraction", 1.0)), 0.0), 1.0)
        if "external_force_torque" in values:
            self.external_force_torque = list(values["external_force_torque"])
