"""Model selection by blocked cross-validation inside the identification data.

The data set is cut into ``folds`` contiguous blocks in time; each block is predicted by parameters
identified on the others, and the score is the mean over joints of the RMS prediction error of all
held-out samples [N·m]. Contiguous blocks (not random samples) keep neighbouring, correlated
samples on the same side of the split. Features that depend on the motion history (the Dahl state)
are computed on the whole sequence from positions only, so no torque leaks into the held-out block.
Only the identification data are used: validation logs must never drive these choices.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterable

import numpy as np

from urident.ident.design import ModelConfig, nonnegative_mask
from urident.ident.estimate_bounded import estimate_bounded_reduced
from urident.ident.estimate_ols import estimate_ols_reduced
from urident.ident.preprocess import Prepared
from urident.ident.reduced import merge, reduce_blocks


@dataclass(frozen=True)
class CVScore:
    model: ModelConfig
    weighting: str
    method: str
    mean_rms_nm: float
    rms_nm: np.ndarray


def cross_validate(spec, data: Prepared, model: ModelConfig, weighting: str = "none",
                   method: str = "ols", folds: int = 5, target: np.ndarray | None = None) -> CVScore:
    """Blocked CV score. ``target`` (N, 6): the torques held-out blocks are scored against
    (default ``data.tau``; pass the unfiltered torques when ``data.tau`` was low-passed, so that
    a torque filter is judged by how well it predicts the raw measurement)."""
    n = len(data)
    edges = np.linspace(0, n, folds + 1).astype(int)
    # one reduced problem per block, with the training torques and the scoring target as columns
    y = data.tau if target is None else np.asarray(target, dtype=float).reshape(n, 6)
    targets = np.stack([data.tau, y], axis=2)
    parts = reduce_blocks(spec, model, data, edges, targets)
    names = [str(k) for k in range(parts[0].n_params)]
    sq = np.zeros(6)
    for k in range(folds):
        train = merge(p for i, p in enumerate(parts) if i != k).select(0)
        if method == "bounded":
            est = estimate_bounded_reduced(train, names, nonnegative_mask(spec, model), weighting)
        else:
            est = estimate_ols_reduced(train, names, weighting)
        sq += parts[k].residual_sq(est.values, target=1)
    rms = np.sqrt(sq / n)
    return CVScore(model, weighting, method, float(rms.mean()), rms)


def select(spec, data: Prepared, candidates: Iterable[tuple[ModelConfig, str]], method: str = "ols",
           folds: int = 5, target: np.ndarray | None = None) -> list[CVScore]:
    """Scores of (model, weighting) candidates, best first."""
    scores = [cross_validate(spec, data, m, w, method, folds, target) for m, w in candidates]
    return sorted(scores, key=lambda s: s.mean_rms_nm)


def select_dahl_rad(spec, data: Prepared, model: ModelConfig, grid: Iterable[float],
                    weighting: str = "none", method: str = "ols", folds: int = 5,
                    target: np.ndarray | None = None) -> tuple[ModelConfig, list[CVScore]]:
    """The Dahl presliding distance δ of ``model`` chosen from ``grid`` by blocked CV (lowest mean
    held-out RMS). Returns the model with that δ and the scores in grid order."""
    grid = [float(d) for d in grid]
    if not grid:
        raise ValueError("empty grid of Dahl distances")
    scores = [cross_validate(spec, data, replace(model, dahl_rad=d), weighting, method, folds, target)
              for d in grid]
    best = min(range(len(grid)), key=lambda k: scores[k].mean_rms_nm)
    return replace(model, dahl_rad=grid[best]), scores


def select_torque_lead(spec, data: Prepared, model: ModelConfig, grid: Iterable[float],
                       weighting: str = "none", method: str = "ols", folds: int = 5,
                       min_gain: float = 0.005) -> tuple[float, list[CVScore]]:
    """How far the measured torque leads the motion [s], chosen from ``grid`` by blocked CV of
    ``model`` (:func:`urident.ident.preprocess.with_torque_lead`; always scored on the measured
    torques): the lowest mean held-out RMS, and 0 unless that is at least ``min_gain`` (relative)
    below the model's without a lead. Returns the lead and the scores in grid order."""
    from urident.ident.preprocess import with_torque_lead

    grid = [float(s) for s in grid]
    if 0.0 not in grid:
        raise ValueError("the grid of torque leads must hold 0")
    scores = [cross_validate(spec, with_torque_lead(data, s), model, weighting, method, folds) for s in grid]
    best = min(range(len(grid)), key=lambda k: scores[k].mean_rms_nm)
    zero = scores[grid.index(0.0)].mean_rms_nm
    return (grid[best] if scores[best].mean_rms_nm <= (1 - min_gain) * zero else 0.0), scores


def select_acceleration_corner(spec, data: Prepared, model: ModelConfig, grid: Iterable[float], base_hz: float,
                               weighting: str = "none", method: str = "ols", folds: int = 5,
                               prewarp: bool = True, min_gain: float = 0.005) -> tuple[float, list[CVScore]]:
    """The corner of the acceleration filter [Hz], chosen from ``grid`` by blocked CV of ``model``
    (:func:`urident.ident.preprocess.with_acceleration_corner`; scored on the measured torques):
    the lowest mean held-out RMS, and ``base_hz`` (the corner ``data`` were prepared with) unless
    that is at least ``min_gain`` (relative) below the base's. Returns the corner and the scores
    in grid order."""
    from urident.ident.preprocess import with_acceleration_corner

    grid = [float(f) for f in grid]
    if float(base_hz) not in grid:
        raise ValueError("the grid of acceleration corners must hold the base corner")
    scores = [cross_validate(spec, data if f == base_hz else with_acceleration_corner(data, f, prewarp),
                             model, weighting, method, folds) for f in grid]
    best = min(range(len(grid)), key=lambda k: scores[k].mean_rms_nm)
    base = scores[grid.index(float(base_hz))].mean_rms_nm
    return (grid[best] if scores[best].mean_rms_nm <= (1 - min_gain) * base else float(base_hz)), scores
