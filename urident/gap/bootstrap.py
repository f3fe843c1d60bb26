"""Block bootstrap over time of per-sample quantities (the residual is correlated in time, so
samples are resampled in contiguous blocks)."""

from __future__ import annotations

import numpy as np


def default_block_length(n: int, rate_hz: float) -> int:
    """About one second of samples, and at least n/50 (at most 50 blocks... at least 10)."""
    return int(max(min(max(rate_hz, 1.0), n / 10), n / 50, 1))


def block_edges(n: int, block_length: int) -> np.ndarray:
    """Edges of the non-overlapping blocks of about ``block_length`` samples over n samples."""
    L = max(int(block_length), 1)
    return np.linspace(0, n, max(n // L, 1) + 1).astype(int)


def block_bootstrap_means(d: np.ndarray, block_length: int, n_boot: int = 1000,
                          seed: int = 0) -> np.ndarray:
    """Bootstrap distribution (n_boot, m) of the mean of each column of ``d`` (N, m) [or (N,)],
    resampling the same non-overlapping blocks of ``block_length`` samples for every column."""
    d = np.asarray(d, float)
    squeeze = d.ndim == 1
    if squeeze:
        d = d[:, None]
    edges = block_edges(d.shape[0], block_length)
    sums = np.add.reduceat(d, edges[:-1], axis=0)           # (M, m)
    means = bootstrap_block_sums(sums, np.diff(edges).astype(float), n_boot, seed)
    return means[:, 0] if squeeze else means


def bootstrap_block_sums(sums: np.ndarray, counts: np.ndarray, n_boot: int = 1000,
                         seed: int = 0) -> np.ndarray:
    """The same bootstrap from the blocks' sums (M, m) and sample counts (M,): what
    :func:`block_bootstrap_means` reduces its samples to (the scorer keeps only these)."""
    m_blocks = sums.shape[0]
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, m_blocks, size=(n_boot, m_blocks))
    return sums[idx].sum(axis=1) / counts[idx].sum(axis=1)[:, None]


def interval(samples: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    a = (1.0 - level) / 2.0
    lo, hi = np.quantile(np.asarray(samples, float), [a, 1.0 - a])
    return float(lo), float(hi)
