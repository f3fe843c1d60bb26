"""Physically consistent estimation: a semidefinite program over the 78 standard parameters.

    minimise   ‖R (C p ⊕ x) − z‖² / σ²  +  λ Σ_k ((p_k − p_nom,k) / s_k)²
    subject to J_i(p) ⪰ 0, m_i ≥ m_min,i      (i = 1..6, pseudo-inertia, Wensing et al. 2017)
               rotor inertia, viscous and Coulomb friction ≥ 0, Stribeck/Dahl extras ≥ 0

with J_i = [[½ tr(I_i)·1 − I_i, h_i], [h_iᵀ, m_i]] (I_i the inertia about the joint frame origin,
h_i = m_i ρ_i): J_i ⪰ 0 is equivalent to the body being realisable by a non-negative mass density
(positive mass, centre of mass in the convex hull of the density, inertia satisfying the triangle
inequalities). C maps standard to base parameters, x are the extra friction coefficients, and
R, z come from a Cholesky factorisation of the Gram matrix of the (weighted) regressor [Θ_B | Θ_X], so the data term is the
least-squares cost up to a constant. σ² is the residual variance of the unconstrained OLS fit, so
the data term is ≈ χ² with 6m degrees of freedom, and the regulariser with the default
λ = 1e-3 is a weak prior (std ≈ 30 s_k) that only fixes the directions the data cannot see
(the 78 − b non-identifiable combinations). s_k is |p_nom,k| with a floor per kind of parameter.
The mass floor m_min,i is 1 % of the nominal mass. Solved by cvxpy with Clarabel.
"""

from __future__ import annotations

import numpy as np

from urident.errors import UridentError
from urident.ident.estimate import Estimate, row_weights, statistics, statistics_reduced
from urident.ident.estimate_ols import (check_inputs, check_reduced, factor_scaled, reduce_ls, resolve_weights,
                                       resolve_weights_reduced, solve_ls, solve_reduced)
from urident.model.parameters import COULOMB, DRIVE, FRICTION, N_JOINTS, N_PARAMS, ROTOR, VISCOUS, body_slice

DEFAULT_REGULARISATION = 1e-3
_FLOORS = {"m": 0.1, "h": 0.01, "I": 1e-3, "IM": 1e-2, "f": 0.1}


class ConsistentSolveError(UridentError):
    """The semidefinite program did not solve."""


def parameter_scales(nominal: np.ndarray) -> np.ndarray:
    s = np.zeros(N_PARAMS)
    for i in range(N_JOINTS):
        k = body_slice(i).start
        s[k] = max(abs(nominal[k]), _FLOORS["m"])
        s[k + 1:k + 4] = np.maximum(np.abs(nominal[k + 1:k + 4]), _FLOORS["h"])
        s[k + 4:k + 10] = np.maximum(np.abs(nominal[k + 4:k + 10]), _FLOORS["I"])
    s[ROTOR] = np.maximum(np.abs(nominal[ROTOR]), _FLOORS["IM"])
    s[FRICTION] = np.maximum(np.abs(nominal[FRICTION]), _FLOORS["f"])
    return s


def estimate_consistent(w: np.ndarray, y: np.ndarray, names, combination: np.ndarray,
                        nominal: np.ndarray, extra_nonnegative: np.ndarray,
                        weighting: str = "none", regularisation: float = DEFAULT_REGULARISATION,
                        ) -> Estimate:
    """``w`` = [Θ_B | Θ_X] (6N, b + nx), ``combination`` C (b, 78), ``nominal`` the robot file's
    78-vector, ``extra_nonnegative`` (nx,) which extra coefficients must be ≥ 0."""
    check_inputs(w, y)
    b = combination.shape[0]
    nx = w.shape[1] - b
    weights = resolve_weights(w, y, weighting)
    rw = row_weights(weights, len(y) // 6)
    ww, yw = w * rw[:, None], y * rw
    col = np.linalg.norm(ww, axis=0)
    col[col == 0] = 1.0
    r_, z = reduce_ls(ww / col, yw)
    x_ols = solve_ls(w, y, weights)
    e = ww @ x_ols - yw
    noise_var = max(float(e @ e) / max(len(y) - w.shape[1], 1), 1e-300)

    x, p_hat, info = _solve_sdp(r_, z, col, noise_var, combination, nominal, extra_nonnegative,
                                regularisation, nx)
    return Estimate("consistent", tuple(names), x, weights=weights, standard=p_hat, info=info,
                    **statistics(w, y, x, weights))


def estimate_consistent_reduced(red, names, combination: np.ndarray, nominal: np.ndarray,
                                extra_nonnegative: np.ndarray, weighting: str = "none",
                                regularisation: float = DEFAULT_REGULARISATION) -> Estimate:
    """:func:`estimate_consistent` on a reduced problem (:mod:`urident.ident.reduced`)."""
    check_reduced(red)
    nx = red.n_params - combination.shape[0]
    weights = resolve_weights_reduced(red, weighting)
    r_, z, col = factor_scaled(red, weights)
    x_ols = solve_reduced(red, weights)
    dof = max(6 * red.n_samples - red.n_params, 1)
    noise_var = max(float(weights ** 2 @ red.residual_sq(x_ols)) / dof, 1e-300)
    x, p_hat, info = _solve_sdp(r_, z, col, noise_var, combination, nominal, extra_nonnegative,
                                regularisation, nx)
    return Estimate("consistent", tuple(names), x, weights=weights, standard=p_hat, info=info,
                    **statistics_reduced(red, x, weights))


def _solve_sdp(r_, z, col, noise_var, combination, nominal, extra_nonnegative, regularisation, nx):
    import cvxpy as cp

    nominal = np.asarray(nominal, dtype=float)
    s = parameter_scales(nominal)
    p = cp.Variable(N_PARAMS)
    xe = cp.Variable(nx) if nx else None
    theta = combination @ p
    full = cp.hstack([theta, xe]) if nx else theta
    # the QR is of the column-scaled matrix, whose unknowns are col·x
    resid = r_ @ cp.multiply(col, full) - z
    objective = cp.sum_squares(resid) / noise_var + regularisation * cp.sum_squares(cp.multiply(1.0 / s, p - nominal))
    if nx:
        objective += regularisation * cp.sum_squares(xe)
    cons = []
    for i in range(N_JOINTS):
        k = body_slice(i).start
        m, hx, hy, hz, a_, b_, c_, d_, e_, f_ = (p[k + j] for j in range(10))
        jm = cp.Variable((4, 4), PSD=True)
        cons += [jm[0, 0] == (-a_ + b_ + c_) / 2, jm[1, 1] == (a_ - b_ + c_) / 2,
                 jm[2, 2] == (a_ + b_ - c_) / 2, jm[0, 1] == f_, jm[0, 2] == e_, jm[1, 2] == d_,
                 jm[0, 3] == hx, jm[1, 3] == hy, jm[2, 3] == hz, jm[3, 3] == m,
                 m >= 0.01 * max(nominal[k], _FLOORS["m"])]
    cons += [p[ROTOR] >= 0, p[VISCOUS] >= 0, p[COULOMB] >= 0]
    if nx and np.any(extra_nonnegative):
        cons.append(xe[np.flatnonzero(extra_nonnegative)] >= 0)
    problem = cp.Problem(cp.Minimize(objective), cons)
    try:
        problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise ConsistentSolveError(f"consistent estimation: solver failed ({exc})") from None
    if problem.status not in ("optimal", "optimal_inaccurate") or p.value is None:
        raise ConsistentSolveError(f"consistent estimation: solver status {problem.status}")
    p_hat = np.asarray(p.value, dtype=float)
    x = combination @ p_hat
    if nx:
        x = np.concatenate([x, np.asarray(xe.value, dtype=float)])
    info = {"solver_status": problem.status, "regularisation": regularisation,
            "min_pseudo_inertia_eig": float(min(_pseudo_min_eig(p_hat)))}
    return x, p_hat, info


def pseudo_inertia(p10: np.ndarray) -> np.ndarray:
    """4×4 pseudo-inertia matrix of one body's ten parameters."""
    from urident.model.parameters import inertia_tensor

    inertia = inertia_tensor(p10)
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    h = np.asarray(p10[1:4], dtype=float)
    return np.block([[sigma, h[:, None]], [h[None, :], np.array([[p10[0]]])]])


def _pseudo_min_eig(p: np.ndarray) -> list[float]:
    return [float(np.linalg.eigvalsh(pseudo_inertia(p[body_slice(i)])).min()) for i in range(N_JOINTS)]


def is_physically_consistent(p: np.ndarray, tol: float = 1e-9) -> bool:
    """Every body's pseudo-inertia ⪰ 0 with positive mass, rotor inertia and friction ≥ 0."""
    p = np.asarray(p, dtype=float)
    masses = p[[body_slice(i).start for i in range(N_JOINTS)]]
    ok = all(e >= -tol * max(1.0, abs(m)) for m, e in zip(masses, _pseudo_min_eig(p)))
    ok &= all(m > 0 for m in masses)
    return bool(ok and np.all(p[DRIVE] >= -tol))
