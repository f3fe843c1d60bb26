"""Forward kinematics from UR's DH parameters, for the TCP fields the controller reports.

UR convention: ``T_i = Rz(q_i) · Tz(d_i) · Tx(a_i) · Rx(alpha_i)``; the TCP pose is
``[x, y, z, rx, ry, rz]`` (position [m] and rotation vector [rad]) of the flange plus the TCP
offset, in the base frame.
"""

from __future__ import annotations

import numpy as np


def rotation_vector(r: np.ndarray) -> np.ndarray:
    """Axis-angle vector of rotation matrix ``r``."""
    cos_angle = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    angle = float(np.arccos(cos_angle))
    if angle < 1e-9:
        return np.zeros(3)
    if np.pi - angle < 1e-6:
        # near pi: axis from the diagonal
        axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
        k = int(np.argmax(axis))
        for j in range(3):
            if j != k and r[k, j] + r[j, k] < 0:
                axis[j] = -axis[j]
        return axis / np.linalg.norm(axis) * angle
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (2.0 * np.sin(angle))
    return axis * angle


def pose_matrix(pose) -> np.ndarray:
    """4×4 transform of a ``[x, y, z, rx, ry, rz]`` pose."""
    pose = np.asarray(pose, dtype=float)
    t = np.eye(4)
    v = pose[3:]
    angle = float(np.linalg.norm(v))
    if angle > 1e-12:
        k = v / angle
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        t[:3, :3] = np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx
    t[:3, 3] = pose[:3]
    return t


class Kinematics:
    """DH forward kinematics with the geometric Jacobian's linear/angular velocities."""

    def __init__(self, d, a, alpha):
        self.d = np.asarray(d, dtype=float)
        self.a = np.asarray(a, dtype=float)
        self.alpha = np.asarray(alpha, dtype=float)
        self._ca = np.cos(self.alpha)
        self._sa = np.sin(self.alpha)

    @classmethod
    def from_spec(cls, spec) -> "Kinematics":
        return cls(spec.dh["d"], spec.dh["a"], spec.dh["alpha"])

    def frames(self, q) -> list[np.ndarray]:
        """Base-frame transforms of frames 0 (base) … 6 (flange)."""
        out = [np.eye(4)]
        t = np.eye(4)
        for i in range(6):
            ct, st = np.cos(q[i]), np.sin(q[i])
            ca, sa = self._ca[i], self._sa[i]
            step = np.array([[ct, -st * ca, st * sa, self.a[i] * ct],
                             [st, ct * ca, -ct * sa, self.a[i] * st],
                             [0.0, sa, ca, self.d[i]],
                             [0.0, 0.0, 0.0, 1.0]])
            t = t @ step
            out.append(t)
        return out

    def tcp(self, q, qd, tcp_offset=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(TCP pose (6,), TCP speed (6,) [v, ω], elbow position (3,), elbow velocity (3,),
        TCP rotation matrix (3, 3))."""
        frames = self.frames(q)
        flange = frames[6]
        tcp = flange if tcp_offset is None else flange @ pose_matrix(tcp_offset)
        p = tcp[:3, 3]
        elbow = frames[2][:3, 3]  # on the elbow joint's axis
        v = np.zeros(3)
        w = np.zeros(3)
        v_elbow = np.zeros(3)
        for i in range(6):
            z = frames[i][:3, 2]
            o = frames[i][:3, 3]
            w += z * qd[i]
            v += np.cross(z, p - o) * qd[i]
            if i < 2:
                v_elbow += np.cross(z, elbow - o) * qd[i]
        pose = np.concatenate([p, rotation_vector(tcp[:3, :3])])
        return pose, np.concatenate([v, w]), elbow, v_elbow, tcp[:3, :3]
