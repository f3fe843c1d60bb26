"""Pinocchio models (dynamics and capsule collision geometry) built from a :class:`RobotSpec`."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from urident.model.parameters import COULOMB, ROTOR, VISCOUS, body_slice, check_standard, pinocchio_dynamic_parameters
from urident.model.regressor import DEFAULT_FRICTION_EPS
from urident.model.robot import Capsule, RobotSpec

_JOINT_TYPES = {"x": pin.JointModelRX, "y": pin.JointModelRY, "z": pin.JointModelRZ}


def build_model(spec: RobotSpec, params: np.ndarray | None = None) -> pin.Model:
    """A Pinocchio model of the arm whose link inertias are the rigid-body part of ``params``
    (the paper's 78-vector; default: the robot file's nominal values). Rotor inertia and friction
    are not part of it (see :class:`TorqueModel`)."""
    p = spec.nominal_params if params is None else np.asarray(params, dtype=float)
    model = pin.Model()
    model.name = spec.name
    model.gravity = pin.Motion(np.r_[spec.gravity, 0.0, 0.0, 0.0])
    parent = 0
    for i, joint in enumerate(spec.joints):
        placement = pin.SE3(np.array(joint.rotation), np.array(joint.xyz))
        jid = model.addJoint(parent, _JOINT_TYPES[joint.axis](), placement, joint.name,
                             np.array([joint.tau_max]), np.array([joint.qd_max]),
                             np.array([joint.q_min]), np.array([joint.q_max]))
        inertia = pin.Inertia.FromDynamicParameters(pinocchio_dynamic_parameters(p[body_slice(i)]))
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        parent = jid
    model.addFrame(pin.Frame("tool", parent, pin.SE3(np.array(spec.tool_rotation), np.array(spec.tool_xyz)),
                             pin.FrameType.OP_FRAME))
    return model


def build_collision_model(spec: RobotSpec, model: pin.Model | None = None,
                          floor_height_m: float | None = 0.0) -> pin.GeometryModel:
    """Capsules of the robot file as a Pinocchio/coal geometry model, plus the floor (a half-space
    ``z >= floor_height_m``), with the collision pairs the self-collision check uses."""
    import coal

    model = build_model(spec) if model is None else model
    geom = pin.GeometryModel()

    def add(name: str, joint_id: int, capsule: Capsule) -> int:
        axis = capsule.b - capsule.a
        length = float(np.linalg.norm(axis))
        placement = pin.SE3(_rotation_z_to(axis), (capsule.a + capsule.b) / 2)
        obj = pin.GeometryObject(name, joint_id, placement, coal.Capsule(capsule.radius, length))
        return geom.addGeometryObject(obj)

    groups: dict[str, list[int]] = {"base": [add(f"base_{k}", 0, c) for k, c in enumerate(spec.base_collision)]}
    for i, joint in enumerate(spec.joints):
        groups[joint.name] = [add(f"{joint.name}_{k}", i + 1, c) for k, c in enumerate(joint.collision)]
    groups[TOOL_LINK] = [add(f"{TOOL_LINK}_{k}", len(spec.joints), c) for k, c in enumerate(spec.tool_collision)]
    for first, second in collision_link_pairs(spec):
        for a in groups[first]:
            for b in groups[second]:
                geom.addCollisionPair(pin.CollisionPair(a, b))
    if floor_height_m is not None:
        floor = pin.GeometryObject("floor", 0, pin.SE3(np.eye(3), np.array([0.0, 0.0, floor_height_m])),
                                   coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0))
        floor_id = geom.addGeometryObject(floor)
        for name in floor_checked_links(spec):
            for a in groups[name]:
                geom.addCollisionPair(pin.CollisionPair(a, floor_id))
    return geom


#: Name of a mounted tool's capsule group (:attr:`RobotSpec.tool`), rigid on the last link.
TOOL_LINK = "tool"


def collision_link_pairs(spec: RobotSpec) -> list[tuple[str, str]]:
    """Link pairs checked for self-collision: not adjacent in the chain, not allowed contacts.
    The base counts as link 0. A mounted tool is checked against every link but the one it is
    bolted to (the robot file's allowed contacts are about the arm's own capsules)."""
    names = ["base", *spec.joint_names]
    pairs = []
    for i in range(len(names)):
        for j in range(i + 2, len(names)):
            if frozenset((names[i], names[j])) not in spec.allowed_contacts:
                pairs.append((names[i], names[j]))
    if spec.tool is not None:
        pairs += [(name, TOOL_LINK) for name in names[:-1]]
    return pairs


def floor_checked_links(spec: RobotSpec) -> list[str]:
    """Links checked against the floor/mount plane: all but the first (which cannot reach it)."""
    return list(spec.joint_names[1:]) + ([TOOL_LINK] if spec.tool is not None else [])


def _rotation_z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation whose z axis points along ``direction`` (coal capsules lie along z)."""
    z = direction / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


class TorqueModel:
    """Joint torques τ = RNEA(q, q̇, q̈) + i_G² C_M q̈ + r_v q̇ + r_c tanh(q̇/ε) for one parameter set.

    Fast for single samples (a control loop or the simulated controller); for batches use
    :func:`urident.model.regressor.joint_torques`, which gives the same numbers.
    """

    def __init__(self, spec: RobotSpec, params: np.ndarray | None = None,
                 friction_eps: float = DEFAULT_FRICTION_EPS):
        self.spec = spec
        self.params = spec.nominal_params if params is None else np.asarray(params, dtype=float).copy()
        check_standard(self.params)
        self.friction_eps = float(friction_eps)
        self.model = build_model(spec, self.params)
        self.data = self.model.createData()
        self.rotor = self.params[ROTOR].copy()
        self.viscous = self.params[VISCOUS].copy()
        self.coulomb = self.params[COULOMB].copy()

    def rigid_body(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        return pin.rnea(self.model, self.data, q, qd, qdd).copy()

    def friction(self, qd: np.ndarray) -> np.ndarray:
        return self.viscous * qd + self.coulomb * np.tanh(qd / self.friction_eps)

    def torque(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """(6,) joint torques [N m] at one state."""
        q, qd, qdd = (np.asarray(x, dtype=float) for x in (q, qd, qdd))
        return self.rigid_body(q, qd, qdd) + self.rotor * qdd + self.friction(qd)

    def torques(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """(N, 6) joint torques, one Pinocchio call per sample."""
        return np.array([self.torque(a, b, c) for a, b, c in zip(q, qd, qdd)])
