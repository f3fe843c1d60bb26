"""Forward kinematics from UR's DH parameters, for the TCP fields the controller reports.

UR convention: ``T_i = Rz(q_i) · Tz(d_i) · Tx(a_i) · Rx(alpha_i)``; the TCP pose is
``[x, y, z, rx, ry, rz]`` (position [m] and rotation vector [rad]) of the flange plus the TCP
offset, in the base frame.

:class:`Kinematics` runs every controller cycle, so it evaluates the chain with Pinocchio (a DH
chain of revolute-z joints, ~10 µs per call). :class:`DHKinematics` is the same computation in
plain Python, written straight from the convention; the tests hold the two equal.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin


def rotation_vector(r) -> np.ndarray:
    """Axis-angle vector of a 3×3 rotation matrix (nested sequences or array)."""
    r = np.asarray(r, dtype=float)
    cos_angle = min(max((r[0, 0] + r[1, 1] + r[2, 2] - 1.0) / 2.0, -1.0), 1.0)
    angle = math.acos(cos_angle)
    if angle < 1e-9:
        return np.zeros(3)
    if math.pi - angle < 1e-6:
        axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
        k = int(np.argmax(axis))
        for j in range(3):
            if j != k and r[k, j] + r[j, k] < 0:
                axis[j] = -axis[j]
        return axis / np.linalg.norm(axis) * angle
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (2.0 * math.sin(angle))
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
        t[:3, :3] = np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx
    t[:3, 3] = pose[:3]
    return t


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


class DHKinematics:
    """DH forward kinematics with the geometric Jacobian's linear/angular velocities (reference)."""

    def __init__(self, d, a, alpha):
        self.d = [float(x) for x in d]
        self.a = [float(x) for x in a]
        self.ca = [math.cos(float(x)) for x in alpha]
        self.sa = [math.sin(float(x)) for x in alpha]
        self._offset_key = None
        self._offset = None

    @classmethod
    def from_spec(cls, spec) -> "DHKinematics":
        return cls(spec.dh["d"], spec.dh["a"], spec.dh["alpha"])

    def _frames(self, q):
        """Rotation (row-major 3×3 tuples) and origin of frames 0 … 6 in the base frame."""
        r = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
        o = (0.0, 0.0, 0.0)
        rotations, origins = [r], [o]
        for i in range(6):
            ct, st = math.cos(q[i]), math.sin(q[i])
            ca, sa, a, d = self.ca[i], self.sa[i], self.a[i], self.d[i]
            # local transform columns: x=(ct, st, 0), y=(-st ca, ct ca, sa), z=(st sa, -ct sa, ca)
            lx = (ct, st, 0.0)
            ly = (-st * ca, ct * ca, sa)
            lz = (st * sa, -ct * sa, ca)
            lp = (a * ct, a * st, d)
            rows = []
            for row in r:
                rows.append((row[0] * lx[0] + row[1] * lx[1] + row[2] * lx[2],
                             row[0] * ly[0] + row[1] * ly[1] + row[2] * ly[2],
                             row[0] * lz[0] + row[1] * lz[1] + row[2] * lz[2]))
            o = tuple(o[k] + r[k][0] * lp[0] + r[k][1] * lp[1] + r[k][2] * lp[2] for k in range(3))
            r = tuple(rows)
            rotations.append(r)
            origins.append(o)
        return rotations, origins

    def _offset_matrix(self, tcp_offset):
        key = tuple(float(x) for x in tcp_offset)
        if key != self._offset_key:
            self._offset_key = key
            self._offset = None if not any(key) else pose_matrix(key)
        return self._offset

    def tcp(self, q, qd, tcp_offset=None):
        """(TCP pose (6,), TCP speed (6,) [v, ω], elbow position (3,), elbow velocity (3,),
        TCP rotation matrix (3, 3)) as numpy arrays."""
        q = [float(x) for x in q]
        qd = [float(x) for x in qd]
        rotations, origins = self._frames(q)
        rot = np.array(rotations[6])
        p = np.array(origins[6])
        offset = None if tcp_offset is None else self._offset_matrix(tcp_offset)
        if offset is not None:
            p = p + rot @ offset[:3, 3]
            rot = rot @ offset[:3, :3]
        pt = tuple(p.tolist())
        elbow = origins[2]
        v = [0.0, 0.0, 0.0]
        w = [0.0, 0.0, 0.0]
        ve = [0.0, 0.0, 0.0]
        for i in range(6):
            rz = rotations[i]
            z = (rz[0][2], rz[1][2], rz[2][2])
            oi = origins[i]
            s = qd[i]
            c = _cross(z, (pt[0] - oi[0], pt[1] - oi[1], pt[2] - oi[2]))
            for k in range(3):
                w[k] += z[k] * s
                v[k] += c[k] * s
            if i < 2:
                ce = _cross(z, (elbow[0] - oi[0], elbow[1] - oi[1], elbow[2] - oi[2]))
                for k in range(3):
                    ve[k] += ce[k] * s
        pose = np.concatenate([p, rotation_vector(rot)])
        return pose, np.array(v + w), np.array(elbow), np.array(ve), rot


def _dh_link(d: float, a: float, alpha: float) -> pin.SE3:
    """The constant part ``Tz(d) · Tx(a) · Rx(alpha)`` of one DH transform."""
    ca, sa = math.cos(alpha), math.sin(alpha)
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    return pin.SE3(rotation, np.array([a, 0.0, d]))


class Kinematics:
    """The controller's per-cycle forward kinematics: same results as :class:`DHKinematics`.

    Joint ``i`` of the Pinocchio chain sits at DH frame ``i-1`` and turns about its z axis, so
    DH frame 2 (the elbow) is joint 3's origin and the flange is joint 6 times the last link.
    """

    def __init__(self, d, a, alpha):
        links = [_dh_link(float(di), float(ai), float(al)) for di, ai, al in zip(d, a, alpha)]
        model = pin.Model()
        parent = 0
        for i in range(6):
            placement = pin.SE3.Identity() if i == 0 else links[i - 1]
            parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
            model.appendBodyToJoint(parent, pin.Inertia.Zero(), pin.SE3.Identity())
        self._flange = links[5]
        self._tcp_frame = model.addFrame(pin.Frame("tcp", parent, self._flange, pin.FrameType.OP_FRAME))
        self.model = model
        self.data = model.createData()
        self._offset_key = None

    @classmethod
    def from_spec(cls, spec) -> "Kinematics":
        return cls(spec.dh["d"], spec.dh["a"], spec.dh["alpha"])

    def _set_offset(self, tcp_offset) -> None:
        key = None if tcp_offset is None else tuple(float(x) for x in tcp_offset)
        if key == self._offset_key:
            return
        self._offset_key = key
        placement = self._flange
        if key is not None and any(key):
            offset = pose_matrix(key)
            placement = self._flange * pin.SE3(offset[:3, :3], offset[:3, 3])
        self.model.frames[self._tcp_frame].placement = placement

    def tcp(self, q, qd, tcp_offset=None):
        """(TCP pose (6,), TCP speed (6,) [v, ω], elbow position (3,), elbow velocity (3,),
        TCP rotation matrix (3, 3)) as numpy arrays."""
        self._set_offset(tcp_offset)
        model, data = self.model, self.data
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        pin.forwardKinematics(model, data, q, qd)
        tcp = pin.updateFramePlacement(model, data, self._tcp_frame)
        speed = pin.getFrameVelocity(model, data, self._tcp_frame, pin.LOCAL_WORLD_ALIGNED)
        # Joint 3 turns about its own origin, so that origin's velocity comes from joints 1-2 only.
        elbow_velocity = pin.getVelocity(model, data, 3, pin.LOCAL_WORLD_ALIGNED).linear
        rotation = tcp.rotation
        pose = np.concatenate([tcp.translation, pin.log3(rotation)])
        return (pose, np.concatenate([speed.linear, speed.angular]), data.oMi[3].translation.copy(),
                elbow_velocity, rotation)
