"""The result of one estimation method and the statistics shared by all methods.

Standard deviations follow the paper's eq. (21), σ_i = sqrt(((Θ_Bᵀ Θ_B)⁻¹)_ii), *scaled by the
noise variance* σ² = ‖e‖² / (r − n) estimated from the residual e, where r = 6m is the number of
rows of the stacked regressor (m time samples) and n the number of estimated parameters (eq. 21
as printed assumes unit noise variance). With per-joint weighting the rows are divided by the
joint's residual standard deviation first, so σ² is the weighted residual variance (≈ 1).
For the bounded and consistent methods the same covariance is evaluated at their solution; it
ignores active constraints (an upper estimate of the uncertainty there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.ident.metrics import error_metrics


@dataclass(frozen=True)
class Estimate:
    """Parameters of the identification model estimated by one method."""

    method: str
    names: tuple[str, ...]
    values: np.ndarray          # (n,) base parameters followed by the extra friction coefficients
    sigma: np.ndarray           # (n,) standard deviations (module doc)
    noise_var: float            # σ² of the (weighted) residual
    weights: np.ndarray         # (6,) per-joint row weights used (ones for plain LS)
    train_rms: np.ndarray       # (6,) per-joint RMS of the unweighted training residual [N·m]
    train_e_n: float            # eq. (22) on the training data
    standard: np.ndarray | None = None   # 78-vector (consistent method only)
    info: dict | None = None

    @property
    def relative_sigma_pct(self) -> np.ndarray:
        """100·σ/|p| per parameter (inf where p = 0)."""
        with np.errstate(divide="ignore"):
            return 100.0 * self.sigma / np.abs(self.values)


def row_weights(weights: np.ndarray, n_samples: int) -> np.ndarray:
    return np.tile(np.asarray(weights, dtype=float), n_samples)


def statistics(w: np.ndarray, y: np.ndarray, x: np.ndarray, weights: np.ndarray) -> dict:
    """σ, σ², training RMS and e_N of parameters ``x`` on stacked (w, y) (unweighted inputs)."""
    n_samples = len(y) // 6
    rw = row_weights(weights, n_samples)
    e = w @ x - y
    ew = e * rw
    dof = max(len(y) - w.shape[1], 1)
    noise_var = float(ew @ ew / dof)
    ww = w * rw[:, None]
    # (ΘᵀΘ)⁻¹ through a column-scaled SVD-based pseudo-inverse (robust to poor conditioning)
    scale = np.linalg.norm(ww, axis=0)
    scale[scale == 0] = 1.0
    gram_inv = np.linalg.pinv((ww / scale).T @ (ww / scale)) / np.outer(scale, scale)
    sigma = np.sqrt(np.clip(np.diag(gram_inv), 0, None) * noise_var)
    train_e_n, train_rms = error_metrics(e.reshape(-1, 6))
    return {"sigma": sigma, "noise_var": noise_var, "train_rms": train_rms, "train_e_n": train_e_n}


def joint_weights(w: np.ndarray, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Per-joint weights 1/std of the residual of a first (unweighted) fit."""
    e = (w @ x - y).reshape(-1, 6)
    std = np.sqrt(np.mean(e ** 2, axis=0))
    std = np.maximum(std, 1e-9 * max(std.max(), 1e-300))
    return 1.0 / std


def joint_correlation_inflation(e: np.ndarray) -> np.ndarray:
    """(6,) the variance factor (1 + ρ_j)/(1 − ρ_j) of each joint's AR(1) residual (row 6k + j):
    its long-run variance over its variance (:func:`correlation_inflation` takes the largest)."""
    r = np.asarray(e, dtype=float).reshape(-1, 6)
    if len(r) < 3:
        return np.ones(6)
    r = r - r.mean(axis=0)
    den = np.sum(r * r, axis=0)
    rho = np.where(den > 0, np.sum(r[1:] * r[:-1], axis=0) / np.where(den > 0, den, 1.0), 0.0)
    rho = np.clip(rho, 0.0, 0.999)
    return (1 + rho) / (1 - rho)


def correlation_inflation(e: np.ndarray) -> float:
    """Variance factor (1 + ρ)/(1 − ρ) of an AR(1) residual with lag-1 autocorrelation ρ (per
    joint, the largest): unmodelled effects make the residual smooth, and white-noise σ would then
    call parameters determined that are not. ``e``: stacked residual, row 6k + j."""
    r = np.asarray(e, dtype=float).reshape(-1, 6)
    if len(r) < 3:
        return 1.0
    r = r - r.mean(axis=0)
    den = np.sum(r * r, axis=0)
    rho = np.where(den > 0, np.sum(r[1:] * r[:-1], axis=0) / np.where(den > 0, den, 1.0), 0.0)
    rho = float(np.clip(rho.max(), 0.0, 0.999))
    return (1 + rho) / (1 - rho)


def sigma_from_factor(r: np.ndarray, noise_var: float) -> np.ndarray:
    """σ from the triangular factor R of the weighted regressor (RᵀR = ΘᵀΘ), as :func:`statistics`."""
    scale = np.linalg.norm(r, axis=0)
    scale[scale == 0] = 1.0
    rs = r / scale
    gram_inv = np.linalg.pinv(rs.T @ rs) / np.outer(scale, scale)
    return np.sqrt(np.clip(np.diag(gram_inv), 0, None) * noise_var)


def statistics_reduced(red, x: np.ndarray, weights: np.ndarray) -> dict:
    """:func:`statistics` on a reduced problem (:mod:`urident.ident.reduced`)."""
    ss = red.residual_sq(x)
    dof = max(6 * red.n_samples - red.n_params, 1)
    noise_var = float(np.asarray(weights, float) ** 2 @ ss / dof)
    r, _ = red.combined(weights)
    n = red.n_samples
    return {"sigma": sigma_from_factor(r, noise_var), "noise_var": noise_var,
            "train_rms": np.sqrt(ss / n), "train_e_n": float(np.sqrt(ss.sum()) / n)}


def joint_weights_reduced(red, x: np.ndarray) -> np.ndarray:
    """:func:`joint_weights` on a reduced problem."""
    std = np.sqrt(red.residual_sq(x) / red.n_samples)
    std = np.maximum(std, 1e-9 * max(std.max(), 1e-300))
    return 1.0 / std
