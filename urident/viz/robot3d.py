"""The robot in 3-D from the model: a skeleton line strip through the joint-frame origins and the
robot file's collision capsules, posed by ``urident.model.kinematics.frame_poses``.

Entities (under ``path``, default ``robot``; Z up)::

    robot/base        Capsules3D, static (the robot file's base_collision)
    robot/links       Capsules3D per time step (every joint's link capsules, world frame)
    robot/skeleton    LineStrips3D per time step: base → K1 … K6 → tool
    robot/tool        Points3D per time step: tool-frame origin
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from urident.model.kinematics import frame_poses
from urident.model.robot import RobotSpec
from urident.viz.recording import time_column

DEFAULT_POSE_RATE_HZ = 30.0
LINK_COLOR = (110, 150, 200)
BASE_COLOR = (90, 90, 90)
SKELETON_COLOR = (40, 40, 40)
TOOL_COLOR = (220, 60, 60)


def decimate_indices(t: np.ndarray, rate_hz: float = DEFAULT_POSE_RATE_HZ) -> np.ndarray:
    """Indices of the first sample in each ``1/rate_hz`` bin of ``t`` (always including the
    first sample); all indices when ``rate_hz`` is not positive."""
    t = np.asarray(t, dtype=float).reshape(-1)
    if len(t) == 0 or not rate_hz or rate_hz <= 0:
        return np.arange(len(t))
    bins = np.floor((t - t[0]) * rate_hz).astype(np.int64)
    keep = np.ones(len(t), dtype=bool)
    keep[1:] = bins[1:] != bins[:-1]
    return np.flatnonzero(keep)


def _quaternions_z_to(d: np.ndarray) -> np.ndarray:
    """Unit quaternions (xyzw) rotating +z onto unit vectors ``d`` (..., 3)."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    quat = np.stack([-y, x, np.zeros_like(x), 1.0 + z], axis=-1)
    flip = (1.0 + z) < 1e-9  # d ≈ −z: half turn about x
    quat[flip] = (1.0, 0.0, 0.0, 0.0)
    return quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def _capsule_table(spec: RobotSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Link capsules as (body index, a, b, radius) arrays."""
    body, a, b, r = [], [], [], []
    for i, joint in enumerate(spec.joints):
        for cap in joint.collision:
            body.append(i)
            a.append(cap.a)
            b.append(cap.b)
            r.append(cap.radius)
    return (np.array(body, dtype=int), np.array(a, dtype=float).reshape(-1, 3),
            np.array(b, dtype=float).reshape(-1, 3), np.array(r, dtype=float))


def _capsule_poses(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translations, lengths and quaternions of capsules a→b (..., 3) in the world."""
    d = b - a
    length = np.linalg.norm(d, axis=-1)
    unit = np.where(length[..., None] > 1e-12, d / np.maximum(length, 1e-12)[..., None],
                    np.array([0.0, 0.0, 1.0]))
    return a, length, _quaternions_z_to(unit)


def robot_geometry(spec: RobotSpec, q: np.ndarray) -> dict[str, np.ndarray]:
    """World-frame geometry for joint angles ``q (N, 6)``: ``skeleton (N, 8, 3)`` (base origin,
    K1..K6, tool), ``tool (N, 3)``, and link capsules ``capsule_a, capsule_b (N, C, 3)``,
    ``capsule_radius (C,)``."""
    rot, pos = frame_poses(spec, q)
    n = rot.shape[0]
    skeleton = np.concatenate([np.zeros((n, 1, 3)), pos], axis=1)
    body, a, b, radius = _capsule_table(spec)
    if len(body):
        r = rot[:, body]                     # (N, C, 3, 3)
        p = pos[:, body]                     # (N, C, 3)
        cap_a = np.einsum("ncij,cj->nci", r, a) + p
        cap_b = np.einsum("ncij,cj->nci", r, b) + p
    else:
        cap_a = cap_b = np.zeros((n, 0, 3))
    return {"skeleton": skeleton, "tool": pos[:, 6], "capsule_a": cap_a, "capsule_b": cap_b,
            "capsule_radius": radius}


def log_robot_static(rec: rr.RecordingStream, spec: RobotSpec, path: str = "robot") -> None:
    """The base capsules (static)."""
    if spec.base_collision:
        a = np.array([c.a for c in spec.base_collision], dtype=float)
        b = np.array([c.b for c in spec.base_collision], dtype=float)
        trans, length, quat = _capsule_poses(a, b)
        rec.log(f"{path}/base", rr.Capsules3D(
            lengths=length, radii=[c.radius for c in spec.base_collision], translations=trans,
            quaternions=quat, colors=BASE_COLOR), static=True)


def log_robot_motion(rec: rr.RecordingStream, spec: RobotSpec, t: np.ndarray, q: np.ndarray,
                     path: str = "robot", rate_hz: float | None = DEFAULT_POSE_RATE_HZ,
                     static_parts: bool = True) -> int:
    """Log the robot's pose at times ``t (N,)`` [s] for joint angles ``q (N, 6)`` [rad],
    decimated to ``rate_hz`` (None or 0: every sample). Returns the number of poses logged."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (len(t), 6):
        raise ValueError(f"q must be ({len(t)}, 6), got {q.shape}")
    if static_parts:
        log_robot_static(rec, spec, path)
    if len(t) == 0:
        return 0
    idx = decimate_indices(t, rate_hz or 0.0)
    t, q = t[idx], q[idx]
    n = len(t)
    geo = robot_geometry(spec, q)
    index = [time_column(t)]
    rec.send_columns(f"{path}/skeleton", indexes=index, columns=rr.LineStrips3D.columns(
        strips=list(geo["skeleton"])).partition(np.ones(n, dtype=int)))
    rec.send_columns(f"{path}/tool", indexes=index,
                     columns=rr.Points3D.columns(positions=geo["tool"]).partition(np.ones(n, dtype=int)))
    n_caps = geo["capsule_a"].shape[1]
    if n_caps:
        trans, length, quat = _capsule_poses(geo["capsule_a"], geo["capsule_b"])
        radii = np.tile(geo["capsule_radius"], n)
        rec.send_columns(f"{path}/links", indexes=index, columns=rr.Capsules3D.columns(
            lengths=length.reshape(-1), radii=radii, translations=trans.reshape(-1, 3),
            quaternions=quat.reshape(-1, 4)).partition(np.full(n, n_caps)))
    if static_parts:
        rec.log(f"{path}/skeleton", rr.LineStrips3D.from_fields(radii=[0.006], colors=[SKELETON_COLOR]),
                static=True)
        rec.log(f"{path}/tool", rr.Points3D.from_fields(radii=[0.02], colors=[TOOL_COLOR]), static=True)
        rec.log(f"{path}/links", rr.Capsules3D.from_fields(colors=[LINK_COLOR]), static=True)
    return n
