"""MJCF (MuJoCo) export of a physically consistent 78-vector, built as a ``mujoco.MjSpec`` and
written by MuJoCo's own writer (:func:`urident.sim.mujoco_model.arm_xml`; this module describes the
model in plain values, so that only ``mujoco_model`` imports MuJoCo).

Body i is the paper's joint frame K_i (``pos``/``quat``: the robot file's fixed placement of K_i in
K_{i−1}); its hinge joint sits at the body origin. Link inertials come from the ten parameters (centre
of mass ρ = h/m, ``fullinertia`` about it, which MuJoCo writes as ``diaginertia`` + ``quat``), the
reflected rotor inertia i_G²·C_M is the joint's ``armature``, viscous friction its ``damping`` and
Coulomb friction its ``frictionloss``; limits are the robot file's. MuJoCo's frictionloss is a soft
constraint whose force in the friction zone is
−D·(q̈ + b·q̇), clipped to ± frictionloss, with D = d/((1 − d)·w), w the joint's inverse inertia at
qpos0 (MuJoCo's ``dof_invweight0``) and d, b from ``solimpfriction`` / ``solreffriction``:
:func:`friction_softness` picks them so that the slope at q̇ = 0 is tanh(q̇/ε)'s, f_c/ε, and the
acceleration term is negligible (d = 1e-3). One clipped line is 0.11·f_c from tanh at worst (near
|q̇| ≈ ε, i.e. at every velocity reversal and at rest); so the Coulomb friction is split in two
pieces with different slopes, the joint's ``frictionloss`` and a fixed tendon's on the same joint
(``<joint>_friction``, their sum is f_c), which follow tanh to 0.035·f_c (:data:`FRICTION_PIECES`).
Collision geometry: the robot file's capsules (class ``collision``; MuJoCo writes a ``fromto`` as
``pos``/``quat``/``size``). A motor actuator per joint takes torques (gear 1, ctrlrange ± the joint's
torque limit; MuJoCo writes it in its general form); a site ``tool0`` marks the flange. Numbers are
written with 17 significant digits (MuJoCo's writer, :func:`urident.sim.mujoco_model.arm_xml`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from urident.model.parameters import COULOMB, ROTOR, VISCOUS, body_slice

#: frictionloss impedance: D = d/((1 − d)·w) stays ~1e-3/w, so D·q̈ is negligible
FRICTION_IMPEDANCE = 1e-3
#: (share of f_c, slope at 0 in units of 1/ε) of the joint's and the tendon's frictionloss: the
#: minimax fit of w1·clip(k1·x) + w2·clip(k2·x) to tanh(x) (max error 0.035)
FRICTION_PIECES = ((0.5075, 1.229), (0.4925, 0.4982))
AXES = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}


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


@dataclass(frozen=True)
class MjcfHinge:
    """A hinge joint at its body's origin: ``axis`` (3,), ``range`` (2,) [rad], ``armature`` [kg·m²],
    ``damping`` [N·m·s/rad], ``frictionloss`` [N·m] with its ``solref``/``solimp`` (None: MuJoCo's)."""

    name: str
    axis: tuple[float, float, float]
    range: tuple[float, float]
    armature: float
    damping: float
    frictionloss: float
    solref: tuple[float, ...] | None = None
    solimp: tuple[float, ...] | None = None


@dataclass(frozen=True)
class MjcfBody:
    """A body at ``pos``/``quat`` (w, x, y, z) in its parent, its inertial (``mass`` [kg], centre of
    mass ``com`` [m] in the body, ``fullinertia`` (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) about it [kg·m²]),
    an optional hinge and capsules ((fromto (6,), radius), class ``collision``)."""

    name: str
    pos: tuple[float, ...]
    quat: tuple[float, ...]
    mass: float
    com: tuple[float, ...]
    fullinertia: tuple[float, ...]
    joint: MjcfHinge | None = None
    capsules: tuple[tuple[tuple[float, ...], float], ...] = ()


@dataclass(frozen=True)
class MjcfFrictionTendon:
    """A fixed tendon on one joint (coefficient 1) carrying a share of its Coulomb friction."""

    name: str
    joint: str
    frictionloss: float
    solref: tuple[float, ...]
    solimp: tuple[float, ...]


@dataclass(frozen=True)
class MjcfArm:
    """Everything :func:`urident.sim.mujoco_model.arm_xml` builds: ``links`` is a chain (each body
    the child of the one before), ``tool`` (pos, quat) the site ``tool0`` in the last link, ``payload``
    a body there, ``excludes`` body-name pairs whose contacts are off, a motor per joint."""

    name: str
    comment: tuple[str, ...]
    gravity: tuple[float, float, float]
    base_capsules: tuple[tuple[tuple[float, ...], float], ...]
    links: tuple[MjcfBody, ...]
    tool: tuple[tuple[float, ...], tuple[float, ...]]
    payload: MjcfBody | None
    excludes: tuple[tuple[str, str], ...]
    tendons: tuple[MjcfFrictionTendon, ...]
    motors: tuple[tuple[str, float], ...]          # (joint, torque limit [N·m])


def _vec(values) -> tuple[float, ...]:
    return tuple(float(v) for v in np.atleast_1d(values))


def _numbers(text: str) -> tuple[float, ...]:
    return tuple(float(v) for v in text.split())


def _capsules(capsules) -> tuple:
    return tuple((_vec(np.r_[c.a, c.b]), float(c.radius)) for c in capsules)


def _full(ic: np.ndarray) -> tuple[float, ...]:
    return _vec([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]])


def mjcf_arm(spec, standard: np.ndarray, name: str | None = None, notes=(),
             friction_eps: float = 0.01, payload=None) -> MjcfArm:
    """The MJCF model of ``spec``'s kinematics with the 78-vector ``standard``; ``notes``: lines of
    the top comment (e.g. the identified terms MJCF cannot express); ``friction_eps``: the tanh
    slope [rad/s] the frictionloss imitates; ``payload``: a :class:`urident.model.payload.Payload`,
    a body ``payload`` on the flange (frame ``tool0``)."""
    from urident.ident.urdf import check_exportable, link_inertial

    p = check_exportable(standard, "MJCF")
    loaded = p.copy()
    if payload is not None:     # MuJoCo's dof_invweight0 (the friction softness) includes the payload
        loaded[body_slice(len(spec.joints) - 1)] += payload.body_params(spec)
    weights = inverse_weights(spec, loaded)
    comment = [line.replace("--", "- -") for line in notes]
    links = []
    for i, joint in enumerate(spec.joints):
        m, com, ic = link_inertial(p[body_slice(i)])
        ic, changed = mujoco_inertia(ic)
        if changed:
            comment.append(f"{joint.name}_link: principal moments raised to >= {MIN_PRINCIPAL_INERTIA:g} "
                           "kg m^2 (MuJoCo refuses a zero one)")
        fc = p[COULOMB][i] * FRICTION_PIECES[0][0]
        ref = imp = None
        if fc > 0:
            ref, imp = (_numbers(t) for t in friction_softness(fc, weights[i], friction_eps / FRICTION_PIECES[0][1]))
        hinge = MjcfHinge(joint.name, _vec(AXES[joint.axis].split()), (float(joint.q_min), float(joint.q_max)),
                          float(p[ROTOR][i]), float(p[VISCOUS][i]), float(fc), ref, imp)
        links.append(MjcfBody(joint.name + "_link", _vec(joint.xyz), _vec(quaternion(joint.rotation)), m,
                              _vec(com), _full(ic), hinge, _capsules(joint.collision)))
    tool = (_vec(spec.tool_xyz), _vec(quaternion(spec.tool_rotation)))
    body = None
    if payload is not None:
        ic, _ = mujoco_inertia(payload.inertia_kg_m2)
        body = MjcfBody("payload", *tool, float(payload.mass_kg), _vec(payload.com_m), _full(ic))
    link = {j.name: j.name + "_link" for j in spec.joints}
    link["base"] = "world"
    excludes = tuple((link[a], link[b]) for a, b in (sorted(pair) for pair in spec.allowed_contacts)
                     if a in link and b in link)
    tendons = []
    share, slope = FRICTION_PIECES[1]
    for i, joint in enumerate(spec.joints):
        fc = p[COULOMB][i] * share
        if fc > 0:
            ref, imp = friction_softness(fc, weights[i], friction_eps / slope)
            tendons.append(MjcfFrictionTendon(joint.name + "_friction", joint.name, float(fc), _numbers(ref),
                                              _numbers(imp)))
    return MjcfArm(name or f"{spec.name}_identified", tuple(comment), _vec(spec.gravity),
                   _capsules(spec.base_collision), tuple(links), tool, body, excludes, tuple(tendons),
                   tuple((j.name, float(j.tau_max)) for j in spec.joints))


def to_mjcf(spec, standard: np.ndarray, name: str | None = None, notes=(),
            friction_eps: float = 0.01, payload=None) -> str:
    """MJCF text of :func:`mjcf_arm` (its arguments), written by MuJoCo."""
    from urident.sim.mujoco_model import arm_xml

    return arm_xml(mjcf_arm(spec, standard, name, notes, friction_eps, payload))


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
