"""The log format, defined once: the column table, the sidecar keys and the sanity bounds.

A urident log is ``NAME.csv`` plus ``NAME.yaml`` (the *sidecar*). The CSV header uses ur_rtde's
recorder naming: a scalar field is one column named after the field, a vector field of width 6 is
expanded to ``name_0 .. name_5``. One row per controller sample. See ``logs/README.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

FORMAT_NAME = "urident-log"
FORMAT_VERSION = 1

N_JOINTS = 6


@dataclass(frozen=True)
class LogField:
    """One logical log field (one or six CSV columns)."""

    name: str  #: ur_rtde output name, used in the CSV header
    width: int  #: 1 (scalar), 3 (a base-frame vector) or 6 (one value per joint)
    dtype: str  #: "float" or "int"
    unit: str  #: SI unit (°C for temperatures, as the controller reports them), "" for codes
    attr: str  #: attribute of :class:`urident.logs.Recording` that holds it
    bound: float  #: sanity bound: a value with |x| > bound is corrupt (not a measurement)
    description: str

    @property
    def columns(self) -> tuple[str, ...]:
        """CSV column names of this field."""
        if self.width == 1:
            return (self.name,)
        return tuple(f"{self.name}_{j}" for j in range(self.width))

    @property
    def csv_format(self) -> str:
        """printf-style format of one value: timestamps with µs resolution, floats ``%.9g``."""
        if self.dtype == "int":
            return "%d"
        if self.name == "timestamp":
            return "%.6f"
        return "%.9g"


_TWO_PI = 2.0 * math.pi

#: Every field the loaders understand, in the order the writer writes them. Bounds are loose
#: physical limits of any UR arm (joint range ±2π, speeds ≤ 2π rad/s, currents ≤ ~20 A); anything
#: beyond is a corrupt cell, e.g. the 1e306 values of a defective recording.
LOG_FIELDS: tuple[LogField, ...] = (
    LogField("timestamp", 1, "float", "s", "t", 1e10, "controller time since power-on"),
    LogField("actual_q", 6, "float", "rad", "q", 2 * _TWO_PI, "measured joint positions"),
    LogField("actual_qd", 6, "float", "rad/s", "qd", 20.0, "measured joint velocities"),
    LogField("actual_current", 6, "float", "A", "current", 100.0, "measured motor currents"),
    LogField("target_q", 6, "float", "rad", "target_q", 2 * _TWO_PI, "target joint positions"),
    LogField("target_qd", 6, "float", "rad/s", "target_qd", 20.0, "target joint velocities"),
    LogField("target_qdd", 6, "float", "rad/s^2", "target_qdd", 1e3, "target accelerations"),
    LogField("target_current", 6, "float", "A", "target_current", 100.0, "target currents"),
    LogField("target_moment", 6, "float", "N*m", "target_moment", 1e4, "target joint torques"),
    LogField("joint_temperatures", 6, "float", "degC", "temperature", 300.0, "joint temperatures"),
    LogField("robot_mode", 1, "int", "", "robot_mode", 2.0**31, "robot mode code"),
    LogField("safety_status_bits", 1, "int", "", "safety_status_bits", 2.0**32, "safety bits"),
    LogField("runtime_state", 1, "int", "", "runtime_state", 2.0**32, "program state code"),
)

#: Fields the loaders also map when present but the writer does not write by default.
OPTIONAL_FIELDS: tuple[LogField, ...] = (
    LogField("actual_current_as_torque", 6, "float", "N*m", "tau", 1e4,
             "joint torques, gravity-compensated by the controller (docs/signals.md)"),
    LogField("target_gravity", 3, "float", "m/s^2", "target_gravity", 1e3,
             "gravity vector of the controller, base frame (docs/signals.md)"),
)

ALL_FIELDS: tuple[LogField, ...] = LOG_FIELDS + OPTIONAL_FIELDS
FIELDS_BY_NAME: dict[str, LogField] = {f.name: f for f in ALL_FIELDS}
FIELDS_BY_ATTR: dict[str, LogField] = {f.attr: f for f in ALL_FIELDS}

#: Recording attributes every loaded log must provide.
REQUIRED_ATTRS: tuple[str, ...] = ("t", "q", "qd", "current")

#: Largest plausible joint motion between two samples: MAX_JUMP_SPEED·Δt + MAX_JUMP_OFFSET (rad).
#: A larger step of ``q`` is a corrupt (shifted or garbage) row, not motion.
MAX_JUMP_SPEED = 2 * _TWO_PI
MAX_JUMP_OFFSET = 0.05

#: Sidecar status values.
STATUS_RUNNING = "running"
STATUS_COMPLETED = "completed"
STATUS_ABORTED = "aborted"
STATUS_UNKNOWN = "unknown"
STATUSES = (STATUS_RUNNING, STATUS_COMPLETED, STATUS_ABORTED)

#: Sidecar keys and their Python types (``None`` is allowed for every key but ``format``).
SIDECAR_KEYS: dict[str, tuple[type, ...]] = {
    "format": (str,),
    "format_version": (int,),
    "robot": (str,),
    "controller_version": (str,),
    "rate_hz": (int, float),
    "trajectory_file": (str,),
    "trajectory_sha256": (str,),
    "gear_ratios": (list,),
    "torque_constants": (list,),
    "start_time": (str,),
    "end_time": (str,),
    "urident_version": (str,),
    "status": (str,),
    "abort_reason": (str,),
    "late_cycles": (int,),
    "duplicates_skipped": (int,),
    "n_samples": (int,),
    "columns": (list,),
    "extra": (dict,),
}

#: Keys the caller may set through ``LogWriter(metadata=...)``; anything else goes to ``extra``.
USER_METADATA_KEYS = (
    "robot",
    "controller_version",
    "rate_hz",
    "trajectory_file",
    "trajectory_sha256",
    "gear_ratios",
    "torque_constants",
    "start_time",
)


def field_columns(fields: tuple[LogField, ...] | list[LogField]) -> list[str]:
    """All CSV column names of ``fields``, in order."""
    return [c for f in fields for c in f.columns]


def resolve_fields(fields) -> tuple[LogField, ...]:
    """Turn a list of field names or :class:`LogField` into a validated tuple of fields."""
    out: list[LogField] = []
    for item in fields:
        if isinstance(item, LogField):
            fld = item
        elif isinstance(item, str) and item in FIELDS_BY_NAME:
            fld = FIELDS_BY_NAME[item]
        elif isinstance(item, str) and item in FIELDS_BY_ATTR:
            fld = FIELDS_BY_ATTR[item]
        else:
            known = ", ".join(FIELDS_BY_NAME)
            raise ValueError(f"unknown log field {item!r}; known fields: {known}")
        if fld in out:
            raise ValueError(f"log field {fld.name!r} given twice")
        out.append(fld)
    names = [f.name for f in out]
    if not out or out[0].name != "timestamp":
        raise ValueError("the first log field must be 'timestamp'")
    for attr in REQUIRED_ATTRS:
        if FIELDS_BY_ATTR[attr].name not in names:
            raise ValueError(f"log fields must include {FIELDS_BY_ATTR[attr].name!r}")
    return tuple(out)


def sidecar_path(csv_path: str | Path) -> Path:
    """The YAML sidecar beside a log: same stem, ``.yaml`` in place of ``.csv``."""
    return Path(csv_path).with_suffix(".yaml")
