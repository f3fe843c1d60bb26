"""MJCF (MuJoCo) export of a physically consistent 78-vector, written as plain XML.

Body i is the paper's joint frame K_i (``pos``/``quat``: the robot file's fixed placement of K_i in
K_{i−1}); its hinge joint sits at the body origin. Link inertials come from the ten parameters (centre
of mass ρ = h/m, ``fullinertia`` about it), the reflected rotor inertia i_G²·C_M is the joint's
``armature``, viscous friction its ``damping`` and Coulomb friction its ``frictionloss``; limits are the
robot file's. MuJoCo's frictionloss is a soft constraint whose force in the friction zone is
−D·(q̈ + b·q̇), clipped to ± frictionloss, with D = d/((1 − d)·w), w the joint's inverse inertia at
qpos0 (MuJoCo's ``dof_invweight0``) and d, b from ``solimpfriction`` / ``solreffriction``:
:func:`friction_softness` picks them so that the slope at q̇ = 0 is tanh(q̇/ε)'s, f_c/ε, and the
acceleration term is negligible (d = 1e-3). One clipped line is 0.11·f_c from tanh at worst (near
|q̇| ≈ ε, i.e. at every velocity reversal and at rest); so the Coulomb friction is split in two
pieces with different slopes, the joint's ``frictionloss`` and a fixed tendon's on the same joint
(``<joint>_friction``, their sum is f_c), which follow tanh to 0.035·f_c (:data:`FRICTION_PIECES`).
Collision geometry: the robot file's capsules. A motor actuator per joint takes
torques (ctrlrange ± the joint's torque limit); a site ``tool0`` marks the flange.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from urident.model.parameters import COULOMB, ROTOR, VISCOUS, body_slice

#: frictionloss impedance: D = d/((1 − d)·w) stays ~1e-3/w, so D·q̈ is negligible
FRICTION_IMPEDANCE = 1e-3
#: (share of f_c, slope at 0 in units of 1/ε) of the joint's and the tendon's frictionloss: the
#: minimax fit of w1·clip(k1·x) + w2·clip(k2·x) to tanh(x) (max error 0.035)
FRICTION_PIECES = ((0.5075, 1.229), (0.4925, 0.4982))
AXES = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}


def _fmt(values) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.atleast_1d(values))


def quaternion(rotation: np.ndarray) -> np.ndarray:
    """MuJoCo's (w, x, y, z) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_quat()
    return np.array([w, x, y, z])


def inverse_weights(spec, standard: np.ndarray) -> np.ndarray:
    """(6,) diagonal of M(q = 0)⁻¹ with the rotor inertias (MuJoCo's ``dof_invweight0`` of a chain of
    hinges), from the regressor: column k of M is τ(0, 0, e_k) − τ(0, 0, 0)."""
    from urident.model import regressor_blocks

    n = len(spec.joints)
    qdd = np.vstack([np.zeros(n), np.eye(n)])
    tau = regressor_blocks(spec, np.zeros((n + 1, n)), np.zeros((n + 1, n)), qdd) @ standard
    mass = (tau[1:] - tau[0]).T
    return np.diag(np.linalg.inv((mass + mass.T) / 2))


def friction_softness(coulomb: float, inverse_weight: float, friction_eps: float) -> tuple[str, str]:
    """(solreffriction, solimpfriction) making a frictionloss ``coulomb`` give the force
    −f_c·clip(q̇/ε, −1, 1) at q̈ = 0: slope D·b = f_c/ε with D = d/((1 − d)·w) and b = B/d
    (direct solref "−k −B")."""
    d = FRICTION_IMPEDANCE
    b = coulomb * (1 - d) * inverse_weight / friction_eps   # MuJoCo's b = B/dmax: D·b = f_c/ε
    return f"-1 {-b:.12g}", f"{d:g} {d:g} 0.001 0.5 2"


#: MuJoCo refuses an inertia with a zero principal moment, which a physically consistent estimate
#: on the boundary of its constraint can have: principal moments are raised to at least this [kg m²]
MIN_PRINCIPAL_INERTIA = 1e-9


def mujoco_inertia(inertia: np.ndarray) -> tuple[np.ndarray, bool]:
    """(inertia about the CoM MuJoCo accepts, whether it was changed): principal moments raised to
    :data:`MIN_PRINCIPAL_INERTIA` and to the triangle inequality a + b ≥ c."""
    eig, vec = np.linalg.eigh((inertia + inertia.T) / 2)
    fixed = np.maximum(eig, MIN_PRINCIPAL_INERTIA)
    for k in range(3):
        others = [fixed[i] for i in range(3) if i != k]
        short = fixed[k] - sum(others)
        if short > 0:
            fixed[[i for i in range(3) if i != k]] += short / 2 + MIN_PRINCIPAL_INERTIA
    changed = bool(np.any(fixed != eig))
    return (vec * fixed) @ vec.T if changed else inertia, changed


def _comment(text: str) -> str:
    return "<!-- " + text.replace("--", "- -") + " -->"


def _capsules(capsules, indent: str, group: str) -> list[str]:
    return [f'{indent}<geom class="{group}" type="capsule" fromto="{_fmt(np.r_[c.a, c.b])}" '
            f'size="{c.radius:.12g}"/>' for c in capsules]


def to_mjcf(spec, standard: np.ndarray, name: str | None = None, notes=(),
            friction_eps: float = 0.01, payload=None) -> str:
    """MJCF text of ``spec``'s kinematics with the 78-vector ``standard``; ``notes``: lines of the
    header comment (e.g. the identified terms MJCF cannot express); ``friction_eps``: the tanh slope
    [rad/s] the frictionloss imitates; ``payload``: a :class:`urident.model.payload.Payload`, written
    as a body ``payload`` on the flange (frame ``tool0``)."""
    from urident.ident.urdf import check_exportable, link_inertial

    p = check_exportable(standard, "MJCF")
    loaded = p.copy()
    if payload is not None:     # MuJoCo's dof_invweight0 (the friction softness) includes the payload
        loaded[body_slice(len(spec.joints) - 1)] += payload.body_params(spec)
    weights = inverse_weights(spec, loaded)
    name = name or f"{spec.name}_identified"
    out = ['<?xml version="1.0"?>', f"<mujoco model={quoteattr(name)}>"]
    out += ["  " + _comment(line) for line in notes]
    inertials = []
    for i, joint in enumerate(spec.joints):
        m, com, ic = link_inertial(p[body_slice(i)])
        ic, changed = mujoco_inertia(ic)
        inertials.append((m, com, ic))
        if changed:
            out.append("  " + _comment(f"{joint.name}_link: principal moments raised to >= "
                                       f"{MIN_PRINCIPAL_INERTIA:g} kg m^2 (MuJoCo refuses a zero one)"))
    out += ['  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
            f'  <option gravity="{_fmt(spec.gravity)}"/>',
            "  <default>",
            '    <default class="collision"><geom contype="1" conaffinity="1" group="3" rgba="0.6 0.6 0.7 1"/></default>',
            "  </default>",
            "  <worldbody>"]
    out += _capsules(spec.base_collision, "    ", "collision")
    indent = "    "
    for i, joint in enumerate(spec.joints):
        m, com, ic = inertials[i]
        fc = p[COULOMB][i] * FRICTION_PIECES[0][0]
        soft = ""
        if fc > 0:
            ref, imp = friction_softness(fc, weights[i], friction_eps / FRICTION_PIECES[0][1])
            soft = f' solreffriction="{ref}" solimpfriction="{imp}"'
        out += [f'{indent}<body name={quoteattr(joint.name + "_link")} pos="{_fmt(joint.xyz)}" '
                f'quat="{_fmt(quaternion(joint.rotation))}">',
                f'{indent}  <inertial pos="{_fmt(com)}" mass="{m:.12g}" fullinertia="'
                f'{_fmt([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]])}"/>',
                f'{indent}  <joint name={quoteattr(joint.name)} type="hinge" axis="{AXES[joint.axis]}" '
                f'range="{joint.q_min:.12g} {joint.q_max:.12g}" armature="{p[ROTOR][i]:.12g}" '
                f'damping="{p[VISCOUS][i]:.12g}" frictionloss="{fc:.12g}"{soft}/>']
        out += _capsules(joint.collision, indent + "  ", "collision")
        indent += "  "
    out.append(f'{indent}<site name="tool0" pos="{_fmt(spec.tool_xyz)}" '
               f'quat="{_fmt(quaternion(spec.tool_rotation))}"/>')
    if payload is not None:
        ic, _ = mujoco_inertia(payload.inertia_kg_m2)
        out += [f'{indent}<body name="payload" pos="{_fmt(spec.tool_xyz)}" '
                f'quat="{_fmt(quaternion(spec.tool_rotation))}">',
                f'{indent}  <inertial pos="{_fmt(payload.com_m)}" mass="{payload.mass_kg:.12g}" fullinertia="'
                f'{_fmt([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]])}"/>',
                f"{indent}</body>"]
    for i in reversed(range(len(spec.joints))):
        indent = indent[:-2]
        out.append(f"{indent}</body>")
    out.append("  </worldbody>")
    excludes = []
    link = {j.name: j.name + "_link" for j in spec.joints}
    link["base"] = "world"
    for pair in spec.allowed_contacts:
        a, b = sorted(pair)
        if a in link and b in link:
            excludes.append(f'    <exclude body1={quoteattr(link[a])} body2={quoteattr(link[b])}/>')
    if excludes:
        out += ["  <contact>"] + excludes + ["  </contact>"]
    tendons = []
    share, slope = FRICTION_PIECES[1]
    for i, joint in enumerate(spec.joints):
        fc = p[COULOMB][i] * share
        if fc > 0:
            ref, imp = friction_softness(fc, weights[i], friction_eps / slope)
            tendons += [f'    <fixed name={quoteattr(joint.name + "_friction")} frictionloss="{fc:.12g}" '
                        f'solreffriction="{ref}" solimpfriction="{imp}">',
                        f'      <joint joint={quoteattr(joint.name)} coef="1"/>', "    </fixed>"]
    if tendons:
        out += ["  <tendon>"] + tendons + ["  </tendon>"]
    out.append("  <actuator>")
    for joint in spec.joints:
        out.append(f'    <motor name={quoteattr(joint.name)} joint={quoteattr(joint.name)} gear="1" '
                   f'ctrlrange="{-joint.tau_max:.12g} {joint.tau_max:.12g}"/>')
    out += ["  </actuator>", "</mujoco>", ""]
    return "\n".join(out)


def write_mjcf(spec, standard: np.ndarray, path: str | Path, name: str | None = None, notes=(),
               overwrite: bool = True, friction_eps: float = 0.01, payload=None) -> Path:
    """Write the MJCF atomically, never through a symbolic link (``overwrite=False``: must be new)."""
    from urident.fileio import write_text_atomic

    path = Path(path)
    write_text_atomic(path, to_mjcf(spec, standard, name, notes, friction_eps, payload), fsync=False,
                      overwrite=overwrite)
    return path


def downloaded_like_standard(spec) -> np.ndarray:
    """The 78-vector of a model as people download it: the robot file's nominal masses and centres
    of mass, solid-cylinder inertias from each link's first capsule, no armature, damping or
    friction."""
    from urident.model.parameters import body_params, standard_vector

    bodies = []
    for joint in spec.joints:
        c = joint.collision[0]
        axis = np.asarray(c.b, float) - np.asarray(c.a, float)
        length = max(float(np.linalg.norm(axis)), 2 * c.radius)
        z = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 0 else np.array([0, 0, 1.0])
        m, r = joint.mass, c.radius
        side, along = m * (3 * r * r + length * length) / 12, m * r * r / 2
        inertia = side * np.eye(3) + (along - side) * np.outer(z, z)
        bodies.append(body_params(m, joint.com, inertia))
    zeros = np.zeros(len(spec.joints))
    return standard_vector(bodies, zeros, zeros, zeros)
