"""Excitation criteria of the information matrix (paper section III-E).

Θ̄_B is the base regressor stacked over the samples. Its columns carry different units (kg, kg·m,
kg·m², N·m·s/rad, N·m), so its raw condition number depends on the choice of units. The criterion
therefore scales each column by a fixed reference: its RMS over random states spanning the robot's
joint range, velocity and acceleration limits (:func:`reference_scales`, deterministic). Unlike
scaling by the trajectory's own column norms, this keeps the absolute excitation level in the
criterion: a joint that barely moves leaves its friction columns small and the cond large.

* ``cond_theta``  = cond(Θ̄_B S⁻¹) = σ_max/σ_min, S = diag(reference scales),
* ``cond_lambda`` = cond(Λ), Λ = (Θ̄_B S⁻¹)ᵀ(Θ̄_B S⁻¹) (the paper's eq. 23) = cond_theta²,
* ``logdet``      = log det(Λ / m) (D-optimality; a column scaling only adds a constant to it),
* ``cond_theta_equilibrated`` (columns scaled by their own norms) and ``cond_theta_raw`` (SI
  units), for reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.model.base import BaseParameters, random_states
from urident.model.parameters import N_PARAMS
from urident.model.regressor import DEFAULT_FRICTION_EPS, regressor_blocks
from urident.model.robot import RobotSpec

CRITERIA = ("cond", "logdet")


@dataclass(frozen=True)
class CriterionValues:
    cond_theta: float       # cond of Θ̄_B with reference-scaled columns
    cond_lambda: float      # cond of Λ = Θ̄_Bᵀ Θ̄_B (reference-scaled) = cond_theta²
    logdet: float           # log det(Λ / m), reference-scaled
    cond_theta_equilibrated: float  # cond of Θ̄_B with each column scaled by its own norm
    cond_theta_raw: float   # cond of the raw Θ̄_B (SI units)
    n_samples: int
    n_base: int

    def as_dict(self) -> dict[str, float]:
        return {"cond_theta": self.cond_theta, "cond_lambda": self.cond_lambda,
                "logdet_lambda": self.logdet, "cond_theta_equilibrated": self.cond_theta_equilibrated,
                "cond_theta_raw": self.cond_theta_raw, "n_samples": self.n_samples,
                "n_base": self.n_base}


def base_regressor(spec: RobotSpec, base: BaseParameters, q: np.ndarray, qd: np.ndarray,
                   qdd: np.ndarray, friction_eps: float = DEFAULT_FRICTION_EPS) -> np.ndarray:
    """Θ̄_B (6N, b) for (N, 6) samples."""
    return base.columns(regressor_blocks(spec, q, qd, qdd, friction_eps).reshape(-1, N_PARAMS))


_SCALE_CACHE: dict[tuple, np.ndarray] = {}
REFERENCE_SAMPLES = 2000


def reference_scales(spec: RobotSpec, base: BaseParameters) -> np.ndarray:
    """(b,) root of the mean (per sample, summed over joints) square of each base regressor column
    over random states (q over the joint range clipped
    to ±π, |q̇| ≤ q̇_max, |q̈| ≤ q̈_max; fixed seed)."""
    key = (spec.name, str(spec.source), base.reduced, base.independent.tobytes())
    if key not in _SCALE_CACHE:
        states = random_states(spec, REFERENCE_SAMPLES, np.random.default_rng(0))
        w = base_regressor(spec, base, *states)
        _SCALE_CACHE[key] = np.sqrt(np.sum(w ** 2, axis=0) / REFERENCE_SAMPLES)
    return _SCALE_CACHE[key].copy()


def gram_criteria(gram: np.ndarray, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """log cond(Λ) and log det(Λ) of Λ = S⁻¹ G S⁻¹, batched: ``gram`` (..., b, b) = Θ̄_Bᵀ Θ̄_B / m,
    ``scales`` (b,) → two arrays (...)."""
    inv = 1.0 / scales
    lam = gram * inv[:, None] * inv[None, :]
    eig = np.linalg.eigvalsh(lam)
    log_cond = np.log(np.maximum(eig[..., -1], 1e-300)) - np.log(np.maximum(eig[..., 0], 1e-300))
    sign, logdet = np.linalg.slogdet(lam)
    logdet = np.where(sign > 0, logdet, -np.inf)
    return log_cond, logdet


def evaluate_criteria(spec: RobotSpec, base: BaseParameters, q: np.ndarray, qd: np.ndarray,
                      qdd: np.ndarray) -> CriterionValues:
    """All criteria of the samples (N, 6) (singular values from SVDs, not the Gram matrix)."""
    w = base_regressor(spec, base, q, qd, qdd)
    m = q.shape[0]

    def cond(matrix: np.ndarray) -> tuple[float, np.ndarray]:
        sv = np.linalg.svd(matrix, compute_uv=False)
        return (float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")), sv

    scaled_cond, sv = cond(w / reference_scales(spec, base))
    norms = np.linalg.norm(w, axis=0)
    eq_cond, _ = cond(w / np.where(norms > 0, norms, 1.0))
    raw_cond, _ = cond(w)
    logdet = float(2.0 * np.sum(np.log(sv)) - len(sv) * np.log(m)) if sv[-1] > 0 else float("-inf")
    return CriterionValues(scaled_cond, scaled_cond ** 2, logdet, eq_cond, raw_cond, m, base.n_base)
