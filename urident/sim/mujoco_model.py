"""MuJoCo, the optional simulator: the only module that imports ``mujoco``.

``inverse_dynamics(xml, q, qd, qdd)`` runs ``mj_inverse`` at every state and returns the joint
torques (N, 6) [N·m] the model needs: rigid body + armature·q̈ + damping·q̇ + the frictionloss
constraint's force (+ gravity, from the file's ``<option gravity>``). Contacts are disabled for it:
a recorded trajectory passed the collision checks, and a touching capsule pair must not add forces.

The arm's angles are read from ``qpos0``: MuJoCo sets a hinge's ``qpos0`` to its ``ref`` (the qpos
at which the bodies are as the file places them), so the arm's angle q is qpos − ref, and every
state here sets qpos = qpos0 + q. Every other joint (a gripper's) is held at its ``qpos0``, still;
free joints are removed first (:func:`welded`).
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

import numpy as np

from urident.errors import ConfigError, UridentError

INSTALL_HINT = "MuJoCo is not installed: pip install 'urident[mujoco]' (or '.[mujoco]' in a checkout)"


class MujocoModelError(ConfigError):
    """An MJCF file MuJoCo cannot load, or one that does not fit the robot."""


def import_mujoco():
    try:
        import mujoco
    except ImportError:
        raise UridentError(INSTALL_HINT) from None
    return mujoco


@contextlib.contextmanager
def _warnings_kept(mujoco) -> Iterator[list[str]]:
    """MuJoCo's warnings collected instead of printed and appended to MUJOCO_LOG.TXT in the working
    directory (what it does without a user handler)."""
    said: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: said.append(" ".join(str(msg).split())))
    try:
        yield said
    finally:
        mujoco.set_mju_user_warning(previous)


def load_model(source: str | Path, *, text: bool = False):
    """``mujoco.MjModel`` from an MJCF file (or its ``text``); MujocoModelError naming the file, also
    when MuJoCo warns while loading it (a NaN in the XML, for one)."""
    mujoco = import_mujoco()
    label = "MJCF text" if text else str(source)
    with _warnings_kept(mujoco) as said:
        try:
            model = (mujoco.MjModel.from_xml_string(str(source)) if text
                     else mujoco.MjModel.from_xml_path(str(source)))
        except ValueError as exc:   # MuJoCo's parse/compile errors
            message = " ".join(str(exc).split())
            raise MujocoModelError(f"{label}: MuJoCo cannot load it: {message}"
                                   + (f" (MuJoCo warned: {said[0]})" if said else "")) from None
    if said:
        raise MujocoModelError(f"{label}: MuJoCo warns: {said[0]}")
    return model


def hinge_joints(model) -> list[str]:
    """Names of the model's hinge joints in tree order."""
    mujoco = import_mujoco()
    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]


def inverse_dynamics(model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *,
                     frictionloss: bool = True, qpos_adr=None, dof_adr=None) -> np.ndarray:
    """(N, 6) joint torques of ``model`` (an MjModel, an MJCF path) at the states (N, 6); with
    ``qpos_adr``/``dof_adr`` (6,) the arm's joints among more (the others held at ``qpos0``, still)."""
    mujoco = import_mujoco()
    if not hasattr(model, "nv"):
        model = load_model(model)
    if qpos_adr is None:
        if model.nv != q.shape[1] or model.nq != q.shape[1]:
            raise MujocoModelError(f"the MuJoCo model has {model.nv} degrees of freedom, the log {q.shape[1]}")
        qpos_adr = dof_adr = np.arange(q.shape[1])
    qpos_adr, dof_adr = np.asarray(qpos_adr), np.asarray(dof_adr)
    flags = model.opt.disableflags
    model.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | (
        0 if frictionloss else int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS))
    try:
        with _warnings_kept(mujoco) as said:
            data = mujoco.MjData(model)
            data.qpos[:] = model.qpos0
            out = np.empty_like(np.asarray(q, dtype=float))
            for k in range(q.shape[0]):
                data.qpos[qpos_adr] = model.qpos0[qpos_adr] + q[k]
                data.qvel[dof_adr] = qd[k]
                data.qacc[dof_adr] = qdd[k]
                mujoco.mj_inverse(model, data)
                out[k] = data.qfrc_inverse[dof_adr]
        if said or not np.all(np.isfinite(out)):
            raise MujocoModelError("MuJoCo's inverse dynamics of the model "
                                   + (f"warns: {said[0]}" if said else "is not finite at every state"))
        return out
    finally:
        model.opt.disableflags = flags


#: a stand-in for a mesh file that is not there (a tetrahedron of 1 cm): the kinematics and the
#: explicit inertials do not need the visual meshes a user removed
_PLACEHOLDER_OBJ = b"v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 0 0 0.01\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def _missing_meshes(spec, path: Path) -> list[str]:
    """The mesh files the model names that are not on disk (relative to its meshdir)."""
    base = path.parent / (spec.meshdir or "")
    return [m.file for m in spec.meshes if m.file and not (base / m.file).is_file() and not Path(m.file).is_file()]


def load_spec(path: str | Path):
    """(``mujoco.MjSpec``, compiled ``MjModel``, missing mesh files) of the MJCF at ``path``: MuJoCo
    resolves its includes, default classes, childclasses and angle units. Mesh files that are not
    there are compiled as a small placeholder (named in the third item) unless a body's inertia
    comes from such a mesh; MujocoModelError naming the file otherwise."""
    mujoco = import_mujoco()
    path = Path(path)
    with _warnings_kept(mujoco) as said:
        spec, model, missing = _load_spec(mujoco, path)
    if said:  # a NaN in the XML, for one
        raise MujocoModelError(f"{path}: MuJoCo warns: {said[0]}")
    return spec, model, missing


def _load_spec(mujoco, path: Path):
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise MujocoModelError(f"{path}: MuJoCo cannot load it: {' '.join(str(exc).split())}") from None
    missing = _missing_meshes(spec, path)
    if missing:
        if any(not f.lower().endswith(".obj") for f in missing):
            other = next(f for f in missing if not f.lower().endswith(".obj"))
            raise MujocoModelError(f"{path}: mesh file {other!r} not found (meshdir {spec.meshdir!r})")
        spec.assets = {**spec.assets, **{f: _PLACEHOLDER_OBJ for f in missing}}
        names = {m.name or Path(m.file).stem for m in spec.meshes if m.file in missing}
        geom_inertia = spec.compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE
        for g in spec.geoms:
            if g.type == mujoco.mjtGeom.mjGEOM_MESH and g.meshname in names:
                body = g.parent
                if geom_inertia or not body.explicitinertial:
                    raise MujocoModelError(f"{path}: body {body.name!r} takes its mass from mesh {g.meshname!r}, "
                                           f"whose file is not found (meshdir {spec.meshdir!r})")
    try:
        model = spec.compile()
    except ValueError as exc:
        raise MujocoModelError(f"{path}: MuJoCo cannot load it: {' '.join(str(exc).split())}") from None
    return spec, model, missing


def welded(spec, names):
    """The ``MjModel`` of a copy of ``spec`` without the joints ``names`` (free joints): their
    bodies stay where the file places them (a free joint's ``qpos0``), fixed to their parents, so
    inertias seen by the other joints (``dof_invweight0``, the frictionloss softness) are a fixed
    base's."""
    mujoco = import_mujoco()
    edit = spec.copy()
    for name in names:
        edit.delete(edit.joint(name))
    with _warnings_kept(mujoco) as said:
        try:
            model = edit.compile()
        except ValueError as exc:
            raise MujocoModelError(f"MuJoCo cannot fix the free joints {', '.join(names)}: "
                                   f"{' '.join(str(exc).split())}") from None
    if said:
        raise MujocoModelError(f"MuJoCo warns with the free joints fixed: {said[0]}")
    return model


def joint_table(model) -> list[tuple[str, str, int, int, int]]:
    """(name, type, qpos address, dof address, body id) of every joint, in tree order."""
    mujoco = import_mujoco()
    return [(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}",
             mujoco.mjtJoint(model.jnt_type[j]).name.replace("mjJNT_", "").lower(),
             int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j]), int(model.jnt_bodyid[j]))
            for j in range(model.njnt)]


def joint_lines(model, joint_ids, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World anchors and axes (N, 6, 3) of ``joint_ids`` at the arm poses ``q`` (N, 6) (the other
    joints at ``qpos0``)."""
    mujoco = import_mujoco()
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    adr = model.jnt_qposadr[list(joint_ids)]
    anchors, axes = [], []
    for qk in np.atleast_2d(q):
        data.qpos[adr] = model.qpos0[adr] + qk
        mujoco.mj_kinematics(model, data)
        anchors.append(np.array(data.xanchor[list(joint_ids)]))
        axes.append(np.array(data.xaxis[list(joint_ids)]))
    return np.array(anchors), np.array(axes)


def body_poses(model, joint_ids, q: np.ndarray) -> dict:
    """At the arm pose ``q`` (6,): per body its frame (``xpos`` (nbody, 3), ``xmat`` (nbody, 3, 3)),
    centre of mass ``xipos``, inertia about it in world axes ``inertia`` (nbody, 3, 3), ``mass`` and
    ``arm_joint``: the 0-based arm joint that moves it (the nearest one at or above it), −1 for the
    base."""
    mujoco = import_mujoco()
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    adr = model.jnt_qposadr[list(joint_ids)]
    data.qpos[adr] = model.qpos0[adr] + q
    mujoco.mj_kinematics(model, data)
    joint_body = {int(model.jnt_bodyid[j]): i for i, j in enumerate(joint_ids)}
    arm = np.full(model.nbody, -1)
    for b in range(1, model.nbody):        # parents come before children
        arm[b] = joint_body.get(b, arm[model.body_parentid[b]])
    ximat = np.array(data.ximat).reshape(-1, 3, 3)
    inertia = np.einsum("bij,bj,bkj->bik", ximat, np.array(model.body_inertia), ximat)
    return {"xpos": np.array(data.xpos), "xmat": np.array(data.xmat).reshape(-1, 3, 3),
            "xipos": np.array(data.xipos), "inertia": inertia, "mass": np.array(model.body_mass),
            "arm_joint": arm}


def spec_to_xml(spec) -> str:
    """The MJCF text of ``spec`` (compiled first, as MuJoCo's writer needs). MuJoCo writes
    ``angle="radian"`` with the elements' compiled values but the default classes' joint angles as
    given: with ``angle="degree"`` those are turned into radians here (``spec`` is changed)."""
    mujoco = import_mujoco()
    with _warnings_kept(mujoco):  # what it says went into the diagnosis already: not to the cwd
        return _spec_to_xml(mujoco, spec)


def _spec_to_xml(mujoco, spec) -> str:
    import xml.etree.ElementTree as ET

    try:
        spec.compile()
        text = spec.to_xml()
        if spec.compiler.degree:
            names = {d.get("class") for d in ET.fromstring(text).iter("default")} - {None} | {"main"}
            for name in names:
                joint = spec.find_default(name).joint
                if joint.type in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_BALL):
                    joint.range = np.deg2rad(joint.range)
                    joint.ref, joint.springref = np.deg2rad(joint.ref), np.deg2rad(joint.springref)
            spec.compile()
            text = spec.to_xml()
        return text
    except ValueError as exc:
        raise MujocoModelError(f"MuJoCo cannot write the corrected model: {' '.join(str(exc).split())}") from None


def tendon_frictionloss(model, names) -> np.ndarray:
    """The frictionloss of the tendon of each name (0 where there is none)."""
    mujoco = import_mujoco()
    out = np.zeros(len(names))
    for k, name in enumerate(names):
        t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, name)
        if t >= 0:
            out[k] = model.tendon_frictionloss[t]
    return out


#: the MuJoCo versions whose XML writer's precision urident sets (a private, version-specific hook
#: of libmujoco: an int of significant digits, thread-local); others write MuJoCo's 6 digits
_PRECISION_HOOK_VERSIONS = ("3.3.7",)
#: significant digits of a written double that reads back exactly
FULL_DIGITS = 17


@contextlib.contextmanager
def _full_precision(mujoco) -> Iterator[bool]:
    """MuJoCo's writer at :data:`FULL_DIGITS` digits inside (True) where the version has the hook,
    6 digits otherwise (False): an exported estimate must read back as it was identified."""
    import ctypes

    lib = None
    if mujoco.__version__ in _PRECISION_HOOK_VERSIONS:
        found = sorted(Path(mujoco.__file__).parent.glob("libmujoco.so*")) + sorted(
            Path(mujoco.__file__).parent.glob("libmujoco*.dylib")) + sorted(Path(mujoco.__file__).parent.glob("mujoco*.dll"))
        try:
            lib = ctypes.CDLL(str(found[0])) if found else None
            get, put = lib._mjPRIVATE__get_xml_precision, lib._mjPRIVATE__set_xml_precision
        except (OSError, AttributeError):
            lib = None
    if lib is None:
        yield False
        return
    get.restype, put.argtypes = ctypes.c_int, [ctypes.c_int]
    before = get()
    put(FULL_DIGITS)
    try:
        yield True
    finally:
        put(before)


def arm_xml(arm) -> str:
    """The MJCF text of a :class:`urident.sim.mjcf.MjcfArm`, built as a ``mujoco.MjSpec`` and written
    by MuJoCo (17 significant digits; an XML declaration and the arm's notes as the top comment)."""
    mujoco = import_mujoco()
    spec = mujoco.MjSpec()
    spec.modelname = arm.name
    if arm.comment:
        spec.comment = " " + "\n     ".join(arm.comment) + " "
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.option.gravity = list(arm.gravity)
    collision = spec.add_default("collision", spec.default)
    collision.geom.contype, collision.geom.conaffinity, collision.geom.group = 1, 1, 3
    collision.geom.rgba = [0.6, 0.6, 0.7, 1.0]

    def capsules(body, items):
        for fromto, radius in items:
            body.add_geom(collision, type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=list(fromto), size=[radius, 0, 0])

    def add(parent, b):
        body = parent.add_body(name=b.name)
        body.pos, body.quat = list(b.pos), list(b.quat)
        body.explicitinertial = True
        body.mass, body.ipos, body.fullinertia = b.mass, list(b.com), list(b.fullinertia)
        if b.joint is not None:
            j = b.joint
            joint = body.add_joint(name=j.name, type=mujoco.mjtJoint.mjJNT_HINGE)
            joint.axis, joint.range = list(j.axis), list(j.range)
            joint.armature, joint.damping, joint.frictionloss = j.armature, j.damping, j.frictionloss
            if j.solref is not None:
                joint.solref_friction, joint.solimp_friction = list(j.solref), list(j.solimp)
        capsules(body, b.capsules)
        return body

    capsules(spec.worldbody, arm.base_capsules)
    parent = spec.worldbody
    for link in arm.links:
        parent = add(parent, link)
    parent.add_site(name="tool0", pos=list(arm.tool[0]), quat=list(arm.tool[1]))
    if arm.payload is not None:
        add(parent, arm.payload)
    for a, b in arm.excludes:
        spec.add_exclude(bodyname1=a, bodyname2=b)
    for t in arm.tendons:
        tendon = spec.add_tendon(name=t.name, frictionloss=t.frictionloss, solref_friction=list(t.solref),
                                 solimp_friction=list(t.solimp))
        tendon.wrap_joint(t.joint, 1.0)
    for joint, limit in arm.motors:
        actuator = spec.add_actuator(name=joint, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_motor()
        actuator.ctrlrange = [-limit, limit]
    with _warnings_kept(mujoco), _full_precision(mujoco):
        try:
            spec.compile()
            text = spec.to_xml()
        except ValueError as exc:
            raise MujocoModelError(f"MuJoCo cannot build the model: {' '.join(str(exc).split())}") from None
    return '<?xml version="1.0"?>\n' + text
