"""Write a user's simulator model with the corrections the gap found (``urident gap --write-sim``).

The user's file is edited, not regenerated. MJCF: through its ``mujoco.MjSpec`` (MuJoCo's own
editor), so default classes, childclasses, actuators, keyframes, meshes and the file's top comment
stay; MuJoCo's writer puts ``<include>`` files inline, writes actuators in their general form and
numbers with 6 significant digits (principal moments keep a + b ≥ c after that rounding), and
``meshdir``/``texturedir`` are rewritten to reach the same files from the written file's folder.
URDF: ElementTree on the user's file (comments kept), only ``<dynamics>`` and ``<inertial>`` change.

What changes, per attribute:

* joint ``armature`` (MJCF), ``damping``: the model's value plus the correction;
* Coulomb friction: MJCF ``frictionloss`` in the two pieces of :mod:`urident.sim.mjcf` (the joint's,
  with ``solreffriction``/``solimpfriction``, and a fixed tendon ``<joint>_friction``), so MuJoCo's
  force follows tanh(q̇/ε); URDF ``<dynamics friction>``;
* a link's mass, first moment (about the robot's joint frame K_i) and inertia (about K_i's origin):
  the ``<inertial>`` (``mass``, ``pos``, ``quat``, ``diaginertia``) of the bodies the joint moves,
  spread over them in proportion to their masses (MJCF; URDF: the joint's child link), each keeping
  its share of the inertia about K_i's origin as the correction's columns do;
* a payload: a point mass body/link ``payload`` near the tool point when positive (placed so that
  it carries the first-moment part too); a negative one (a tool the model carries and the arm
  does not) goes into link 6.

K_i is placed in the user's world through the model's base alignment (:mod:`urident.sim.chain`).
URDF has no armature (the caller lists it as not expressible).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from urident.errors import ConfigError
from urident.model.parameters import inertia_matrix


def _parse(path) -> ET.ElementTree:
    """The file with its comments kept."""
    return ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))


def _fmt(values) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.atleast_1d(values))


def _shift(x: np.ndarray) -> np.ndarray:
    """Parallel-axis term |x|²·1 − x·xᵀ (per kg)."""
    return x @ x * np.eye(3) - np.outer(x, x)


def _inertia(changes: dict, i: int) -> np.ndarray:
    """Link i's inertia change about K_i (K_i's axes); none when ``changes`` has no ``inertia``."""
    return np.asarray(changes["inertia"][i], float) if "inertia" in changes else np.zeros((3, 3))


def _robot_frames(sim, spec) -> tuple[np.ndarray, np.ndarray]:
    """The robot's joint frames K_1 … K_6 and the tool frame at q = 0 in the user's world
    (rotations (7, 3, 3), origins (7, 3)), through the model's alignment."""
    from urident.model.kinematics import frame_poses

    rot, pos = frame_poses(spec, np.zeros((1, 6)))
    return np.einsum("ji,kjl->kil", sim.alignment.rotation, rot[0]), sim.alignment.to_user(pos[0])


#: relative slack kept in the triangle inequality of written principal moments (6 written digits)
WRITE_MARGIN = 2e-5


def _principal(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(principal moments (3,), MuJoCo quaternion of the principal axes) of a symmetric inertia."""
    from urident.sim.mjcf import quaternion

    eig, vec = np.linalg.eigh((inertia + inertia.T) / 2)
    if np.linalg.det(vec) < 0:
        vec[:, 2] = -vec[:, 2]
    return _with_margin(eig), quaternion(vec)


def _with_margin(eig: np.ndarray) -> np.ndarray:
    """Principal moments with a + b >= c kept after MuJoCo's writer rounds them to 6 digits."""
    eig = np.array(eig, float)
    for k in range(3):
        others = [i for i in range(3) if i != k]
        short = eig[k] * (1 + WRITE_MARGIN) - eig[others].sum()
        if short > 0:
            eig[others] += short / 2
    return eig


def _loadable_after_writing(edit) -> None:
    """Bodies whose principal moments MuJoCo's 6-digit writer would round into a + b < c (a
    consistent estimate on its constraint's boundary) get :data:`WRITE_MARGIN` of slack; no other
    value changes."""
    model = edit.compile()
    bodies = {b.id: b for b in edit.bodies}
    for k in range(1, model.nbody):
        eig = np.array(model.body_inertia[k], float)
        rounded = np.array([float(f"{v:.6g}") for v in eig])
        if k in bodies and any(rounded[i] > rounded.sum() - rounded[i] for i in range(3)):
            body = bodies[k]
            body.explicitinertial = True
            body.mass, body.ipos = float(model.body_mass[k]), np.array(model.body_ipos[k])
            body.iquat, body.inertia = np.array(model.body_iquat[k]), _with_margin(eig)
            body.fullinertia = np.full(6, np.nan)


def _numbers(text: str) -> list[float]:
    return [float(v) for v in text.split()]


def _relocate_assets(mjspec, source: Path, out: Path) -> None:
    """Keep the mesh and texture files found from the written file's folder (MuJoCo resolves them
    relative to the model file's folder)."""
    import os

    src, dst = source.resolve().parent, out.resolve().parent
    if src == dst:
        return
    for attr in ("meshdir", "texturedir"):
        old = getattr(mjspec, attr) or ""
        if not os.path.isabs(old):
            setattr(mjspec, attr, os.path.relpath(src / old, dst) + "/")


def fold_payload(changes: dict, spec) -> dict:
    """``changes`` with the payload correction (a point mass at the tool point plus a first-moment
    change of link 6, about K_6) in a writable form: a positive mass stays a point mass ``payload``
    ``(mass, offset (3,))`` whose centre sits ``offset`` (K_6 axes) from the tool point so that it
    carries the first moment too; a negative one (the model carries a tool the arm does not) goes
    into link 6's mass, first moment and inertia about K_6, exactly the payload columns."""
    payload = changes.get("payload")
    if payload is None:
        return changes
    mass, first = float(payload[0]), np.asarray(payload[1], float)
    out = {k: (np.array(v, float) if k != "payload" else v) for k, v in changes.items()}
    out["inertia"] = np.array(out.get("inertia", np.zeros((6, 3, 3))), float)
    out["payload"] = None
    if mass > 0:
        out["payload"] = (mass, first / mass)
    else:
        tool = np.asarray(spec.tool_xyz, float)
        out["mass"][5] += mass
        out["first_moment"][5] += mass * tool + first
        out["inertia"][5] += mass * _shift(tool)
    return out


def _edit_bodies(sel, shares, b, rot_i, pos_i, dm, dh, di) -> dict | None:
    """{body id: (mass, ipos, inertia about the CoM in body axes)} with share s_k of the correction
    on body k (its own inertial replaced by ``b``'s lumped one when ``sel[k]`` is a tuple of bodies),
    or None when one would not be a real mass distribution."""
    from urident.sim.mjcf import mujoco_inertia

    new = {}
    for group, share in zip(sel, shares):
        group = tuple(group)
        m0 = float(sum(b["mass"][k] for k in group))
        com = (sum(b["mass"][k] * b["xipos"][k] for k in group) / m0) if m0 > 0 else b["xpos"][group[0]]
        about_k = sum(b["inertia"][k] + b["mass"][k] * _shift(b["xipos"][k] - pos_i) for k in group)
        about_k = about_k + share * rot_i @ di @ rot_i.T
        mass = m0 + share * dm
        if not mass > 0:
            return None
        new_com = pos_i + (m0 * (com - pos_i) + share * rot_i @ dh) / mass
        i_new = about_k - mass * _shift(new_com - pos_i)
        if np.linalg.eigvalsh(i_new).min() < -1e-12 * max(np.abs(about_k).max(), 1e-300):
            return None
        i_new, _ = mujoco_inertia(i_new)
        k = group[0]
        rb, xb = b["xmat"][k], b["xpos"][k]
        new[k] = (mass, rb.T @ (new_com - xb), rb.T @ i_new @ rb)
        for other in group[1:]:
            new[other] = (0.0, np.zeros(3), np.zeros((3, 3)))
    return new


def _link_edits(sim, rot, pos, b, changes) -> dict:
    """Per corrected link i: {body id: (mass, ipos, inertia about the CoM in body axes)} of the new
    inertials, or None when the correction leaves no real mass distribution. A link's correction
    is spread over the bodies it moves in proportion to their masses (a flange or gripper welded on
    takes its share), each keeping its share of the inertia about K_i (the columns' assumption);
    where that leaves one of them unreal (a tool the model carries taken off), the joint's body takes
    the whole link's mass with no joint of its own (those bodies keep mass 0) and the correction."""
    model = sim.handle
    out = {}
    for i in range(len(sim.joint_names)):
        dm, dh, di = changes["mass"][i], changes["first_moment"][i], _inertia(changes, i)
        if dm == 0 and not np.any(dh != 0) and not np.any(di != 0):
            continue
        own = int(model.jnt_bodyid[sim.joint_ids[i]])
        sel = [int(k) for k in np.flatnonzero((b["arm_joint"] == i) & (b["mass"] > 0))] or [own]
        total = float(sum(b["mass"][k] for k in sel))
        new = _edit_bodies([(k,) for k in sel], [b["mass"][k] / total if total > 0 else 1.0 / len(sel) for k in sel],
                           b, rot[i], pos[i], dm, dh, di)
        if new is None:
            welded = [k for k in sel if k != own and model.body_dofnum[k] == 0]
            moving = [k for k in sel if k != own and model.body_dofnum[k] > 0]
            new = _edit_bodies([(own, *welded)] + [(k,) for k in moving], [1.0] + [0.0] * len(moving),
                               b, rot[i], pos[i], dm, dh, di)
        out[i] = new
    return out


def _mjcf_text(sim, spec, changes: dict, notes, out: Path | None = None) -> str:
    """The user's model (its ``mujoco.MjSpec``: defaults, classes, actuators, keyframes, meshes kept;
    includes written inline) with the joint drive terms, the links' inertials and a payload body
    changed, written by MuJoCo."""
    from urident.sim.mjcf import FRICTION_PIECES, friction_softness
    from urident.sim.mujoco_model import body_poses, spec_to_xml

    model = sim.handle
    changes = fold_payload(changes, spec)
    edit = sim.mjspec.copy()
    rot, pos = _robot_frames(sim, spec)
    b = body_poses(model, sim.joint_ids, np.zeros(6))
    drive = sim.drive()
    for i, name in enumerate(sim.joint_names):
        joint = edit.joint(name)
        if joint is None:
            raise ConfigError(f"{sim.path}: <joint name={name!r}> not found to correct")
        dof = int(sim.dof_adr[i])
        joint.armature = max(model.dof_armature[dof] + changes["armature"][i], 0.0)
        joint.damping = max(model.dof_damping[dof] + changes["damping"][i], 0.0)
        if changes["frictionloss"][i] != 0:
            fc = max(drive["frictionloss"][i] + changes["frictionloss"][i], 0.0)
            w = float(model.dof_invweight0[dof])
            (s1, k1), (s2, k2) = FRICTION_PIECES
            ref, imp = friction_softness(fc * s1, w, sim.friction_eps / k1)
            joint.frictionloss = fc * s1
            joint.solref_friction, joint.solimp_friction = _numbers(ref), _numbers(imp)
            old = edit.tendon(f"{name}_friction")
            if old is not None:
                edit.delete(old)
            ref, imp = friction_softness(fc * s2, w, sim.friction_eps / k2)
            tendon = edit.add_tendon(name=f"{name}_friction", frictionloss=fc * s2,
                                     solref_friction=_numbers(ref), solimp_friction=_numbers(imp))
            tendon.wrap_joint(name, 1.0)
    bodies = None
    for i, new in _link_edits(sim, rot, pos, b, changes).items():
        if new is None:
            raise ConfigError(f"{sim.path}: the mass/CoM correction of link {i + 1} (joint "
                              f"{sim.joint_names[i]!r}) is not a real mass distribution (drop it: unrealisable_links)")
        if bodies is None:
            edit.compile()
            bodies = {body.id: body for body in edit.bodies}
        for k, (mass, ipos, i_body) in new.items():
            if k not in bodies:
                raise ConfigError(f"{sim.path}: body #{k} of link {i + 1} not found to correct")
            moments, iquat = _principal(i_body)
            body = bodies[k]
            body.explicitinertial = True
            body.mass, body.ipos, body.iquat, body.inertia = mass, ipos, iquat, moments
            body.fullinertia = np.full(6, np.nan)
    payload = changes.get("payload")
    if payload is not None and payload[0] > 0:
        last = edit.joint(sim.joint_names[-1]).parent
        k = int(model.jnt_bodyid[sim.joint_ids[-1]])
        xb, rb = b["xpos"][k], b["xmat"][k]
        old = edit.body("payload")
        if old is not None:
            edit.delete(old)
        last.add_body(name="payload", pos=rb.T @ (pos[6] - xb), quat=[1.0, 0, 0, 0], explicitinertial=True,
                      ipos=rb.T @ rot[5] @ payload[1], iquat=[1.0, 0, 0, 0],
                      mass=float(payload[0]), inertia=np.full(3, 1e-6 * payload[0]))
    lines = [line.replace("--", "- -") for line in notes]
    if edit.comment:
        lines.append(edit.comment.strip())
    edit.comment = " " + "\n     ".join(lines) + " " if lines else edit.comment
    if out is not None:
        _relocate_assets(edit, sim.path, out)
    _loadable_after_writing(edit)
    return spec_to_xml(edit)


def _urdf_text(sim, spec, changes: dict, notes) -> str:
    import pinocchio as pin

    from urident.ident.urdf import matrix_rpy, payload_link
    from urident.model.robot import rpy_to_matrix

    changes = fold_payload(changes, spec)
    tree = _parse(sim.path)
    root = tree.getroot()
    model, data = sim.handle
    pin.forwardKinematics(model, data, np.zeros(model.nq))
    rot, pos = _robot_frames(sim, spec)
    rot, pos = rot[None], pos[None]
    for i, name in enumerate(sim.joint_names):
        joint = root.find(f"joint[@name='{name}']")
        dyn = joint.find("dynamics")
        if dyn is None:
            dyn = ET.SubElement(joint, "dynamics")
        dyn.set("damping", f"{max(sim.damping[i] + changes['damping'][i], 0.0):.12g}")
        dyn.set("friction", f"{max(sim.friction[i] + changes['frictionloss'][i], 0.0):.12g}")
        dm, dh, di = changes["mass"][i], changes["first_moment"][i], _inertia(changes, i)
        if dm == 0 and not np.any(dh != 0) and not np.any(di != 0):
            continue
        child = joint.find("child").get("link")
        link = root.find(f"link[@name='{child}']")
        # K_i in the child link's frame (both move with joint i: a constant transform)
        frame = data.oMi[i + 1]
        r_k = frame.rotation.T @ rot[0, i]
        t_k = frame.rotation.T @ (pos[0, i] - frame.translation)
        m0, c0, ic0 = 0.0, np.zeros(3), np.zeros((3, 3))
        inertial = link.find("inertial")
        if inertial is not None:
            origin = inertial.find("origin")
            xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
            rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
            m0, c0 = float(inertial.find("mass").get("value")), np.array(xyz)
            e = inertial.find("inertia")
            g = {k: float(e.get(k, 0)) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
            ic = inertia_matrix([g["ixx"], g["iyy"], g["izz"], g["ixy"], g["ixz"], g["iyz"]], "ur")
            r = rpy_to_matrix(np.array(rpy))
            ic0 = r @ ic @ r.T
            link.remove(inertial)
        mass = m0 + dm
        if not mass > 0:
            raise ConfigError(f"{sim.path}: correcting link {child!r} leaves mass {mass:g} kg")
        about_k = ic0 + m0 * _shift(c0 - t_k) + r_k @ di @ r_k.T
        com = t_k + (m0 * (c0 - t_k) + r_k @ dh) / mass
        ic1 = about_k - mass * _shift(com - t_k)
        if np.linalg.eigvalsh(ic1).min() < 0:
            raise ConfigError(f"{sim.path}: the correction of link {child!r} is not a real mass distribution "
                              "(drop it: unrealisable_links)")
        new = ET.Element("inertial")
        ET.SubElement(new, "origin", xyz=_fmt(com), rpy="0 0 0")
        ET.SubElement(new, "mass", value=f"{mass:.12g}")
        ET.SubElement(new, "inertia", ixx=f"{ic1[0, 0]:.12g}", ixy=f"{ic1[0, 1]:.12g}", ixz=f"{ic1[0, 2]:.12g}",
                      iyy=f"{ic1[1, 1]:.12g}", iyz=f"{ic1[1, 2]:.12g}", izz=f"{ic1[2, 2]:.12g}")
        link.insert(0, new)
    payload = changes.get("payload")
    if payload is not None and payload[0] > 0:
        last = root.find(f"joint[@name='{sim.joint_names[-1]}']").find("child").get("link")
        frame = data.oMi[len(sim.joint_names)]
        xyz = frame.rotation.T @ (pos[0, 6] - frame.translation)
        rpy = matrix_rpy(frame.rotation.T @ rot[0, 6])
        for old in [e for e in root if e.get("name") in ("payload", "payload_fixed")]:
            root.remove(old)
        from urident.model.payload import Payload

        com = np.asarray(spec.tool_rotation, float).T @ payload[1]      # K_6 axes → the tool frame's
        point = Payload(spec.name, payload[0], com, np.eye(3) * 1e-6 * payload[0])
        text = "<r>" + "".join(payload_link(point, parent=last, indent="")) + "</r>"
        for e in ET.fromstring(text):
            if e.tag == "joint":
                e.find("origin").set("xyz", _fmt(xyz))
                e.find("origin").set("rpy", _fmt(rpy))
            root.append(e)
    for line in reversed(list(notes)):
        root.insert(0, ET.Comment(" " + line.replace("--", "- -") + " "))
    ET.indent(tree)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def unrealisable_links(sim, spec, changes: dict) -> list[int]:
    """0-based links whose mass/CoM correction, with the inertia about the joint frame kept (as
    the correction's columns assume), leaves no real mass distribution (inertia about the new CoM
    not positive semi-definite): such a correction cannot be written."""
    if sim.fmt != "mjcf":
        return _unrealisable_urdf(sim, spec, changes)
    from urident.sim.mujoco_model import body_poses

    bp = body_poses(sim.handle, sim.joint_ids, np.zeros(6))
    rot, pos = _robot_frames(sim, spec)
    return sorted(i for i, new in _link_edits(sim, rot, pos, bp, fold_payload(changes, spec)).items() if new is None)


def _unrealisable_urdf(sim, spec, changes: dict) -> list[int]:
    changes = fold_payload(changes, spec)
    out = []
    for i in range(len(sim.joint_names)):
        one = {k: np.zeros_like(np.asarray(changes[k], float)) for k in ("armature", "damping", "frictionloss",
                                                                         "mass", "first_moment")}
        one["inertia"] = np.zeros((6, 3, 3))
        one["payload"] = None
        one["mass"][i], one["first_moment"][i], one["inertia"][i] = (changes["mass"][i], changes["first_moment"][i],
                                                                     _inertia(changes, i))
        if one["mass"][i] == 0 and not np.any(one["first_moment"][i] != 0) and not np.any(one["inertia"][i] != 0):
            continue
        try:
            _urdf_text(sim, spec, one, ())
        except ConfigError:
            out.append(i)
    return out


def write_corrected(sim, spec, changes: dict, path: str | Path, *, notes=(), overwrite: bool = False) -> Path:
    """Write ``sim`` with ``changes`` (:func:`urident.gap.sim_baseline.corrections`) to ``path``."""
    from urident.fileio import write_text_atomic

    path = Path(path)
    text = _mjcf_text(sim, spec, changes, notes, path) if sim.fmt == "mjcf" else _urdf_text(sim, spec, changes, notes)
    write_text_atomic(path, text, fsync=False, overwrite=overwrite)
    return path
