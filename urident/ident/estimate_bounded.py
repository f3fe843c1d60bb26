"""The bounded least-squares problem (paper eq. 19 with positivity constraints).

The paper solves eq. (19) numerically "with the constraint that all base parameters are
positive". Not every base parameter of a 6-axis arm is physically positive (first moments m·ρ and
combinations such as A − B may be negative), so the bound p ≥ 0 is applied only to those that are:
base parameters made only of masses, diagonal inertias about a joint frame, rotor inertias and
friction coefficients with positive coefficients (:func:`urident.ident.design.nonnegative_mask`),
and the Stribeck/Dahl friction extras. Solved with ``scipy.optimize.lsq_linear`` (column-scaled).
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from urident.ident.estimate import Estimate, row_weights, statistics, statistics_reduced
from urident.ident.estimate_ols import (check_inputs, check_reduced, factor_scaled, reduce_ls, resolve_weights,
                                       resolve_weights_reduced)


def estimate_bounded(w: np.ndarray, y: np.ndarray, names, nonnegative: np.ndarray,
                     weighting: str = "none") -> Estimate:
    check_inputs(w, y)
    weights = resolve_weights(w, y, weighting)
    rw = row_weights(weights, len(y) // 6)
    ww, yw = w * rw[:, None], y * rw
    scale = np.linalg.norm(ww, axis=0)
    scale[scale == 0] = 1.0
    r_, z_ = reduce_ls(ww / scale, yw)
    x, info = _solve_bounded(r_, z_, scale, names, nonnegative)
    return Estimate("bounded", tuple(names), x, weights=weights, info=info,
                    **statistics(w, y, x, weights))


def _solve_bounded(r_, z_, scale, names, nonnegative):
    lower = np.where(nonnegative, 0.0, -np.inf)
    res = scipy.optimize.lsq_linear(r_, z_, bounds=(lower, np.inf), method="bvls", tol=1e-12)
    x = res.x / scale
    x[nonnegative] = np.maximum(x[nonnegative], 0.0)
    active = [n for n, a in zip(names, nonnegative & (x <= 0)) if a]
    return x, {"active_bounds": active}


def estimate_bounded_reduced(red, names, nonnegative: np.ndarray, weighting: str = "none") -> Estimate:
    """:func:`estimate_bounded` on a reduced problem (:mod:`urident.ident.reduced`)."""
    check_reduced(red)
    weights = resolve_weights_reduced(red, weighting)
    r_, z_, scale = factor_scaled(red, weights)
    x, info = _solve_bounded(r_, z_, scale, names, nonnegative)
    return Estimate("bounded", tuple(names), x, weights=weights, info=info,
                    **statistics_reduced(red, x, weights))
