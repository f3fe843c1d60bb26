"""Vectorised joint-frame kinematics in the paper's convention: ``(N, 6)`` joint angles in,
per-joint rotations and frame origins out."""

from __future__ import annotations

import numpy as np

from urident.model.robot import RobotSpec

AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def axis_rotations(axis: str, q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by angles ``q`` (N,) about a coordinate axis."""
    c, s = np.cos(q), np.sin(q)
    r = np.zeros(q.shape + (3, 3))
    i = AXIS_INDEX[axis]
    j, k = [(1, 2), (2, 0), (0, 1)][i]
    r[..., i, i] = 1.0
    r[..., j, j] = c
    r[..., k, k] = c
    r[..., j, k] = -s
    r[..., k, j] = s
    return r


def joint_rotations(spec: RobotSpec, q: np.ndarray) -> list[np.ndarray]:
    """For each joint i the (N, 3, 3) rotation of K_i relative to K_{i-1}."""
    return [joint.rotation @ axis_rotations(joint.axis, q[:, i]) for i, joint in enumerate(spec.joints)]


def frame_poses(spec: RobotSpec, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World (base-frame) rotations ``(N, 7, 3, 3)`` and origins ``(N, 7, 3)`` of K_1..K_6 and the
    tool frame, for joint angles ``q`` (N, 6)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    rot = np.zeros((n, 7, 3, 3))
    pos = np.zeros((n, 7, 3))
    r_prev = np.broadcast_to(np.eye(3), (n, 3, 3))
    p_prev = np.zeros((n, 3))
    for i, r_rel in enumerate(joint_rotations(spec, q)):
        p_prev = p_prev + r_prev @ spec.joints[i].xyz
        r_prev = r_prev @ r_rel
        rot[:, i], pos[:, i] = r_prev, p_prev
    pos[:, 6] = p_prev + r_prev @ spec.tool_xyz
    rot[:, 6] = r_prev @ spec.tool_rotation
    return rot, pos


def packed_joints(spec: RobotSpec) -> tuple[np.ndarray, bytes]:
    """The compiled kernels' joint description: 6 × (xyz, R0 row-major) doubles and the axes as
    bytes (0 = x, 1 = y, 2 = z), cached on the spec."""
    cached = spec.arrays.get("packed_joints")
    if cached is None:
        packed = np.concatenate([np.r_[j.xyz, j.rotation.reshape(-1)] for j in spec.joints]).astype(float)
        cached = spec.arrays["packed_joints"] = (packed, bytes(AXIS_INDEX[j.axis] for j in spec.joints))
    return cached
