"""A user's simulator model (MJCF or URDF) of a robot of ours: loaded, checked against the robot
file's kinematic chain, and asked for its inverse dynamics.

* MJCF: MuJoCo's ``mj_inverse`` (contacts off; armature, damping and frictionloss as MuJoCo has them);
* URDF: Pinocchio's RNEA plus ``<dynamics damping friction>`` as damping·q̇ + friction·tanh(q̇/ε)
  (URDF does not say how its Coulomb friction is smoothed; urident's ε).

The chain must be the robot file's: six revolute joints whose anchors lie within 1 mm and whose
axes lie within 0.01 rad of the robot file's at q = 0 and at four other poses; any other joint
(mimic, continuous, prismatic, ball, free) is refused with the element named.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from urident.errors import ConfigError

POSITION_TOL_M = 1e-3
AXIS_TOL_RAD = 0.01
_UNIT = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}


class SimModelError(ConfigError):
    """A simulator model that cannot be read or does not fit the robot."""


def model_format(path: str | Path) -> str:
    suffix = Path(path).suffix.lower()
    if suffix in (".xml", ".mjcf"):
        return "mjcf"
    if suffix == ".urdf":
        return "urdf"
    raise SimModelError(f"{path}: a simulator model must be MJCF (.xml) or URDF (.urdf)")


def check_poses(spec) -> np.ndarray:
    """q = 0 and four fixed poses inside every robot's limits (5, 6)."""
    rng = np.random.default_rng(7)
    return np.vstack([np.zeros(6), rng.uniform(-1.5, 1.5, (4, 6))])


def spec_joint_geometry(spec, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World anchors (N, 6, 3) and axes (N, 6, 3) of the robot file's joints."""
    from urident.model.kinematics import frame_poses

    rot, pos = frame_poses(spec, q)
    axes = np.stack([rot[:, i] @ _UNIT[j.axis] for i, j in enumerate(spec.joints)], axis=1)
    return pos[:, :6], axes


@dataclass(eq=False)
class SimModel:
    path: Path
    fmt: str                                  # 'mjcf' or 'urdf'
    joint_names: tuple[str, ...]
    friction_eps: float = 0.01
    handle: object = field(default=None, repr=False)   # MjModel or pinocchio (model, data, xml)
    damping: np.ndarray = field(default_factory=lambda: np.zeros(6))
    friction: np.ndarray = field(default_factory=lambda: np.zeros(6))   # URDF <dynamics friction>

    def predict(self, q, qd, qdd) -> np.ndarray:
        """(N, 6) joint torques the model needs at the states [N·m]."""
        if self.fmt == "mjcf":
            from urident.sim.mujoco_model import inverse_dynamics

            return inverse_dynamics(self.handle, q, qd, qdd)
        return self.rigid(q, qd, qdd) + self.damping * qd + self.friction * np.tanh(qd / self.friction_eps)

    def rigid(self, q, qd, qdd) -> np.ndarray:
        """(N, 6) rigid body + rotor inertia (armature) part: no damping, no friction."""
        if self.fmt == "mjcf":
            from urident.sim.mujoco_model import inverse_dynamics

            damping = np.asarray(self.handle.dof_damping, float)
            return inverse_dynamics(self.handle, q, qd, qdd, frictionloss=False) - damping * qd
        import pinocchio as pin

        model, data = self.handle
        return np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd)])


def _geometry_mjcf(model, q):
    from urident.sim.mujoco_model import import_mujoco

    mj = import_mujoco()
    data = mj.MjData(model)
    anchors, axes = [], []
    for qk in q:
        data.qpos[:] = qk
        mj.mj_kinematics(model, data)
        anchors.append(np.array(data.xanchor[:6]))
        axes.append(np.array(data.xaxis[:6]))
    return np.array(anchors), np.array(axes)


def _check_chain(path, spec, names, anchors, axes) -> None:
    q = check_poses(spec)
    ref_pos, ref_axes = spec_joint_geometry(spec, q)
    for i, name in enumerate(names):
        d = np.linalg.norm(anchors[:, i] - ref_pos[:, i], axis=1)
        k = int(np.argmax(d))
        if d[k] > POSITION_TOL_M:
            raise SimModelError(f"{path}: <joint name={name!r}>: its anchor is {1000 * d[k]:.1f} mm from {spec.name}'s joint "
                                f"{i + 1} ({spec.joints[i].name}) at q = {np.round(q[k], 3).tolist()}: not "
                                f"the same kinematic chain (tolerance 1 mm)")
        ang = np.arccos(np.clip(np.sum(axes[:, i] * ref_axes[:, i], axis=1), -1, 1))
        k = int(np.argmax(ang))
        if ang[k] > AXIS_TOL_RAD:
            raise SimModelError(f"{path}: <joint name={name!r}>: its axis is {ang[k]:.3f} rad from {spec.name}'s joint "
                                f"{i + 1} ({spec.joints[i].name}) at q = {np.round(q[k], 3).tolist()}: not "
                                f"the same kinematic chain (tolerance 0.01 rad)")


def _load_mjcf(path: Path, spec) -> SimModel:
    from urident.sim.mujoco_model import import_mujoco, load_model

    try:
        ET.parse(path)
    except ET.ParseError as exc:
        raise SimModelError(f"{path}: not valid XML: {exc}") from None
    except OSError as exc:
        raise SimModelError(f"{path}: cannot read: {exc.strerror or exc}") from None
    mj = import_mujoco()
    model = load_model(path)
    names = []
    for j in range(model.njnt):
        name = mj.mj_id2name(model, mj.mjtObj.mjOBJ_JOINT, j) or f"#{j}"
        kind = mj.mjtJoint(model.jnt_type[j]).name.replace("mjJNT_", "").lower()
        if kind != "hinge":
            raise SimModelError(f"{path}: <joint name={name!r} type={kind!r}>: urident maps only the "
                                f"six hinge joints of {spec.name}")
        names.append(name)
    if len(names) != len(spec.joints):
        raise SimModelError(f"{path}: {len(names)} hinge joints, {spec.name} has {len(spec.joints)}"
                            + (f" (missing after <joint name={names[-1]!r}>)" if 0 < len(names) < 6 else ""))
    anchors, axes = _geometry_mjcf(model, check_poses(spec))
    _check_chain(path, spec, names, anchors, axes)
    return SimModel(path, "mjcf", tuple(names), handle=model, damping=np.array(model.dof_damping, float))


def _load_urdf(path: Path, spec, friction_eps: float) -> SimModel:
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SimModelError(f"{path}: not valid XML: {exc}") from None
    except OSError as exc:
        raise SimModelError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if root.tag != "robot":
        raise SimModelError(f"{path}: <{root.tag}>: a URDF's root element is <robot>")
    moving, damping, friction, local_axes = [], [], [], []
    for joint in root.iter("joint"):
        name, kind = joint.get("name", "?"), joint.get("type", "?")
        if joint.find("mimic") is not None:
            raise SimModelError(f"{path}: <joint name={name!r}> has a <mimic> element: urident cannot map "
                                f"a coupled joint")
        if kind == "fixed":
            continue
        if kind != "revolute":
            raise SimModelError(f"{path}: <joint name={name!r} type={kind!r}>: urident maps only revolute "
                                f"joints with limits" + (" (a continuous joint has no limits and two "
                                                         "configuration coordinates)" if kind == "continuous" else ""))
        dyn = joint.find("dynamics")
        for attr in ("damping", "friction"):
            text = dyn.get(attr) if dyn is not None else None
            if text is not None and not _nonnegative(text):
                raise SimModelError(f"{path}: <joint name={name!r}>: <dynamics {attr}={text!r}>: must be a "
                                    "finite number >= 0")
        try:
            damping.append(float(dyn.get("damping", 0)) if dyn is not None else 0.0)
            friction.append(float(dyn.get("friction", 0)) if dyn is not None else 0.0)
            axis = joint.find("axis")
            local_axes.append(np.array([float(v) for v in (axis.get("xyz", "1 0 0") if axis is not None
                                                           else "1 0 0").split()]))
        except ValueError:
            raise SimModelError(f"{path}: <joint name={name!r}>: <dynamics> or <axis> is not numeric") from None
        moving.append(name)
    if len(moving) != len(spec.joints):
        raise SimModelError(f"{path}: {len(moving)} revolute joints, {spec.name} has {len(spec.joints)}")
    _check_urdf_inertials(path, root)
    import pinocchio as pin

    from urident.quiet import captured_fds

    try:
        with captured_fds() as said:     # urdfdom's C++ parser prints its errors itself
            model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as exc:
        why = said.first_line("Error:").replace("Error:", "").strip()
        raise SimModelError(f"{path}: Pinocchio cannot load it: {' '.join(str(exc).split())}"
                            + (f" (urdfdom: {why})" if why else "")) from None
    names = tuple(model.names[1:])
    if list(names) != moving or model.nq != 6:
        raise SimModelError(f"{path}: the joints do not form one chain of {len(spec.joints)} revolute joints "
                            f"(Pinocchio sees {list(names)})")
    data = model.createData()
    anchors, axes = [], []
    for q in check_poses(spec):
        pin.forwardKinematics(model, data, q)
        anchors.append([data.oMi[i + 1].translation.copy() for i in range(6)])
        axes.append([data.oMi[i + 1].rotation @ (a / np.linalg.norm(a)) for i, a in enumerate(local_axes)])
    _check_chain(path, spec, names, np.array(anchors), np.array(axes))
    return SimModel(path, "urdf", names, friction_eps, (model, data), np.array(damping), np.array(friction))


def _nonnegative(text: str) -> bool:
    try:
        v = float(text)
    except ValueError:
        return False
    return math.isfinite(v) and v >= 0


def _check_urdf_inertials(path: Path, root) -> None:
    """Every link's <inertial> mass (> 0) and inertia entries finite, named before urdfdom sees
    them (its own messages go to the terminal and name no element)."""
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        where = f"{path}: <link name={link.get('name', '?')!r}>: <inertial>"
        mass = inertial.find("mass")
        value = None if mass is None else mass.get("value")
        if value is not None and not (_nonnegative(value) and float(value) > 0):
            raise SimModelError(f"{where}: <mass value={value!r}>: must be a finite number > 0")
        inertia = inertial.find("inertia")
        for attr in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
            text = None if inertia is None else inertia.get(attr)
            try:
                ok = text is None or math.isfinite(float(text))
            except ValueError:
                ok = False
            if not ok:
                raise SimModelError(f"{where}: <inertia {attr}={text!r}>: must be a finite number")


def load_sim_model(path: str | Path, spec, friction_eps: float = 0.01) -> SimModel:
    """The simulator model at ``path`` (MJCF or URDF, by suffix), checked against ``spec``."""
    path = Path(path)
    fmt = model_format(path)
    if not path.is_file():
        raise SimModelError(f"{path}: no such file")
    sim = _load_mjcf(path, spec) if fmt == "mjcf" else _load_urdf(path, spec, friction_eps)
    _check_torque_scale(sim, spec)
    return sim


#: A model whose gravity torque at rest exceeds this many times a joint's rated torque is no model
#: of the arm (the arm holds itself with margin): a mass in grams, a typo, 1e300.
TORQUE_SCALE_LIMIT = 10.0


def _check_torque_scale(sim: SimModel, spec) -> None:
    """SimModelError when the model's torques at rest, at the check poses, are not finite or beyond
    :data:`TORQUE_SCALE_LIMIT` × the robot file's rated torques (its masses are not the arm's)."""
    q = check_poses(spec)
    zero = np.zeros_like(q)
    try:
        tau = sim.predict(q, zero, zero)
    except ConfigError as exc:
        raise SimModelError(f"{sim.path}: {exc}") from None
    limit = TORQUE_SCALE_LIMIT * np.asarray(spec.tau_max, dtype=float)
    bad = ~np.isfinite(tau) | (np.abs(tau) > limit)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise SimModelError(f"{sim.path}: its gravity torque on joint {j + 1} at rest is {tau[k, j]:.4g} N·m, "
                            f"beyond {TORQUE_SCALE_LIMIT:g} × the joint's rated {spec.tau_max[j]:g} N·m: "
                            "are its masses the arm's (kg, not g)?")
