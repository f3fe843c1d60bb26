"""Least-squares problems reduced to small triangular factors, built chunk by chunk (bounded memory).

Per joint j, the R factor of the augmented matrix [Θ_j | Y_j] (the rows 6k + j of the stacked
regressor and ``k`` torque columns) is accumulated by a tall-skinny QR: each chunk of rows is
stacked under the current factor and factored again (``numpy.linalg.qr``, Householder). Since
[Θ_j | Y_j] = Q_j R_j with Q_j orthonormal, ‖Θ_j x − Y_j c‖ = ‖R_j [x; −c]‖ exactly for every x and
c: least squares (any per-joint weighting), bounds, the consistent SDP, σ, training RMS, e_N and
held-out errors all follow from the six (n + k)² factors, whatever the number of samples. A QR is
backward stable like a QR of the whole matrix; normal equations would square the condition number
(the full base set of the paper's model is ill-conditioned enough for that to show).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.blas import one_blas_thread
from urident.errors import ConfigError


def triangle(a: np.ndarray, n_cols: int) -> np.ndarray:
    """The (n_cols, n_cols) R factor of ``a`` (zero rows added while ``a`` has fewer rows)."""
    with one_blas_thread():
        r = np.linalg.qr(a, mode="r")
    if r.shape[0] < n_cols:   # fewer rows than columns so far
        r = np.vstack([r, np.zeros((n_cols - r.shape[0], n_cols))])
    return r


@dataclass(frozen=True)
class ReducedLS:
    """Six per-joint factors ``r (6, n + k, n + k)`` of [Θ_j | Y_j] over ``n_samples`` samples."""

    r: np.ndarray
    n_samples: int
    n_params: int

    @property
    def n_targets(self) -> int:
        return self.r.shape[1] - self.n_params

    def residual_sq(self, x: np.ndarray, target: int = 0) -> np.ndarray:
        """(6,) per-joint Σ_k (Θ x − y)² against torque column ``target`` (unweighted)."""
        v = np.zeros(self.r.shape[1])
        v[:self.n_params] = x
        v[self.n_params + target] = -1.0
        e = self.r @ v
        return np.sum(e * e, axis=1)

    def column_norms(self, weights: np.ndarray) -> np.ndarray:
        """(n,) norms of the regressor's columns with the rows of joint j scaled by weights[j]."""
        w2 = np.asarray(weights, float) ** 2
        sq = np.sum(self.r[:, :, :self.n_params] ** 2, axis=1)
        return np.sqrt(w2 @ sq)

    def combined(self, weights: np.ndarray, target: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(R (n, n), z (n,)) with ‖diag(rw)(Θ x − y)‖² = ‖R x − z‖² + const (rows of joint j
        weighted by weights[j])."""
        n = self.n_params
        cols = np.r_[np.arange(n), n + target]
        stacked = np.vstack([w * rj[:, cols] for w, rj in zip(np.asarray(weights, float), self.r)])
        r = triangle(stacked, n + 1)
        return r[:n, :n], r[:n, n]

    def select(self, target: int) -> "ReducedLS":
        """The same problem with only torque column ``target``."""
        n = self.n_params
        cols = np.r_[np.arange(n), n + target]
        r = np.stack([triangle(rj[:, cols], n + 1) for rj in self.r])
        return ReducedLS(r, self.n_samples, n)


def merge(parts) -> ReducedLS:
    """One factor for the union of the rows of several (e.g. the training folds of a CV)."""
    parts = list(parts)
    if not parts:
        raise ValueError("nothing to merge")
    m = parts[0].r.shape[1]
    r = np.stack([triangle(np.vstack([p.r[j] for p in parts]), m) for j in range(6)])
    return ReducedLS(r, sum(p.n_samples for p in parts), parts[0].n_params)


class Accumulator:
    """Builds a :class:`ReducedLS` from chunks of (m, 6, n) regressor blocks and (m, 6, k) torques."""

    def __init__(self) -> None:
        self._r: list[np.ndarray] | None = None
        self.n_samples = 0
        self.n_params = 0

    def add(self, blocks: np.ndarray, targets: np.ndarray) -> None:
        blocks = np.asarray(blocks, float)
        targets = np.asarray(targets, float).reshape(blocks.shape[0], 6, -1)
        if not (np.all(np.isfinite(blocks)) and np.all(np.isfinite(targets))):
            raise ConfigError("regressor or torques hold NaN/inf")
        if self._r is None:
            self.n_params = blocks.shape[2]
            self._r = [np.zeros((0, blocks.shape[2] + targets.shape[2]))] * 6
        m = self._r[0].shape[1]
        for j in range(6):
            a = np.hstack([blocks[:, j, :], targets[:, j, :]])
            self._r[j] = triangle(np.vstack([self._r[j], a]), m)
        self.n_samples += blocks.shape[0]

    def result(self) -> ReducedLS:
        if self._r is None:
            raise ConfigError("no samples to identify from")
        return ReducedLS(np.stack(self._r), self.n_samples, self.n_params)


def reduce_design(spec, model, data, targets=None, chunk: int | None = None, design=None) -> ReducedLS:
    """The reduced identification problem of prepared ``data`` under ``model``, its regressor built
    :data:`urident.ident.design.CHUNK_SAMPLES` samples at a time. ``targets``: (N, 6, k) torque
    columns (default ``data.tau``)."""
    return reduce_blocks(spec, model, data, [0, len(data)], targets, chunk, design)[0]


def reduce_blocks(spec, model, data, edges, targets=None, chunk: int | None = None,
                  design=None) -> list[ReducedLS]:
    """One reduced problem per block [edges[i], edges[i + 1]) of samples (contiguous blocks of a
    cross-validation), from one pass over the whole sequence (friction states run through the
    block boundaries, as in the whole regressor). ``design``: that pass already made, the
    ``(start, stop, blocks)`` of :func:`urident.ident.design.design_chunks` (a caller that keeps
    them for other uses)."""
    from urident.ident.design import CHUNK_SAMPLES, design_chunks

    from urident.progress import Progress

    y = data.tau[:, :, None] if targets is None else np.asarray(targets, float)
    edges = [int(e) for e in edges]
    accs = [Accumulator() for _ in edges[:-1]]
    with Progress("identification: regressor (samples)", len(data)) as progress:
        if design is None:
            design = design_chunks(spec, model, data.q, data.qd, data.qdd, data.segment, data.t,
                                   chunk or CHUNK_SAMPLES, getattr(data, "temperature", None))
        for a, b, blocks in design:
            for i, acc in enumerate(accs):
                lo, hi = max(a, edges[i]), min(b, edges[i + 1])
                if lo < hi:
                    acc.add(blocks[lo - a:hi - a], y[lo:hi])
            progress.advance(b - a)
    return [acc.result() for acc in accs]


def from_stacked(w: np.ndarray, y: np.ndarray) -> ReducedLS:
    """The reduced form of an in-memory stacked (6N, n) regressor and (6N,) torques."""
    acc = Accumulator()
    acc.add(w.reshape(-1, 6, w.shape[1]), y.reshape(-1, 6, 1))
    return acc.result()
