"""Feature columns of the torque model beyond the paper's regressor, shared by the identification
model (:mod:`urident.ident.design`) and the gap diagnosis' candidates (:mod:`urident.gap.candidates`).

Each function returns the values of a column that is linear in its coefficient, per joint:

* :func:`stribeck`: tanh(q̇/ε)·exp(−(q̇/v_s)²), the extra static friction near zero speed;
* :func:`load_friction`: |τ_L|·z, load-dependent Coulomb friction of a harmonic drive (the tooth and
  bearing forces, hence the friction, grow with the transmitted torque τ_L); z the Coulomb state;
* :func:`sqrt_viscous`: sign(q̇)·sqrt(|q̇|), a concave (sub-linear) viscous term, as the lubricant
  film of a harmonic drive gives;
* :func:`quadratic_viscous`: q̇·|q̇|, friction growing faster than linearly with speed (lubricant
  drag at high speed);
* :func:`offset`: a constant (asymmetric Coulomb friction, current-sensor bias, static load);
* :func:`coulomb_asymmetry`: |z|, a Coulomb level that differs between the two directions of
  motion (z the Coulomb state; unlike an offset it vanishes where z does);
* :func:`sigmoid`, :func:`sigmoid_offset`: tanh(q̇/ε) and tanh²(q̇/ε), together the linearised form
  of Gaz et al.'s (RA-L 2019) sigmoid with a velocity offset (function docs);
* :func:`quadratic_viscous`: q̇·|q̇|, a convex viscous term;
* :func:`position_friction`: z·cos(k·q), z·sin(k·q), Coulomb friction varying with the position at
  harmonic k (k periods per joint revolution);
* :func:`temperature_viscous`, :func:`temperature_coulomb`: q̇·(T − T_ref) and z·(T − T_ref),
  viscous and Coulomb friction changing with the joint temperature T [°C] (the lubricant's
  viscosity falls as it warms), T_ref the temperature at which the base friction holds;
* :func:`link_torque`: the link-side rigid-body torque of a 78-vector (no rotor inertia, no
  friction), the τ_L of the identification model's load friction;
* :func:`tool_body_regressor`, :func:`payload_torque`, :func:`payload_columns`: the torque of a
  payload carried by the last body, and the columns that fit one (point mass at the tool and the
  first moments m·ρ of body 6).

The history-driven Coulomb states (Dahl, hold) are in :mod:`urident.ident.friction`. The simulated
controller's forward effects (:mod:`urident.simcontroller.effects`) are written separately on
purpose: they are the ground truth the benchmarks score these columns against.
"""

from __future__ import annotations

import numpy as np

from urident.model.parameters import BODY_FIELDS, RIGID_BODY, TOOL_BODY, body_params

#: Extra features whose coefficient must be >= 0 physically.
NONNEGATIVE_EXTRAS = frozenset({"stribeck", "dahl", "load", "sqrtvisc", "quadvisc"})
#: The first-moment entries (m·ρx, m·ρy, m·ρz) among a body's ten parameters.
FIRST_MOMENTS = slice(BODY_FIELDS.index("mrx"), BODY_FIELDS.index("mrz") + 1)


def stribeck(qd: np.ndarray, eps: float, vs: float) -> np.ndarray:
    """tanh(q̇/ε)·exp(−(q̇/v_s)²) for velocities ``qd`` [rad/s], slope ``eps``, Stribeck velocity ``vs``."""
    qd = np.asarray(qd, dtype=float)
    return np.tanh(qd / eps) * np.exp(-(qd / vs) ** 2)


def load_friction(link_torque: np.ndarray, coulomb_state: np.ndarray) -> np.ndarray:
    """|τ_L|·z from the link-side torque [N·m] and the Coulomb state z (tanh, Dahl or hold)."""
    return np.abs(link_torque) * coulomb_state


def sqrt_viscous(qd: np.ndarray) -> np.ndarray:
    qd = np.asarray(qd, dtype=float)
    return np.sign(qd) * np.sqrt(np.abs(qd))


def quadratic_viscous(qd: np.ndarray) -> np.ndarray:
    """q̇·|q̇| for velocities ``qd`` [rad/s]."""
    qd = np.asarray(qd, dtype=float)
    return qd * np.abs(qd)


def offset(shape) -> np.ndarray:
    return np.ones(shape)


def coulomb_asymmetry(coulomb_state: np.ndarray) -> np.ndarray:
    """|z|: with the Coulomb column a·z, the level is a + b moving forwards and a − b backwards."""
    return np.abs(coulomb_state)


def sigmoid(qd: np.ndarray, eps: float) -> np.ndarray:
    """tanh(q̇/ε): a Coulomb term with its own smoothness ε [rad/s] (Gaz et al.'s 2/φ2)."""
    return np.tanh(np.asarray(qd, dtype=float) / eps)


def sigmoid_offset(qd: np.ndarray, eps: float) -> np.ndarray:
    """tanh²(q̇/ε). Gaz et al.'s φ1/(1 + e^{−φ2(q̇+φ3)}) − φ1/(1 + e^{−φ2 φ3}) is, with ε = 2/φ2,
    (φ1/2)·[tanh((q̇+φ3)/ε) − tanh(φ3/ε)] ≈ (φ1/2)·tanh(q̇/ε) − (φ1 φ3/2ε)·tanh²(q̇/ε) to first
    order in φ3/ε; both asymptotes (φ1(1 − σ(φ2φ3)) and −φ1 σ(φ2φ3)) are matched exactly."""
    return np.tanh(np.asarray(qd, dtype=float) / eps) ** 2


def position_friction(q: np.ndarray, coulomb_state: np.ndarray, harmonic: float) -> tuple[np.ndarray, np.ndarray]:
    """(z·cos(k q), z·sin(k q)): Coulomb friction modulated by the position ``q`` [rad] at harmonic
    k (k periods per joint revolution), e.g. a flexspline's once- or twice-per-turn variation."""
    arg = harmonic * np.asarray(q, dtype=float)
    return coulomb_state * np.cos(arg), coulomb_state * np.sin(arg)


def temperature_viscous(qd: np.ndarray, temperature: np.ndarray, t_ref: float) -> np.ndarray:
    """q̇·(T − T_ref) for velocities ``qd`` [rad/s] and joint temperatures ``temperature`` [°C]."""
    return np.asarray(qd, dtype=float) * (np.asarray(temperature, dtype=float) - t_ref)


def temperature_coulomb(coulomb_state: np.ndarray, temperature: np.ndarray, t_ref: float) -> np.ndarray:
    """z·(T − T_ref) for the Coulomb state z and joint temperatures ``temperature`` [°C]."""
    return coulomb_state * (np.asarray(temperature, dtype=float) - t_ref)


def link_torque(blocks: np.ndarray, params: np.ndarray) -> np.ndarray:
    """(N, 6) rigid-body torque of the 78-vector ``params`` from the (N, 6, 78) regressor: the six
    bodies' parameters only (no rotor inertia, no friction)."""
    return blocks[:, :, RIGID_BODY] @ np.asarray(params, dtype=float)[RIGID_BODY]


def tool_body_regressor(blocks: np.ndarray) -> np.ndarray:
    """(N, 6, 10) regressor columns of the last body (a payload's parameters add to its)."""
    return blocks[:, :, TOOL_BODY]


def payload_torque(blocks: np.ndarray, payload: np.ndarray) -> np.ndarray:
    """(N, 6) torque of a payload (its ten parameters about K_6) from the (N, 6, 78) regressor."""
    return tool_body_regressor(blocks) @ np.asarray(payload, dtype=float)


def payload_columns(blocks: np.ndarray, tool_xyz) -> np.ndarray:
    """(N, 6, 4) columns of a payload error: the torque of 1 kg at the tool point ``tool_xyz``
    (K_6) and the three first-moment columns m·ρ of body 6 (a centre-of-mass shift)."""
    y6 = tool_body_regressor(blocks)
    point = y6 @ body_params(1.0, np.asarray(tool_xyz, float), np.zeros((3, 3)))
    return np.concatenate([point[:, :, None], y6[:, :, FIRST_MOMENTS]], axis=2)
