"""The paper's parameter vector (eq. 39-40), its layout, and conversions to and from link inertial data.

This module is the one place that knows the layout; everything else uses its names:

* for body i = 1..6 the ten values ``(m, mρx, mρy, mρz, A, B, C, D, E, F)`` about the joint frame
  K_i (:func:`body_slice`), with the inertia tensor J = [[A, -F, -E], [-F, B, -D], [-E, -D, C]];
  all sixty together: :data:`RIGID_BODY`;
* the reflected rotor inertias ``i_G,i^2 C_M,i`` (:data:`ROTOR`, 6);
* viscous ``r_v`` (:data:`VISCOUS`, 6) and Coulomb ``r_c`` (:data:`COULOMB`, 6) friction
  coefficients (both: :data:`FRICTION`).

Every column of an identification model has a *kind*: the kind of its standard parameter
(:func:`parameter_kinds`: ``rigid_body``, ``rotor_inertia``, ``viscous``, ``coulomb``; a base
parameter has the kind of the standard parameter it is named after) or, for the extra friction
columns of :mod:`urident.ident.design`, the extra feature's kind (:data:`EXTRA_COLUMNS`).
"""

from __future__ import annotations

import numpy as np

N_JOINTS = 6
BODY_FIELDS = ("m", "mrx", "mry", "mrz", "A", "B", "C", "D", "E", "F")
PARAMS_PER_BODY = len(BODY_FIELDS)
ROTOR_OFFSET = PARAMS_PER_BODY * N_JOINTS
VISCOUS_OFFSET = ROTOR_OFFSET + N_JOINTS
COULOMB_OFFSET = VISCOUS_OFFSET + N_JOINTS
N_PARAMS = COULOMB_OFFSET + N_JOINTS

RIGID_BODY = slice(0, ROTOR_OFFSET)
ROTOR = slice(ROTOR_OFFSET, VISCOUS_OFFSET)
VISCOUS = slice(VISCOUS_OFFSET, COULOMB_OFFSET)
COULOMB = slice(COULOMB_OFFSET, N_PARAMS)
FRICTION = slice(VISCOUS_OFFSET, N_PARAMS)
#: Rotor inertias and friction: the drive's parameters, all >= 0 physically.
DRIVE = slice(ROTOR_OFFSET, N_PARAMS)

# Column kinds.
RIGID_BODY_KIND = "rigid_body"
ROTOR_KIND = "rotor_inertia"
VISCOUS_KIND = "viscous"
COULOMB_KIND = "coulomb"

#: The extra friction columns of the identification model (one per joint): feature name →
#: (name prefix of its columns, e.g. ``fs3``; kind of its columns).
EXTRA_COLUMNS = {
    "offset": ("fo", "offset"),
    "stribeck": ("fs", "stribeck"),
    "dahl": ("fh", "dahl"),
    "load": ("fcl", "load_friction"),
    "sqrtvisc": ("fvs", "sqrt_viscous"),
    "asym": ("fa", "coulomb_asymmetry"),
    "sigmoid": ("fg", "sigmoid"),
    "sigoffset": ("fgo", "sigmoid_offset"),
    "quadvisc": ("fvq", "quadratic_viscous"),
    "poscos": ("fpc", "position_friction"),
    "possin": ("fps", "position_friction"),
    "tempvisc": ("fvt", "temperature_viscous"),
    "tempcoul": ("fct", "temperature_coulomb"),
}
#: Kinds of the columns that are friction (or a constant offset): everything but the link-side
#: rigid body and the rotor inertia.
FRICTION_KINDS = frozenset({VISCOUS_KIND, COULOMB_KIND} | {kind for _, kind in EXTRA_COLUMNS.values()})


def body_slice(i: int) -> slice:
    """The ten parameters of body ``i`` (0-based) in the 78-vector."""
    if not 0 <= i < N_JOINTS:
        raise IndexError(f"body index {i} out of range 0-{N_JOINTS - 1}")
    return slice(PARAMS_PER_BODY * i, PARAMS_PER_BODY * (i + 1))


#: The last body: a payload's ten parameters add to these.
TOOL_BODY = body_slice(N_JOINTS - 1)


def parameter_names() -> list[str]:
    """Names of the 78 standard parameters: ``m2``, ``mrz3`` (m·ρz of body 3), ``C1``, ``IM4``
    (i_G² C_M of joint 4), ``fv5`` (viscous), ``fc6`` (Coulomb)."""
    names = [f"{f}{i}" for i in range(1, N_JOINTS + 1) for f in BODY_FIELDS]
    names += [f"IM{i}" for i in range(1, N_JOINTS + 1)]
    names += [f"fv{i}" for i in range(1, N_JOINTS + 1)]
    names += [f"fc{i}" for i in range(1, N_JOINTS + 1)]
    return names


def parameter_kinds() -> tuple[str, ...]:
    """Kind of each of the 78 standard parameters (module doc)."""
    return ((RIGID_BODY_KIND,) * (ROTOR_OFFSET) + (ROTOR_KIND,) * N_JOINTS
            + (VISCOUS_KIND,) * N_JOINTS + (COULOMB_KIND,) * N_JOINTS)


def parameter_joints() -> np.ndarray:
    """(78,) 0-based body or joint each standard parameter belongs to."""
    bodies = np.repeat(np.arange(N_JOINTS), PARAMS_PER_BODY)
    return np.concatenate([bodies] + [np.arange(N_JOINTS)] * 3)


def extra_column_names(feature: str) -> list[str]:
    """Names of the six columns of extra friction ``feature`` (:data:`EXTRA_COLUMNS`)."""
    prefix = EXTRA_COLUMNS[feature][0]
    return [f"{prefix}{j}" for j in range(1, N_JOINTS + 1)]


def joint_column_name(feature: str, joint: int, value: float | None = None) -> str:
    """Name of the column of a per-joint friction term: ``fg5`` (feature ``sigmoid``, 0-based
    ``joint`` 4), or ``fg5@0.05`` when the term carries its own parameter ``value``."""
    name = f"{EXTRA_COLUMNS[feature][0]}{joint + 1}"
    return name if value is None else f"{name}@{value:g}"


_MISSING = object()


def column_kind(name: str, default=_MISSING) -> str:
    """Kind of an identification-model column from its name: a standard parameter's name (a base
    parameter is named after one) or an extra column's name; any other name: ``default`` if given,
    else KeyError."""
    name = name.split("@", 1)[0]   # a per-joint term's own parameter (joint_column_name)
    if default is _MISSING:
        return _KIND_BY_NAME[name]
    return _KIND_BY_NAME.get(name, default)


def is_friction(kinds) -> np.ndarray:
    """Boolean mask of the friction columns (:data:`FRICTION_KINDS`) among ``kinds``."""
    return np.array([k in FRICTION_KINDS for k in kinds], dtype=bool)


#: Body entries that are >= 0 physically: the mass and the diagonal inertias about the joint frame.
NONNEGATIVE_BODY_FIELDS = ("m", "A", "B", "C")


def nonnegative_parameters() -> np.ndarray:
    """(78,) mask of the standard parameters that are >= 0 physically: masses, diagonal inertias
    about the joint frame (A, B, C), rotor inertias and friction coefficients."""
    mask = np.zeros(N_PARAMS, dtype=bool)
    for i in range(N_JOINTS):
        first = body_slice(i).start
        mask[[first + BODY_FIELDS.index(f) for f in NONNEGATIVE_BODY_FIELDS]] = True
    mask[DRIVE] = True
    return mask


def body_inertia_about_origin(mass: float, com: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """Inertia tensor about the frame origin (parallel-axis theorem)."""
    c = np.asarray(com, dtype=float)
    return inertia_com + mass * (c @ c * np.eye(3) - np.outer(c, c))


def body_params(mass: float, com: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """The ten paper parameters of one body."""
    j = body_inertia_about_origin(mass, com, inertia_com)
    h = mass * np.asarray(com, dtype=float)
    return np.array([mass, h[0], h[1], h[2], j[0, 0], j[1, 1], j[2, 2], -j[1, 2], -j[0, 2], -j[0, 1]])


#: The orders in which files and formulas write a symmetric 3×3 inertia as six numbers (entries
#: as (row, column)): ``ur`` [Ixx, Iyy, Izz, Ixy, Ixz, Iyz], robot files, payload files and
#: URScript's set_target_payload; ``flange`` [Jxx, Jyy, Jzz, Jyz, Jxz, Jxy], the payload's
#: flange-frame vector φ_F (ident.payload). The paper's (A, B, C, D, E, F) = (Jxx, Jyy, Jzz, −Jyz,
#: −Jxz, −Jxy) is :func:`inertia_tensor`.
INERTIA_ORDERS = {"ur": ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)),
                  "flange": ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))}


def inertia_matrix(v6, order: str = "ur") -> np.ndarray:
    """The symmetric 3×3 inertia from its six numbers in ``order`` (:data:`INERTIA_ORDERS`)."""
    j = np.zeros((3, 3))
    for value, (r, c) in zip(np.asarray(v6, dtype=float), INERTIA_ORDERS[order]):
        j[r, c] = j[c, r] = value
    return j


def inertia_vector(j, order: str = "ur") -> np.ndarray:
    """The six numbers of the 3×3 inertia ``j`` in ``order`` (:data:`INERTIA_ORDERS`)."""
    j = np.asarray(j, dtype=float)
    return np.array([j[r, c] for r, c in INERTIA_ORDERS[order]])


def inertia_tensor(p10: np.ndarray) -> np.ndarray:
    """J about the joint frame origin from (…, A, B, C, D, E, F)."""
    a, b, c, d, e, f = p10[4:10]
    return np.array([[a, -f, -e], [-f, b, -d], [-e, -d, c]])


def pinocchio_dynamic_parameters(p10: np.ndarray) -> np.ndarray:
    """Pinocchio's order ``[m, mc_x, mc_y, mc_z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (about the frame
    origin) from the paper's ``(m, mρx, mρy, mρz, A, B, C, D, E, F)``."""
    m, hx, hy, hz, a, b, c, d, e, f = p10
    return np.array([m, hx, hy, hz, a, -f, b, -e, -d, c])


def standard_vector(bodies, rotor, viscous, coulomb) -> np.ndarray:
    """The 78-vector from six bodies' ten parameters each and the drive's (6,) arrays."""
    p = np.zeros(N_PARAMS)
    for i, p10 in enumerate(bodies):
        p[body_slice(i)] = p10
    p[ROTOR] = rotor
    p[VISCOUS] = viscous
    p[COULOMB] = coulomb
    return p


def tool_body_vector(p10: np.ndarray) -> np.ndarray:
    """A 78-vector with ``p10`` on the last body and zeros elsewhere (a payload's parameters)."""
    p = np.zeros(N_PARAMS)
    p[TOOL_BODY] = p10
    return p


def check_standard(params, where: str = "params") -> np.ndarray:
    """``params`` as a float 78-vector; ValueError naming ``where`` otherwise."""
    p = np.asarray(params, dtype=float)
    if p.shape != (N_PARAMS,):
        raise ValueError(f"{where} must be a {N_PARAMS}-vector, got shape {p.shape}")
    return p


def standard_from_links(spec) -> np.ndarray:
    """The nominal 78-vector of a :class:`~urident.model.robot.RobotSpec` (its links and drives)."""
    bodies = [body_params(j.mass, j.com, j.inertia_com) for j in spec.joints]
    return standard_vector(bodies, spec.arrays["rotor_inertia"], spec.arrays["viscous_friction"],
                           spec.arrays["coulomb_friction"])


def _kinds_by_name() -> dict[str, str]:
    out = dict(zip(parameter_names(), parameter_kinds()))
    for feature, (_, kind) in EXTRA_COLUMNS.items():
        out.update(dict.fromkeys(extra_column_names(feature), kind))
    return out


_KIND_BY_NAME = _kinds_by_name()
