"""The :class:`Recording` dataclass every loader returns."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .schema import STATUS_UNKNOWN

_JOINT_ATTRS = (
    "q",
    "qd",
    "current",
    "target_q",
    "target_qd",
    "target_qdd",
    "target_current",
    "target_moment",
    "temperature",
    "tau",
)
_SCALAR_ATTRS = ("robot_mode", "safety_status_bits", "runtime_state")


@dataclass(frozen=True, eq=False)
class Recording:
    """One loaded log: sample-major arrays in SI units (temperatures in °C), read-only.

    ``t (N,)`` s; ``q, qd, current (N, 6)`` rad, rad/s, A; optional ``target_* (N, 6)``,
    ``temperature (N, 6)``, ``tau (N, 6)`` N·m (joint torque, only when the log carries one);
    optional integer ``robot_mode, safety_status_bits, runtime_state (N,)``; ``target_gravity (N, 3)``
    m/s² (the controller's gravity vector, PolyScope 5.26 / 10.12 on). What ``tau`` holds is
    ``metadata["torque_kind"]``: ``compensated`` (UR's gravity-compensated actual_current_as_torque)
    or ``full`` (docs/signals.md). ``metadata`` holds the
    sidecar (own logs) or the format description (others), plus ``dropped`` (rows removed under
    ``drop_bad``), ``duplicates_removed`` and ``status``.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    current: np.ndarray
    source: Path | None = None
    robot: str | None = None
    rate_hz: float | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    target_q: np.ndarray | None = None
    target_qd: np.ndarray | None = None
    target_qdd: np.ndarray | None = None
    target_current: np.ndarray | None = None
    target_moment: np.ndarray | None = None
    temperature: np.ndarray | None = None
    tau: np.ndarray | None = None
    robot_mode: np.ndarray | None = None
    safety_status_bits: np.ndarray | None = None
    runtime_state: np.ndarray | None = None
    target_gravity: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=np.float64).reshape(-1)
        n = t.shape[0]
        object.__setattr__(self, "t", _freeze(t))
        for name in _JOINT_ATTRS:
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.array(value, dtype=np.float64)
            if arr.shape != (n, 6):
                raise ValueError(f"Recording.{name} must have shape ({n}, 6), got {arr.shape}")
            object.__setattr__(self, name, _freeze(arr))
        for name in _SCALAR_ATTRS:
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.array(value, dtype=np.int64).reshape(-1)
            if arr.shape != (n,):
                raise ValueError(f"Recording.{name} must have shape ({n},), got {arr.shape}")
            object.__setattr__(self, name, _freeze(arr))
        if self.target_gravity is not None:
            arr = np.array(self.target_gravity, dtype=np.float64)
            if arr.shape != (n, 3):
                raise ValueError(f"Recording.target_gravity must have shape ({n}, 3), got {arr.shape}")
            object.__setattr__(self, "target_gravity", _freeze(arr))
        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))
        object.__setattr__(self, "metadata", dict(self.metadata))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_samples(self) -> int:
        return len(self)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` in s (0 for fewer than two samples)."""
        return float(self.t[-1] - self.t[0]) if len(self) > 1 else 0.0

    @property
    def status(self) -> str:
        """Sidecar status: completed, aborted, running (writer killed or still writing), unknown."""
        return str(self.metadata.get("status") or STATUS_UNKNOWN)

    @property
    def dropped(self) -> Mapping[str, Any]:
        """Report of rows removed by ``drop_bad`` (``{"count": 0, ...}`` when none)."""
        return self.metadata.get("dropped") or {"count": 0, "reasons": {}, "lines": []}

    def select(self, index) -> "Recording":
        """A new Recording with samples ``index`` (slice, boolean mask or integer array)."""
        changes: dict[str, Any] = {"t": self.t[index]}
        for name in _JOINT_ATTRS + _SCALAR_ATTRS + ("target_gravity",):
            value = getattr(self, name)
            if value is not None:
                changes[name] = value[index]
        return dataclasses.replace(self, **changes)


def _freeze(arr: np.ndarray) -> np.ndarray:
    arr = np.ascontiguousarray(arr)
    arr.flags.writeable = False
    return arr


def with_signal(recording: Recording, signal: str | None, where: str | Path = "") -> Recording:
    """``recording`` with its torques to come from ``signal`` (``current``, ``torque`` or
    ``compensated``; docs/signals.md), recorded in ``metadata["signal"]`` for
    :func:`urident.ident.torque.torque_signal`; ``current`` drops the joint torques so nothing
    later mistakes them for the currents'. LogFormatError (naming ``where``) when the log lacks the
    signal. None leaves the recording as it is."""
    from urident.errors import LogFormatError

    if signal is None:
        return recording
    where = where or recording.source or "recording"
    metadata = {**recording.metadata, "signal": signal}
    if signal == "current":
        if recording.metadata.get("current_from_torque") and recording.metadata.get("torque_kind") == "compensated":
            raise LogFormatError(f"{where}: --signal current: its effort is a gravity-compensated "
                                 "torque and carries no motor current; pass --signal compensated")
        return dataclasses.replace(recording, tau=None, metadata=metadata)
    if recording.tau is None:
        raise LogFormatError(f"{where}: --signal {signal}: the log carries no joint torque "
                             "(actual_current_as_torque, or a bag's torque effort)")
    return dataclasses.replace(recording, metadata=metadata)

