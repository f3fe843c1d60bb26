"""Limits an excitation trajectory must respect, derived from a robot file and safety margins, and
the kinematic part of the check (positions, velocities, accelerations, nominal torques)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.model.robot import RobotSpec

DEFAULT_VELOCITY_FRACTION = 0.8
DEFAULT_ACCELERATION_FRACTION = 1.0
DEFAULT_TORQUE_FRACTION = 0.9
DEFAULT_POSITION_MARGIN_RAD = 0.2
DEFAULT_POSITION_WINDOW_RAD = float(np.pi)
DEFAULT_CLEARANCE_M = 0.05
DEFAULT_FLOOR_HEIGHT_M = 0.0


@dataclass(frozen=True)
class Margins:
    """How far inside the robot's own limits a trajectory must stay."""

    velocity_fraction: float = DEFAULT_VELOCITY_FRACTION          # |q̇| ≤ f·q̇_max
    acceleration_fraction: float = DEFAULT_ACCELERATION_FRACTION  # |q̈| ≤ f·q̈_max
    torque_fraction: float = DEFAULT_TORQUE_FRACTION              # |τ_nominal| ≤ f·τ_max
    position_margin_rad: float = DEFAULT_POSITION_MARGIN_RAD      # q_min + m ≤ q ≤ q_max − m
    position_window_rad: float = DEFAULT_POSITION_WINDOW_RAD      # and |q| ≤ window (one turn)
    clearance_m: float = DEFAULT_CLEARANCE_M                      # capsule distance to floor / links
    floor_height_m: float = DEFAULT_FLOOR_HEIGHT_M                # floor / mount plane z [m]

    def __post_init__(self) -> None:
        for name in ("velocity_fraction", "acceleration_fraction", "torque_fraction"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0 < value <= 1):
                raise ValueError(f"{name} must be in (0, 1], got {value}")
        if not (np.isfinite(self.position_window_rad) and self.position_window_rad > 0):
            raise ValueError(f"position_window_rad must be positive, got {self.position_window_rad}")
        for name in ("position_margin_rad", "clearance_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and not negative, got {value}")
        if not np.isfinite(self.floor_height_m):
            raise ValueError("floor_height_m must be finite")


@dataclass(frozen=True)
class Limits:
    """Absolute bounds (6,) per joint in SI units, plus the collision clearance."""

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray
    tau_max: np.ndarray
    clearance_m: float
    floor_height_m: float
    margins: Margins

    @classmethod
    def from_robot(cls, spec: RobotSpec, margins: Margins | None = None) -> "Limits":
        m = Margins() if margins is None else margins
        q_min = np.maximum(spec.q_min + m.position_margin_rad, -m.position_window_rad)
        q_max = np.minimum(spec.q_max - m.position_margin_rad, m.position_window_rad)
        if np.any(q_min >= q_max):
            raise ValueError(f"position_margin_rad {m.position_margin_rad} leaves no range on some joint")
        return cls(q_min, q_max, spec.qd_max * m.velocity_fraction,
                   spec.qdd_max * m.acceleration_fraction, spec.tau_max * m.torque_fraction,
                   m.clearance_m, m.floor_height_m, m)


def joint_scale_factors(dq: np.ndarray, qd: np.ndarray, qdd: np.ndarray, q0: np.ndarray,
                        limits: Limits) -> np.ndarray:
    """Largest factors s ≤ 1 per joint such that the motion ``s·(dq, qd, qdd)`` about ``q0`` obeys
    the position, velocity and acceleration limits on the grid. Inputs (..., N, 6); out (..., 6).
    (Each joint's motion is linear in its own coefficients, so scaling it is exact.)"""
    room_up = limits.q_max - q0
    room_down = q0 - limits.q_min
    ratio = np.maximum.reduce([
        np.max(dq, axis=-2) / room_up,
        np.max(-dq, axis=-2) / room_down,
        np.max(np.abs(qd), axis=-2) / limits.qd_max,
        np.max(np.abs(qdd), axis=-2) / limits.qdd_max,
    ])
    return 1.0 / np.maximum(ratio, 1.0)


@dataclass(frozen=True)
class KinematicMargins:
    """Tightest margin (limit − value, ≥ 0 when satisfied) per joint (6,) and the time of it."""

    position: np.ndarray
    position_time: np.ndarray
    velocity: np.ndarray
    velocity_time: np.ndarray
    acceleration: np.ndarray
    acceleration_time: np.ndarray


def kinematic_margins(t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                      limits: Limits) -> KinematicMargins:
    pos = np.minimum(q - limits.q_min, limits.q_max - q)
    vel = limits.qd_max - np.abs(qd)
    acc = limits.qdd_max - np.abs(qdd)
    out = []
    for m in (pos, vel, acc):
        k = np.argmin(m, axis=0)
        out += [m[k, np.arange(6)], t[k]]
    return KinematicMargins(*out)
