"""Ordinary least squares (paper eq. 20, the pseudo-inverse) with optional per-joint weighting.

Weighting ``'joint'``: a first plain fit gives each joint's residual standard deviation s_j; the
rows of joint j are then divided by s_j and the problem solved again (weighted least squares,
Gautier's classical choice for joints with different noise levels). ``'none'`` is the paper's.
"""

from __future__ import annotations

import numpy as np

from urident.errors import ConfigError
from urident.ident.estimate import (Estimate, joint_weights, joint_weights_reduced, row_weights, statistics,
                                   statistics_reduced)

WEIGHTINGS = ("none", "joint")


def reduce_ls(a: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, z) with ‖a x − y‖² = ‖R x − z‖² + const, R upper triangular (n, n), from the Cholesky
    factor of the Gram matrix (much faster than a QR of the tall matrix; ``a`` should be
    column-scaled). Falls back to an SVD-based square root when the Gram matrix is singular."""
    import scipy.linalg

    g = a.T @ a
    b = a.T @ y
    try:
        lower = scipy.linalg.cholesky(g, lower=True)
        return lower.T, scipy.linalg.solve_triangular(lower, b, lower=True)
    except np.linalg.LinAlgError:
        u, s, _ = np.linalg.svd(g)
        keep = s > s[0] * 1e-14
        r = (u[:, keep] * np.sqrt(s[keep])).T
        return r, (u[:, keep].T @ b) / np.sqrt(s[keep])


def solve_ls(w: np.ndarray, y: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """argmin ‖diag(weights)(w x − y)‖ with column scaling (w: (6N, n), rows 6k + j). Normal
    equations by Cholesky plus one step of iterative refinement (accurate to the conditioning of
    the column-scaled regressor); SVD-based least squares if the Gram matrix is singular."""
    import scipy.linalg

    if weights is not None:
        rw = row_weights(weights, len(y) // 6)
        w, y = w * rw[:, None], y * rw
    scale = np.linalg.norm(w, axis=0)
    scale[scale == 0] = 1.0
    a = w / scale
    try:
        factor = scipy.linalg.cho_factor(a.T @ a)
        x = scipy.linalg.cho_solve(factor, a.T @ y)
        x += scipy.linalg.cho_solve(factor, a.T @ (y - a @ x))
    except np.linalg.LinAlgError:
        x, *_ = np.linalg.lstsq(a, y, rcond=None)
    return x / scale


def check_inputs(w: np.ndarray, y: np.ndarray) -> None:
    if w.shape[0] != y.shape[0] or w.shape[0] % 6:
        raise ValueError(f"regressor rows {w.shape[0]} and torques {y.shape[0]} must match, multiple of 6")
    if w.shape[0] <= w.shape[1]:
        raise ConfigError(f"{w.shape[0] // 6} samples are too few to identify {w.shape[1]} parameters")
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(y))):
        raise ConfigError("regressor or torques hold NaN/inf")


def resolve_weights(w: np.ndarray, y: np.ndarray, weighting: str) -> np.ndarray:
    if weighting not in WEIGHTINGS:
        raise ConfigError(f"weighting {weighting!r} unknown (known: {', '.join(WEIGHTINGS)})")
    if weighting == "none":
        return np.ones(6)
    return joint_weights(w, y, solve_ls(w, y))


def estimate_ols(w: np.ndarray, y: np.ndarray, names, weighting: str = "none") -> Estimate:
    """Pseudo-inverse solution and its statistics."""
    check_inputs(w, y)
    weights = resolve_weights(w, y, weighting)
    x = solve_ls(w, y, weights)
    return Estimate("ols", tuple(names), x, weights=weights, **statistics(w, y, x, weights))


def factor_scaled(red, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R/scale, z, scale): the weighted reduced problem with unit-norm columns."""
    r, z = red.combined(weights)
    scale = red.column_norms(weights)
    scale[scale == 0] = 1.0
    return r / scale, z, scale


def solve_reduced(red, weights: np.ndarray | None = None) -> np.ndarray:
    """:func:`solve_ls` on a reduced problem: back substitution on the column-scaled factor, SVD-based
    least squares if it is numerically singular."""
    import scipy.linalg

    r, z, scale = factor_scaled(red, np.ones(6) if weights is None else weights)
    d = np.abs(np.diag(r))
    if d.min() > 1e-13 * d.max():
        x = scipy.linalg.solve_triangular(r, z)
    else:
        x, *_ = np.linalg.lstsq(r, z, rcond=None)
    return x / scale


def check_reduced(red) -> None:
    if 6 * red.n_samples <= red.n_params:
        raise ConfigError(f"{red.n_samples} samples are too few to identify {red.n_params} parameters")


def resolve_weights_reduced(red, weighting: str) -> np.ndarray:
    if weighting not in WEIGHTINGS:
        raise ConfigError(f"weighting {weighting!r} unknown (known: {', '.join(WEIGHTINGS)})")
    if weighting == "none":
        return np.ones(6)
    return joint_weights_reduced(red, solve_reduced(red))


def estimate_ols_reduced(red, names, weighting: str = "none") -> Estimate:
    """:func:`estimate_ols` on a reduced problem (:mod:`urident.ident.reduced`)."""
    check_reduced(red)
    weights = resolve_weights_reduced(red, weighting)
    x = solve_reduced(red, weights)
    return Estimate("ols", tuple(names), x, weights=weights, **statistics_reduced(red, x, weights))
