"""Base parameters (paper section III-D): the identifiable linear combinations of the standard
parameters, found numerically from the regressor.

The rank b comes from a QR decomposition with column pivoting of a regressor stacked over random
states. The b independent columns are then chosen greedily in the parameter vector's own order
(body 1 → 6, then rotors, then friction), which reproduces the structure of the paper's eq. (42)
and (45): each base parameter is one standard parameter plus the dependent ones regrouped into it,
e.g. ``B3 + 0.1539 m4 + 0.1539 m5 + 0.1539 m6``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from urident.model.parameters import BODY_FIELDS, DRIVE, N_PARAMS, body_slice, parameter_names
from urident.model.regressor import regressor
from urident.model.robot import RobotSpec

# The paper's reduced model (section IV-B): no products of inertia; body 1 only C1; each centre of
# mass on one axis of its joint frame (K2z, K3z, K4y, K5z, K6y).
PAPER_COM_AXES = {2: "z", 3: "z", 4: "y", 5: "z", 6: "y"}
RANK_TOL = 1e-8


@dataclass(frozen=True)
class BaseParameters:
    """``p_B = combination @ p`` and ``Θ p = Θ[:, independent] p_B`` for every admissible p."""

    robot: str
    reduced: bool
    modelled: np.ndarray      # indices of the standard parameters in the model (78 or fewer)
    independent: np.ndarray   # (b,) standard-parameter index each base parameter is named after
    combination: np.ndarray   # (b, 78)
    names: tuple[str, ...]    # base parameter names (the representative's name)

    @property
    def n_base(self) -> int:
        return len(self.independent)

    def from_standard(self, params: np.ndarray) -> np.ndarray:
        """Base parameters of a standard 78-vector (unmodelled entries are ignored)."""
        return self.combination @ np.asarray(params, dtype=float)

    def columns(self, stacked_regressor: np.ndarray) -> np.ndarray:
        """Θ_B from a stacked (…, 78) regressor."""
        return stacked_regressor[..., self.independent]

    def expressions(self, digits: int = 4) -> list[str]:
        """Readable expression of each base parameter, e.g. ``B3 + 0.1539 m4 + 0.1539 m5``."""
        names = parameter_names()
        out = []
        for k, row in enumerate(self.combination):
            rep = self.independent[k]
            terms = [(rep, row[rep])] + [(j, row[j]) for j in np.flatnonzero(row) if j != rep]
            text = ""
            for j, coef in terms:
                if abs(coef) < 10.0 ** -(digits + 4):
                    continue
                magnitude = abs(coef)
                factor = "" if np.isclose(magnitude, 1.0, rtol=1e-9) else f"{magnitude:.{digits}g} "
                sign = "-" if coef < 0 else "+"
                if not text:
                    text = ("-" if coef < 0 else "") + factor + names[j]
                else:
                    text += f" {sign} {factor}{names[j]}"
            out.append(text)
        return out


def modelled_parameters(reduced: bool) -> np.ndarray:
    """Indices of the standard parameters in the full (78) or the paper's reduced model."""
    if not reduced:
        return np.arange(N_PARAMS)
    keep = [BODY_FIELDS.index("C")]  # body 1: only the axial inertia C1
    for body, axis in PAPER_COM_AXES.items():
        first = body_slice(body - 1).start
        for name in ("m", f"mr{axis}", "A", "B", "C"):
            keep.append(first + BODY_FIELDS.index(name))
    keep += list(range(DRIVE.start, DRIVE.stop))
    return np.array(sorted(keep))


def random_states(spec: RobotSpec, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    q = rng.uniform(np.maximum(spec.q_min, -np.pi), np.minimum(spec.q_max, np.pi), size=(n, 6))
    qd = rng.uniform(-1.0, 1.0, size=(n, 6)) * spec.qd_max
    qdd = rng.uniform(-1.0, 1.0, size=(n, 6)) * spec.qdd_max
    return q, qd, qdd


def base_parameters(spec: RobotSpec, reduced: bool = False, n_samples: int = 300,
                    seed: int = 0) -> BaseParameters:
    """Base parameters of ``spec``'s full (78) or the paper's reduced model."""
    rng = np.random.default_rng(seed)
    w = regressor(spec, *random_states(spec, n_samples, rng))
    modelled = modelled_parameters(reduced)
    wm = w[:, modelled]
    norms = np.linalg.norm(wm, axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    r = scipy.linalg.qr(wm / scale, mode="r", pivoting=True)[0]
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > RANK_TOL * diag[0]))

    # Greedy choice in parameter order: keep a column if it adds to the span of those kept.
    basis = np.zeros((wm.shape[0], 0))
    chosen: list[int] = []
    for k in range(wm.shape[1]):
        if norms[k] == 0:
            continue
        v = wm[:, k] / norms[k]
        for _ in range(2):  # re-orthogonalise once for accuracy
            v = v - basis @ (basis.T @ v)
        if np.linalg.norm(v) > 1e-6:
            basis = np.column_stack([basis, v / np.linalg.norm(v)])
            chosen.append(k)
    if len(chosen) != rank:
        raise RuntimeError(f"base parameter selection found {len(chosen)} columns, QR rank is {rank}")

    independent_local = np.array(chosen)
    dependent_local = np.array([k for k in range(wm.shape[1]) if k not in set(chosen)], dtype=int)
    w_ind = wm[:, independent_local]
    beta = np.linalg.lstsq(w_ind, wm[:, dependent_local], rcond=None)[0] if len(dependent_local) else None
    combination = np.zeros((rank, N_PARAMS))
    combination[np.arange(rank), modelled[independent_local]] = 1.0
    if beta is not None:
        beta[np.abs(beta) < 1e-10] = 0.0
        combination[:, modelled[dependent_local]] = beta
        residual = np.abs(w_ind @ beta - wm[:, dependent_local]).max()
        if residual > 1e-6 * max(1.0, np.abs(wm).max()):
            raise RuntimeError(f"base parameter regrouping is inexact (residual {residual:.3g})")
    names = parameter_names()
    independent = modelled[independent_local]
    return BaseParameters(spec.name, reduced, modelled, independent, combination,
                          tuple(names[j] for j in independent))
