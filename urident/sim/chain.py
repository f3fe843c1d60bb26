"""Kinematic equivalence of a user's simulator model and the robot file's chain.

Two models are the same chain when every joint's axis *line* agrees, direction and place, after the
best rigid placement of the user's base about the gravity axis: a rotation ψ about the vertical and a
translation t change no joint torque, so x_robot = R_z(ψ)·x_user + t. A revolute joint's anchor may sit
anywhere on its axis, and the body frames are the user's affair: only the lines count, at q = 0 and at
four other poses (so a joint with another zero or sign is seen).

Per joint the line's *offset* (the distance of the robot's joint origin from the user's aligned axis
line, largest over the poses) and *angle* are findings up to :data:`OFFSET_LIMIT_M` and
:data:`ANGLE_LIMIT_RAD` (a model's link lengths rounded to the millimetre, a CAD frame a little off);
beyond them the model is another chain (another arm, a missing or extra joint, joints in another
order) and is refused. An axis pointing the other way is refused whatever its place: MuJoCo's and
the robot's joint angles would have opposite signs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: beyond this distance between a joint's axis lines the model is refused [m]: millimetre rounding
#: passes with margin, and the closest pair of UR arms (UR5 and UR5e: d4 24 mm apart, which the
#: least-squares placement spreads to 22 mm on one line) stays apart with margin
OFFSET_LIMIT_M = 0.010
#: beyond this angle between a joint's axes the model is refused [rad] (2°)
ANGLE_LIMIT_RAD = np.deg2rad(2.0)
#: an offset or angle below these is the model's rounding, not a finding worth a line
OFFSET_NOTE_M = 1e-4
ANGLE_NOTE_RAD = 1e-4


@dataclass(frozen=True)
class Alignment:
    """x_robot = rotation · x_user + translation; per joint the axis-line offset [m] and angle [rad]
    (largest over the check poses) after it."""

    yaw: float                   # ψ [rad], the rotation about the vertical
    translation: np.ndarray      # (3,) [m]
    offset_m: np.ndarray         # (6,)
    angle_rad: np.ndarray        # (6,)

    @property
    def rotation(self) -> np.ndarray:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def to_robot(self, x: np.ndarray) -> np.ndarray:
        """Points (…, 3) of the user's world in the robot's base frame."""
        return np.asarray(x, float) @ self.rotation.T + self.translation

    def to_user(self, x: np.ndarray) -> np.ndarray:
        """Points (…, 3) of the robot's base frame in the user's world."""
        return (np.asarray(x, float) - self.translation) @ self.rotation

    def as_dict(self) -> dict:
        return {"yaw_deg": float(np.rad2deg(self.yaw)), "translation_m": [float(v) for v in self.translation],
                "axis_offset_mm": [float(v) for v in 1000 * self.offset_m],
                "axis_angle_deg": [float(v) for v in np.rad2deg(self.angle_rad)]}


def _projector(u: np.ndarray) -> np.ndarray:
    """(…, 3, 3) I − u·uᵀ: the part of a vector off the line's direction u (…, 3)."""
    return np.eye(3) - u[..., :, None] * u[..., None, :]


def _fit_translation(rz, ref_pos, anchors, axes) -> tuple[np.ndarray, float]:
    """t minimising Σ |P_u'(p − R·a − t)|² (our joint origins p to the user's aligned lines)."""
    u = axes @ rz.T
    proj = _projector(u)
    rhs = np.einsum("...ij,...j->...i", proj, ref_pos - anchors @ rz.T)
    t = np.linalg.lstsq(proj.reshape(-1, 3), rhs.reshape(-1), rcond=None)[0]
    res = np.einsum("...ij,...j->...i", proj, ref_pos - anchors @ rz.T - t)
    return t, float(np.sum(res ** 2))


def _rz(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def align(ref_pos: np.ndarray, ref_axes: np.ndarray, anchors: np.ndarray, axes: np.ndarray) -> Alignment:
    """The best placement of the user's base (rotation about z, translation) bringing its joint axis
    lines (``anchors``, ``axes``: (N, 6, 3) world points on the lines and unit directions at the
    check poses) onto the robot's (``ref_pos``, ``ref_axes``), and what each line is off after it."""
    from scipy.optimize import minimize_scalar

    axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
    # ψ from the directions' horizontal parts (2-D Procrustes), then refined on the lines' places
    cross = np.sum(axes[..., 0] * ref_axes[..., 1] - axes[..., 1] * ref_axes[..., 0])
    dot = np.sum(axes[..., 0] * ref_axes[..., 0] + axes[..., 1] * ref_axes[..., 1])
    yaw0 = float(np.arctan2(cross, dot))

    def cost(yaw):
        rz = _rz(yaw)
        angle = np.sum(1.0 - np.sum((axes @ rz.T) * ref_axes, axis=-1))
        return _fit_translation(rz, ref_pos, anchors, axes)[1] + 0.01 * angle   # 0.1 m per rad, squared
    yaw = float(minimize_scalar(cost, bounds=(yaw0 - 0.05, yaw0 + 0.05), method="bounded",
                                options={"xatol": 1e-10}).x)
    rz = _rz(yaw)
    t, _ = _fit_translation(rz, ref_pos, anchors, axes)
    u = axes @ rz.T
    res = np.einsum("...ij,...j->...i", _projector(u), ref_pos - anchors @ rz.T - t)
    offset = np.max(np.linalg.norm(res, axis=-1), axis=0)
    angle = np.max(np.arccos(np.clip(np.sum(u * ref_axes, axis=-1), -1.0, 1.0)), axis=0)
    return Alignment(float(np.arctan2(np.sin(yaw), np.cos(yaw))), t, offset, angle)


def refusal(alignment: Alignment) -> tuple[int, str] | None:
    """(0-based joint, why) for a model that is another chain, or None: an axis pointing the other
    way first (it spoils every line after it), then the first joint of the chain whose angle, then
    whose offset is beyond the limits (an error moves every axis after it)."""
    ang, off = alignment.angle_rad, alignment.offset_m
    flipped = np.flatnonzero(ang > np.pi / 2)
    if flipped.size:
        i = int(flipped[0])
        return i, f"its axis points the other way ({np.rad2deg(ang[i]):.0f}° from the robot's)"
    i = int(np.argmax(ang > ANGLE_LIMIT_RAD))
    if ang[i] > ANGLE_LIMIT_RAD:
        return i, (f"its axis is {np.rad2deg(ang[i]):.2f}° from the robot's after aligning the bases "
                   f"(limit {np.rad2deg(ANGLE_LIMIT_RAD):g}°)")
    i = int(np.argmax(off > OFFSET_LIMIT_M))
    if off[i] > OFFSET_LIMIT_M:
        return i, (f"its axis line is {1000 * off[i]:.1f} mm from the robot's after aligning the bases "
                   f"(limit {1000 * OFFSET_LIMIT_M:g} mm)")
    return None


#: joint names a model may give the robot's joints (besides the robot file's own), {i}: 1-based index
NAME_PATTERNS = ("{name}", "{name}_joint", "joint{i}", "joint_{i}", "j{i}")


def match_joint_names(names: list[str], robot_names: tuple[str, ...]) -> list[str] | None:
    """The user's joint for each robot joint by name: the robot's own names, with ``_joint``, or
    ``joint1`` …, after any common prefix (``ur5e_``); None when they do not all match."""
    out = []
    for i, robot in enumerate(robot_names):
        wanted = [p.format(name=robot, i=i + 1).lower() for p in NAME_PATTERNS]
        hits = [n for n in names if any(n.lower() == w or n.lower().endswith(("_" + w, "/" + w, ":" + w))
                                        for w in wanted)]
        if len(hits) != 1:
            return None
        out.append(hits[0])
    return out if len(set(out)) == len(out) else None
