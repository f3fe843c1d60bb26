"""A user's simulator model (MJCF or URDF) of a robot of ours: loaded, checked against the robot
file's kinematic chain, and asked for its inverse dynamics.

* MJCF: MuJoCo compiles it (``mujoco.MjSpec``: includes, default classes, childclass, angle units,
  frames in any orientation form); ``mj_inverse`` gives the torques (contacts off; armature, damping
  and frictionloss as MuJoCo has them). Mesh files that are not there do not stop it unless a
  body's mass comes from one. Joints other than the arm's six (a gripper's) are held at ``qpos0``
  (URDF: Pinocchio's reduced model, the others locked at the neutral configuration).
* URDF: Pinocchio's RNEA plus ``<dynamics damping friction>`` as damping·q̇ + friction·tanh(q̇/ε)
  (URDF does not say how its Coulomb friction is smoothed; urident's ε).

The arm's six joints: the model's six hinge (revolute) joints in tree order; among more, those named
like the robot's (``shoulder_pan_joint``, ``joint1``, … after any prefix such as ``ur5e_``), or the
ones a ``joint_map`` names. The chain must be the robot file's in the sense of
:mod:`urident.sim.chain`: the joint axis lines agree after the best placement of the base about the
vertical; what is left per joint is a finding (``SimModel.alignment``) below the refusal limits.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from urident.errors import ConfigError
from urident.sim.chain import Alignment, align, match_joint_names, refusal

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


@dataclass(frozen=True, eq=False)
class DriveTerms:
    """A model's joint drive terms, (6,) each; also read by name (``drive["damping"]``)."""

    armature: np.ndarray        # [kg·m²]
    damping: np.ndarray         # [N·m·s/rad]
    frictionloss: np.ndarray    # [N·m]

    KEYS = ("armature", "damping", "frictionloss")

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self.KEYS:
            raise KeyError(key)
        return getattr(self, key)

    def keys(self) -> tuple[str, ...]:
        return self.KEYS

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in self.KEYS}


@dataclass(eq=False)
class SimModel:
    path: Path
    fmt: str                                  # 'mjcf' or 'urdf'
    joint_names: tuple[str, ...]
    friction_eps: float = 0.01
    handle: object = field(default=None, repr=False)   # MjModel or pinocchio (model, data)
    damping: np.ndarray = field(default_factory=lambda: np.zeros(6))
    friction: np.ndarray = field(default_factory=lambda: np.zeros(6))   # URDF <dynamics friction>
    #: the user's base placed on the robot's, and what each axis line is off after it
    alignment: Alignment | None = None
    mjspec: object = field(default=None, repr=False)   # MJCF: the user's mujoco.MjSpec (edited by --write-sim)
    joint_ids: tuple[int, ...] = ()                    # MJCF: the arm's joint ids
    qpos_adr: np.ndarray | None = None
    dof_adr: np.ndarray | None = None
    missing_meshes: tuple[str, ...] = ()
    #: what urident assumed of the file, one line each (a free joint held still, a joint's ref)
    notes: tuple[str, ...] = ()

    def predict(self, q, qd, qdd) -> np.ndarray:
        """(N, 6) joint torques the model needs at the states [N·m]."""
        if self.fmt == "mjcf":
            from urident.sim.mujoco_model import inverse_dynamics

            return inverse_dynamics(self.handle, q, qd, qdd, qpos_adr=self.qpos_adr, dof_adr=self.dof_adr)
        return self.rigid(q, qd, qdd) + self.damping * qd + self.friction * np.tanh(qd / self.friction_eps)

    def rigid(self, q, qd, qdd) -> np.ndarray:
        """(N, 6) rigid body + rotor inertia (armature) part: no damping, no friction."""
        if self.fmt == "mjcf":
            from urident.sim.mujoco_model import inverse_dynamics

            return inverse_dynamics(self.handle, q, qd, qdd, frictionloss=False, qpos_adr=self.qpos_adr,
                                    dof_adr=self.dof_adr) - self.drive()["damping"] * qd
        import pinocchio as pin

        model, data = self.handle
        return np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd)])

    def drive(self) -> "DriveTerms":
        """The model's joint drive terms (6,) each: ``armature`` [kg·m²] (URDF: none), ``damping``
        [N·m·s/rad] and ``frictionloss`` [N·m] (MJCF: the joint's plus its ``<joint>_friction``
        tendon's)."""
        if self.fmt != "mjcf":
            return DriveTerms(np.zeros(6), np.array(self.damping, float), np.array(self.friction, float))
        from urident.sim.mujoco_model import tendon_frictionloss

        m = self.handle
        fl = np.array(m.dof_frictionloss[self.dof_adr], float)
        fl += tendon_frictionloss(m, [f"{n}_friction" for n in self.joint_names])
        return DriveTerms(np.array(m.dof_armature[self.dof_adr], float),
                          np.array(m.dof_damping[self.dof_adr], float), fl)

    def link_params(self, spec) -> np.ndarray:
        """(6, 10) the model's link parameters in the paper's form (m, m·ρ, A … F about K_i in K_i's
        axes; every body a joint moves lumped into its link, the user's base placed on the robot's
        by the alignment), read at q = 0."""
        from urident.model.kinematics import frame_poses
        from urident.model.parameters import body_params

        rot, pos = frame_poses(spec, np.zeros((1, 6)))
        r_align = self.alignment.rotation
        out = np.zeros((6, 10))
        for i, (m, com, inertia) in enumerate(self._link_inertials()):
            if m <= 0:
                continue
            c_k = rot[0, i].T @ (self.alignment.to_robot(com) - pos[0, i])
            i_k = rot[0, i].T @ r_align @ inertia @ r_align.T @ rot[0, i]
            out[i] = body_params(m, c_k, i_k)
        return out

    def _link_inertials(self) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """Per arm joint: (mass, world centre of mass, world inertia about it) of what it moves
        itself (not through later joints), at q = 0, in the user's world."""
        out = []
        if self.fmt == "mjcf":
            from urident.sim.mujoco_model import body_poses

            b = body_poses(self.handle, self.joint_ids, np.zeros(6))
            for i in range(6):
                sel = np.flatnonzero(b["arm_joint"] == i)
                out.append(_lump(b["mass"][sel], b["xipos"][sel], b["inertia"][sel]))
            return out
        import pinocchio as pin

        model, data = self.handle
        pin.forwardKinematics(model, data, np.zeros(model.nq))
        for i in range(6):
            inert, frame = model.inertias[i + 1], data.oMi[i + 1]
            out.append((float(inert.mass), frame.rotation @ inert.lever + frame.translation,
                        frame.rotation @ inert.inertia @ frame.rotation.T))
        return out


def _lump(masses, coms, inertias) -> tuple[float, np.ndarray, np.ndarray]:
    m = float(np.sum(masses))
    if m <= 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = masses @ coms / m
    total = np.zeros((3, 3))
    for mk, ck, ik in zip(masses, coms, inertias):
        d = ck - com
        total += ik + mk * (d @ d * np.eye(3) - np.outer(d, d))
    return m, com, total


def _arm_joints(path, spec, names: list[str], joint_map: dict | None, what: str) -> list[int]:
    """Indices into ``names`` of the robot's six joints, in the robot's order."""
    robot = spec.joint_names
    if joint_map:
        unknown = [k for k in joint_map if k not in robot and not (k.isdigit() and int(k) < len(robot))
                   and k.removesuffix("_joint") not in robot]
        if unknown:
            raise SimModelError(f"--joint-map: {unknown[0]!r} is not a joint of {spec.name} ({', '.join(robot)})")
        out = []
        for i, rj in enumerate(robot):
            user = joint_map.get(rj, joint_map.get(str(i), joint_map.get(f"{rj}_joint")))
            if user is None:
                raise SimModelError(f"--joint-map: {spec.name}'s joint {rj!r} is not mapped "
                                    f"(its joints: {', '.join(robot)})")
            if user not in names:
                raise SimModelError(f"--joint-map: {path} has no {what} joint {user!r} (it has: {', '.join(names)})")
            out.append(names.index(user))
        return out
    if len(names) == len(robot):
        return list(range(len(robot)))
    matched = match_joint_names(names, robot)
    if matched is None:
        raise SimModelError(f"{path}: {len(names)} {what} joints ({', '.join(names)}), {spec.name} has "
                            f"{len(robot)}: name the arm's with --joint-map "
                            f"{','.join(f'{r}=...' for r in robot)}")
    return [names.index(n) for n in matched]


def _check_chain(path, spec, names, anchors, axes) -> Alignment:
    """The alignment of the model's axis lines on the robot's; SimModelError for another chain."""
    q = check_poses(spec)
    ref_pos, ref_axes = spec_joint_geometry(spec, q)
    alignment = align(ref_pos, ref_axes, anchors, axes)
    bad = refusal(alignment)
    if bad is not None:
        i, why = bad
        raise SimModelError(f"{path}: <joint name={names[i]!r}> ({spec.name}'s joint {i + 1}, "
                            f"{spec.joints[i].name}): {why}: not the same kinematic chain")
    return alignment


def _load_mjcf(path: Path, spec, joint_map=None) -> SimModel:
    from urident.sim.mujoco_model import joint_lines, joint_table, load_spec, welded

    try:
        ET.parse(path)
    except ET.ParseError as exc:
        raise SimModelError(f"{path}: not valid XML: {exc}") from None
    except OSError as exc:
        raise SimModelError(f"{path}: cannot read: {exc.strerror or exc}") from None
    mjspec, model, missing = load_spec(path)
    table = joint_table(model)
    # a scene that puts the arm on a free joint: the base fixed where the file places it (the free
    # joint's qpos0); removed, not held still, so that the frictionloss softness (MuJoCo's
    # dof_invweight0) is the fixed base's. --write-sim keeps it in the written file.
    free = [name for name, kind, *_ in table if kind == "free"]
    notes = [f"<joint name={name!r} type='free'>: held still at its qpos0 (the base fixed where the file "
             "places it)" for name in free]
    if free:
        model = welded(mjspec, free)
        table = joint_table(model)
    hinges = [row for row in table if row[1] == "hinge"]
    if len(hinges) < len(spec.joints):
        other = next((r for r in table if r[1] != "hinge"), None)
        if other is not None:
            raise SimModelError(f"{path}: <joint name={other[0]!r} type={other[1]!r}>: urident maps only "
                                f"hinge joints to the six of {spec.name}")
        raise SimModelError(f"{path}: {len(hinges)} hinge joints, {spec.name} has {len(spec.joints)}"
                            + (f" (missing after <joint name={hinges[-1][0]!r}>)" if hinges else ""))
    picked = _arm_joints(path, spec, [r[0] for r in hinges], joint_map, "hinge")
    arm = [hinges[k] for k in picked]
    names = tuple(r[0] for r in arm)
    joint_ids = tuple(table.index(r) for r in arm)
    qpos_adr = np.array([r[2] for r in arm])
    notes += [f"<joint name={name!r}> has ref = {model.qpos0[a]:.6g} rad: its angle is read as qpos − ref "
              "(drive it with qpos = q + ref)" for name, a in zip(names, qpos_adr) if model.qpos0[a] != 0]
    anchors, axes = joint_lines(model, joint_ids, check_poses(spec))
    alignment = _check_chain(path, spec, names, anchors, axes)
    return SimModel(path, "mjcf", names, handle=model, damping=np.array(model.dof_damping[[r[3] for r in arm]], float),
                    alignment=alignment, mjspec=mjspec, joint_ids=joint_ids,
                    qpos_adr=qpos_adr, dof_adr=np.array([r[3] for r in arm]),
                    missing_meshes=tuple(missing), notes=tuple(notes))


def _load_urdf(path: Path, spec, friction_eps: float, joint_map=None) -> SimModel:
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SimModelError(f"{path}: not valid XML: {exc}") from None
    except OSError as exc:
        raise SimModelError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if root.tag != "robot":
        raise SimModelError(f"{path}: <{root.tag}>: a URDF's root element is <robot>")
    rows = {}        # every moving joint: name → (type, mimic, damping, friction, local axis)
    for joint in root.iter("joint"):
        name, kind = joint.get("name", "?"), joint.get("type", "?")
        if kind == "fixed":
            continue
        dyn = joint.find("dynamics")
        for attr in ("damping", "friction"):
            text = dyn.get(attr) if dyn is not None else None
            if text is not None and not _nonnegative(text):
                raise SimModelError(f"{path}: <joint name={name!r}>: <dynamics {attr}={text!r}>: must be a "
                                    "finite number >= 0")
        try:
            axis = joint.find("axis")
            rows[name] = (kind, joint.find("mimic") is not None,
                          float(dyn.get("damping", 0)) if dyn is not None else 0.0,
                          float(dyn.get("friction", 0)) if dyn is not None else 0.0,
                          np.array([float(v) for v in (axis.get("xyz", "1 0 0") if axis is not None
                                                        else "1 0 0").split()]))
        except ValueError:
            raise SimModelError(f"{path}: <joint name={name!r}>: <dynamics> or <axis> is not numeric") from None
    revolute = [n for n, r in rows.items() if r[0] == "revolute" and not r[1]]
    if len(revolute) < len(spec.joints):
        for name, (kind, mimic, *_) in rows.items():
            if mimic:
                raise SimModelError(f"{path}: <joint name={name!r}> has a <mimic> element: urident cannot map "
                                    f"a coupled joint")
            if kind != "revolute":
                raise SimModelError(f"{path}: <joint name={name!r} type={kind!r}>: urident maps only revolute "
                                    f"joints with limits" + (" (a continuous joint has no limits and two "
                                                             "configuration coordinates)" if kind == "continuous" else ""))
        raise SimModelError(f"{path}: {len(revolute)} revolute joints, {spec.name} has {len(spec.joints)}")
    moving = [revolute[k] for k in _arm_joints(path, spec, revolute, joint_map, "revolute")]
    damping = [rows[n][2] for n in moving]
    friction = [rows[n][3] for n in moving]
    local_axes = [rows[n][4] for n in moving]
    _check_urdf_inertials(path, root)
    import pinocchio as pin

    from urident.quiet import captured_fds

    try:
        with captured_fds() as said:     # urdfdom's C++ parser prints its errors itself
            full = pin.buildModelFromUrdf(str(path))
        # the joints that are not the arm's (a gripper's) held at the neutral configuration
        locked = [full.getJointId(n) for n in full.names[1:] if n not in moving]
        model = pin.buildReducedModel(full, locked, pin.neutral(full)) if locked else full
    except (RuntimeError, ValueError) as exc:
        why = said.first_line("Error:").replace("Error:", "").strip()
        raise SimModelError(f"{path}: Pinocchio cannot load it: {' '.join(str(exc).split())}"
                            + (f" (urdfdom: {why})" if why else "")) from None
    names = tuple(model.names[1:])
    if list(names) != moving or model.nq != 6:
        raise SimModelError(f"{path}: the joints {moving} do not form one chain of {len(spec.joints)} revolute "
                            f"joints in that order (Pinocchio sees {list(names)})")
    data = model.createData()
    anchors, axes = [], []
    for q in check_poses(spec):
        pin.forwardKinematics(model, data, q)
        anchors.append([data.oMi[i + 1].translation.copy() for i in range(6)])
        axes.append([data.oMi[i + 1].rotation @ (a / np.linalg.norm(a)) for i, a in enumerate(local_axes)])
    alignment = _check_chain(path, spec, names, np.array(anchors), np.array(axes))
    return SimModel(path, "urdf", names, friction_eps, (model, data), np.array(damping), np.array(friction),
                    alignment=alignment)


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


def load_sim_model(path: str | Path, spec, friction_eps: float = 0.01, joint_map: dict | None = None) -> SimModel:
    """The simulator model at ``path`` (MJCF or URDF, by suffix), checked against ``spec``;
    ``joint_map``: :func:`urident.cli.options.joint_map`'s dict (robot joint name or
    0-based index as text → the model's joint name)."""
    path = Path(path)
    fmt = model_format(path)
    if not path.is_file():
        raise SimModelError(f"{path}: no such file")
    if fmt == "mjcf":
        sim = _load_mjcf(path, spec, joint_map)
        sim.friction_eps = friction_eps
    else:
        sim = _load_urdf(path, spec, friction_eps, joint_map)
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
