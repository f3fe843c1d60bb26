"""Validation metrics: the paper's normalised error e_N (eq. 22), per-joint RMS and relative error.

e_N = ‖e‖ / m with e the stacked residual over all joints and m the number of *time samples*;
rms_j = sqrt(mean_k e_kj²) [N·m]; rre_j = 100·‖e_j‖/‖τ_j‖ [%] (the source project's measure).

This module is the one place these are computed: :func:`error_metrics` (a residual), :func:`metrics`
(measured vs predicted), and :class:`RunningMetrics`, the same sums kept batch by batch for a
stream (the live view).
"""

from __future__ import annotations

import numpy as np


def error_metrics(residual: np.ndarray) -> tuple[float, np.ndarray]:
    """(e_N, rms (6,)) of an (N, 6) residual (either sign)."""
    e = np.asarray(residual, float)
    return float(np.linalg.norm(e) / e.shape[0]), np.sqrt(np.mean(e ** 2, axis=0))


def metrics(tau_measured: np.ndarray, tau_predicted: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(e_N, rms (6,), rre % (6,))."""
    e = np.asarray(tau_predicted, float) - np.asarray(tau_measured, float)
    e_n, rms = error_metrics(e)
    with np.errstate(divide="ignore", invalid="ignore"):
        rre = 100.0 * np.linalg.norm(e, axis=0) / np.linalg.norm(tau_measured, axis=0)
    return e_n, rms, rre


class RunningMetrics:
    """e_N and per-joint RMS over all samples added so far, from running sums of squares (a stream
    cannot keep its whole residual); equal to :func:`error_metrics` of the concatenated residual."""

    def __init__(self) -> None:
        self.n = 0
        self._sq = np.zeros(6)

    def add(self, residual: np.ndarray) -> None:
        e = np.asarray(residual, float).reshape(-1, 6)
        self.n += e.shape[0]
        self._sq = self._sq + np.sum(e * e, axis=0)

    @property
    def e_n(self) -> float:
        return float(np.sqrt(np.sum(self._sq)) / self.n) if self.n else float("nan")

    @property
    def rms(self) -> np.ndarray:
        return np.sqrt(self._sq / self.n) if self.n else np.full(6, np.nan)
