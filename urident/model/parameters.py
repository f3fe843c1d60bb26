"""The paper's parameter vector (eq. 39-40) and conversions to and from link inertial data.

Layout (78): for body i = 1..6 the ten values ``(m, mρx, mρy, mρz, A, B, C, D, E, F)`` about the
joint frame K_i, with the inertia tensor J = [[A, -F, -E], [-F, B, -D], [-E, -D, C]]; then the
reflected rotor inertias ``i_G,i^2 C_M,i`` (6); then viscous ``r_v`` (6) and Coulomb ``r_c`` (6)
friction coefficients.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from urident.model.robot import RobotSpec

BODY_FIELDS = ("m", "mrx", "mry", "mrz", "A", "B", "C", "D", "E", "F")
ROTOR_OFFSET = 60
VISCOUS_OFFSET = 66
COULOMB_OFFSET = 72


def parameter_names() -> list[str]:
    """Names of the 78 standard parameters: ``m2``, ``mrz3`` (m·ρz of body 3), ``C1``, ``IM4``
    (i_G² C_M of joint 4), ``fv5`` (viscous), ``fc6`` (Coulomb)."""
    names = [f"{f}{i}" for i in range(1, 7) for f in BODY_FIELDS]
    names += [f"IM{i}" for i in range(1, 7)]
    names += [f"fv{i}" for i in range(1, 7)]
    names += [f"fc{i}" for i in range(1, 7)]
    return names


def body_inertia_about_origin(mass: float, com: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """Inertia tensor about the frame origin (parallel-axis theorem)."""
    c = np.asarray(com, dtype=float)
    return inertia_com + mass * (c @ c * np.eye(3) - np.outer(c, c))


def body_params(mass: float, com: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """The ten paper parameters of one body."""
    j = body_inertia_about_origin(mass, com, inertia_com)
    h = mass * np.asarray(com, dtype=float)
    return np.array([mass, h[0], h[1], h[2], j[0, 0], j[1, 1], j[2, 2], -j[1, 2], -j[0, 2], -j[0, 1]])


def inertia_tensor(p10: np.ndarray) -> np.ndarray:
    """J about the joint frame origin from (…, A, B, C, D, E, F)."""
    a, b, c, d, e, f = p10[4:10]
    return np.array([[a, -f, -e], [-f, b, -d], [-e, -d, c]])


def pinocchio_dynamic_parameters(p10: np.ndarray) -> np.ndarray:
    """Pinocchio's order ``[m, mc_x, mc_y, mc_z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (about the frame
    origin) from the paper's ``(m, mρx, mρy, mρz, A, B, C, D, E, F)``."""
    m, hx, hy, hz, a, b, c, d, e, f = p10
    return np.array([m, hx, hy, hz, a, -f, b, -e, -d, c])


def standard_from_links(spec: "RobotSpec") -> np.ndarray:
    """The robot file's nominal 78-vector."""
    p = np.zeros(78)
    for i, joint in enumerate(spec.joints):
        p[10 * i:10 * i + 10] = body_params(joint.mass, joint.com, joint.inertia_com)
    p[ROTOR_OFFSET:ROTOR_OFFSET + 6] = spec.arrays["rotor_inertia"]
    p[VISCOUS_OFFSET:VISCOUS_OFFSET + 6] = spec.arrays["viscous_friction"]
    p[COULOMB_OFFSET:COULOMB_OFFSET + 6] = spec.arrays["coulomb_friction"]
    return p
