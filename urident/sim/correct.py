"""Write a user's simulator model with the corrections the gap found (``urident gap --write-sim``).

The file is edited, not regenerated: everything else in it stays. Per joint: armature, damping
and Coulomb friction become the model's value plus the correction (MJCF: ``frictionloss`` in the
two pieces of :mod:`urident.sim.mjcf`, joint and fixed tendon ``<joint>_friction``, so MuJoCo's
force follows tanh(q̇/ε); URDF: ``<dynamics damping friction>``). A link's mass and first-moment
correction (about the robot's joint frame K_i, turned into the body's frame) moves its inertial's
mass and centre of mass and keeps its inertia about K_i's origin, as the correction's columns do; a link
inertia correction (about K_i's origin, K_i's axes) is added to that inertia. A payload is a
point mass body ``payload`` at the tool point (MJCF), a fixed link ``payload`` there (URDF). URDF has
no armature (the caller lists it as not expressible). A world base frame is assumed to be the robot's
(the model loader checked the chain against the robot file).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from urident.errors import ConfigError


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


def _mjcf_text(sim, spec, changes: dict, notes) -> str:
    from urident.model.kinematics import frame_poses
    from urident.sim.mjcf import FRICTION_PIECES, friction_softness, mujoco_inertia, quaternion
    from urident.sim.mujoco_model import import_mujoco

    mj = import_mujoco()
    model = sim.handle
    tree = _parse(sim.path)
    root = tree.getroot()
    parents = {child: parent for parent in root.iter() for child in parent}
    data = mj.MjData(model)
    data.qpos[:] = 0
    mj.mj_kinematics(model, data)
    rot, pos = frame_poses(spec, np.zeros((1, 6)))
    tendons = root.find("tendon")
    for i, name in enumerate(sim.joint_names):
        joint = root.find(f".//joint[@name='{name}']")
        if joint is None:
            raise ConfigError(f"{sim.path}: <joint name={name!r}> not found to correct")
        dof = model.jnt_dofadr[i]
        joint.set("armature", f"{max(model.dof_armature[dof] + changes['armature'][i], 0.0):.12g}")
        joint.set("damping", f"{max(model.dof_damping[dof] + changes['damping'][i], 0.0):.12g}")
        if changes["frictionloss"][i] != 0:
            old = model.dof_frictionloss[dof]
            for t in range(model.ntendon):
                if mj.mj_id2name(model, mj.mjtObj.mjOBJ_TENDON, t) == f"{name}_friction":
                    old += model.tendon_frictionloss[t]
            fc = max(old + changes["frictionloss"][i], 0.0)
            w = float(model.dof_invweight0[dof])
            (s1, k1), (s2, k2) = FRICTION_PIECES
            ref, imp = friction_softness(fc * s1, w, sim.friction_eps / k1)
            joint.set("frictionloss", f"{fc * s1:.12g}")
            joint.set("solreffriction", ref)
            joint.set("solimpfriction", imp)
            if tendons is None:
                tendons = ET.SubElement(root, "tendon")
            for old_t in tendons.findall(f"fixed[@name='{name}_friction']"):
                tendons.remove(old_t)
            ref, imp = friction_softness(fc * s2, w, sim.friction_eps / k2)
            fixed = ET.SubElement(tendons, "fixed", name=f"{name}_friction", frictionloss=f"{fc * s2:.12g}",
                                  solreffriction=ref, solimpfriction=imp)
            ET.SubElement(fixed, "joint", joint=name, coef="1")
        dm, dh, di = changes["mass"][i], changes["first_moment"][i], _inertia(changes, i)
        if dm != 0 or np.any(dh != 0) or np.any(di != 0):
            b = int(model.jnt_bodyid[i])
            body = parents[joint]
            m = float(model.body_mass[b])
            xb, rb = np.array(data.xpos[b]), np.array(data.xmat[b]).reshape(3, 3)
            com = np.array(data.xipos[b])
            first = m * (com - pos[0, i]) + rot[0, i] @ dh      # about K_i's origin, world axes
            mass = m + dm
            if not mass > 0:
                raise ConfigError(f"{sim.path}: correcting body {body.get('name')!r} leaves mass {mass:g} kg")
            new_com = pos[0, i] + first / mass
            ipos = rb.T @ (new_com - xb)
            # the correction keeps the inertia about K_i's origin (its columns are m and m·ρ only)
            ri = np.array(data.ximat[b]).reshape(3, 3)
            i_com = ri @ np.diag(model.body_inertia[b]) @ ri.T
            about_k = i_com + m * _shift(com - pos[0, i]) + rot[0, i] @ di @ rot[0, i].T
            i_new = about_k - mass * _shift(new_com - pos[0, i])
            if np.linalg.eigvalsh(i_new).min() < 0:
                raise ConfigError(f"{sim.path}: the mass/CoM correction of body {body.get('name')!r} is not a "
                                  "real mass distribution (drop it: unrealisable_links)")
            i_new, _ = mujoco_inertia(i_new)
            i_body = rb.T @ i_new @ rb
            for old_i in body.findall("inertial"):
                body.remove(old_i)
            inertial = ET.Element("inertial", pos=_fmt(ipos), mass=f"{mass:.12g}", fullinertia=_fmt(
                [i_body[0, 0], i_body[1, 1], i_body[2, 2], i_body[0, 1], i_body[0, 2], i_body[1, 2]]))
            body.insert(0, inertial)
    payload = changes.get("payload")
    if payload is not None and payload[0] > 0:
        last = parents[root.find(f".//joint[@name='{sim.joint_names[-1]}']")]
        b = int(model.jnt_bodyid[len(sim.joint_names) - 1])
        xb, rb = np.array(data.xpos[b]), np.array(data.xmat[b]).reshape(3, 3)
        tool = rb.T @ (pos[0, 6] - xb)
        body = ET.SubElement(last, "body", name="payload", pos=_fmt(tool), quat=_fmt(quaternion(np.eye(3))))
        ET.SubElement(body, "inertial", pos="0 0 0", mass=f"{payload[0]:.12g}",
                      diaginertia=_fmt(np.full(3, 1e-6 * payload[0])))
    for line in reversed(list(notes)):
        root.insert(0, ET.Comment(" " + line.replace("--", "- -") + " "))
    ET.indent(tree)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _urdf_text(sim, spec, changes: dict, notes) -> str:
    import pinocchio as pin

    from urident.ident.urdf import matrix_rpy, payload_link
    from urident.model.kinematics import frame_poses
    from urident.model.robot import rpy_to_matrix

    tree = _parse(sim.path)
    root = tree.getroot()
    model, data = sim.handle
    pin.forwardKinematics(model, data, np.zeros(model.nq))
    rot, pos = frame_poses(spec, np.zeros((1, 6)))
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
            ic = np.array([[g["ixx"], g["ixy"], g["ixz"]], [g["ixy"], g["iyy"], g["iyz"]],
                           [g["ixz"], g["iyz"], g["izz"]]])
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
        from urident.ident.payload import Payload

        point = Payload(spec.name, payload[0], np.zeros(3), np.eye(3) * 1e-6 * payload[0])
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
    from urident.model.kinematics import frame_poses

    if sim.fmt != "mjcf":
        return _unrealisable_urdf(sim, spec, changes)
    from urident.sim.mujoco_model import import_mujoco

    mj = import_mujoco()
    model = sim.handle
    data = mj.MjData(model)
    mj.mj_kinematics(model, data)
    _, pos = frame_poses(spec, np.zeros((1, 6)))
    rot, _ = frame_poses(spec, np.zeros((1, 6)))
    out = []
    for i in range(len(sim.joint_names)):
        dm, dh, di = changes["mass"][i], changes["first_moment"][i], _inertia(changes, i)
        if dm == 0 and not np.any(dh != 0) and not np.any(di != 0):
            continue
        b = int(model.jnt_bodyid[i])
        m = float(model.body_mass[b])
        com = np.array(data.xipos[b])
        ri = np.array(data.ximat[b]).reshape(3, 3)
        about_k = (ri @ np.diag(model.body_inertia[b]) @ ri.T + m * _shift(com - pos[0, i])
                   + rot[0, i] @ di @ rot[0, i].T)
        mass = m + dm
        if not mass > 0:
            out.append(i)
            continue
        new_com = pos[0, i] + (m * (com - pos[0, i]) + rot[0, i] @ dh) / mass
        if np.linalg.eigvalsh(about_k - mass * _shift(new_com - pos[0, i])).min() < 0:
            out.append(i)
    return out


def _unrealisable_urdf(sim, spec, changes: dict) -> list[int]:
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

    text = _mjcf_text(sim, spec, changes, notes) if sim.fmt == "mjcf" else _urdf_text(sim, spec, changes, notes)
    path = Path(path)
    write_text_atomic(path, text, fsync=False, overwrite=overwrite)
    return path
