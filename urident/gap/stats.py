"""The candidate fits' sufficient statistics, built in one pass over each set (bounded memory).

Every fit the scorer makes is linear in a few columns per joint, so it needs no (6N, ·) matrix:

* identification set (:class:`IdentStats`): per joint the R factor of [W_j | C_j | r_j] (baseline
  design rows of joint j, the identification-mode candidates' columns there, the baseline
  residual) by tall-skinny QR (:mod:`urident.ident.reduced`), merged over the joints into the R
  factor of [W | C | r]. With R = [[R11, R12, R1r], [0, R22, R2r], [0, 0, ρ]]: G = W⁺C =
  R11⁻¹R12, the projected columns F = C − W·G have Gram R22ᵀR22 and Fᵀr = R22ᵀR2r (Frisch–
  Waugh–Lovell without forming Q or F);
* validation set (:class:`ValidStats`): per *cell* (the intersection of a bootstrap block and a CV
  fold) and joint the Gram matrix of [C' | W' | r0] (candidate columns, design rows, baseline
  residual). A residual that is X·u on each cell has per-cell, per-joint squared sums uᵀMu: held-
  out gains, their block bootstrap (block sums), RMS before and after, corrections' RMS and
  correlations all follow from these (S, 6, D, D) numbers.

Per-sample series (a finding's improvement map, the final residual) are recomputed on demand from
the coefficients (:class:`urident.gap.scoring.Fit`), the candidate columns and the design rows
streamed in chunks.
"""

from __future__ import annotations

import numpy as np

from urident.blas import one_blas_thread
from urident.ident.reduced import triangle


def touched(f: np.ndarray) -> np.ndarray:
    """0-based joints whose rows of candidate columns ``f`` (N, 6, k) are not all zero."""
    return np.flatnonzero(np.any(f != 0, axis=(0, 2)))


def joint_parts(c, ctx) -> list[tuple[int, np.ndarray]]:
    """(joint, its (N, k) rows) for each joint whose rows of candidate ``c``'s columns on ``ctx``
    are not all zero (:func:`touched`)."""
    x = c.joint_columns(ctx)
    if x is not None:
        return [(c.joint, x)] if np.any(x != 0) else []
    f = c.features(ctx)
    return [(int(j), f[:, j, :].copy()) for j in touched(f)]   # copies: the (N, 6, k) array is freed


def _compact(cands, ctx, first_col: int = 0):
    """Per joint: the candidate columns on its rows (N, K_j) and their global column indices;
    ``slices``: each candidate's columns in the global layout starting at ``first_col``."""
    parts = {j: [] for j in range(6)}
    index = {j: [] for j in range(6)}
    slices, col = {}, first_col
    for c in cands:
        slices[c] = slice(col, col + c.k)
        for j, x in joint_parts(c, ctx):
            parts[j].append(x)
            index[j].append(np.arange(col, col + c.k))
        col += c.k
    cols = {}
    for j in range(6):
        cols[j] = np.hstack(parts[j]) if parts[j] else None
        parts[j] = None
    idx = {j: (np.concatenate(index[j]) if index[j] else np.zeros(0, int)) for j in range(6)}
    return cols, idx, slices, col


class IdentFactors:
    """Per joint the R factor of [W_j | C_j | r_j] for identification-mode candidates ``cands``
    (one pass over the set): the :class:`IdentStats` of any subset of them follow without
    another pass (a column subset of Q·R is Q times the same columns of R)."""

    def __init__(self, ctx, cands):
        self.cands = list(cands)
        self.p = p = ctx.n_params
        slices, col = {}, p
        for c in self.cands:
            slices[c] = slice(col, col + c.k)
            col += c.k
        r = ctx.residual
        fac, idx = {}, {}
        later: dict[int, dict[int, np.ndarray]] = {j: {} for j in range(6)}   # multi-joint rows kept
        with one_blas_thread():
            # one joint at a time, so only its candidate columns are held: the identification-mode
            # pool of a 10-minute set is gigabytes (docs/scale.md); the design is rebuilt per joint
            # unless the set keeps it
            for j in range(6):
                parts, index = [], []
                for i, c in enumerate(self.cands):
                    if c.on_joint is not None:
                        got = joint_parts(c, ctx) if c.joint == j else []
                    elif j == 0:
                        got = []
                        for jj, x in joint_parts(c, ctx):
                            if jj == 0:
                                got.append((jj, x))
                            else:
                                later[jj][i] = x
                    else:
                        got = [(j, later[j].pop(i))] if i in later[j] else []
                    for _, x in got:
                        parts.append(x)
                        index.append(np.arange(slices[c].start, slices[c].stop))
                m = p + sum(x.shape[1] for x in parts) + 1
                f = np.zeros((0, m))
                for a, b, blocks in ctx.chunks():
                    # [current factor; W_j | C_j | r_j of the chunk], filled in place (one copy)
                    top = f.shape[0]
                    x = np.empty((top + b - a, m))
                    x[:top] = f
                    x[top:, :p] = blocks[:, j, :]
                    at = p
                    for part in parts:
                        x[top:, at:at + part.shape[1]] = part[a:b]
                        at += part.shape[1]
                    x[top:, -1] = r[a:b, j]
                    f = triangle(x, m)
                fac[j] = f
                idx[j] = np.concatenate(index) if index else np.zeros(0, int)
                parts = None
        self.factors = fac
        # where each candidate's columns sit in each joint's factor
        self.where = {c: {} for c in self.cands}
        for j in range(6):
            for pos, g in enumerate(idx[j]):
                for c, sl in slices.items():
                    if sl.start <= g < sl.stop:
                        self.where[c].setdefault(j, []).append((g - sl.start, p + pos))
                        break

    def covers(self, cands) -> bool:
        return all(c in self.where for c in cands)


class IdentStats:
    """Identification-mode candidates ``cands`` on the identification set ``ctx`` (module doc),
    from ``factors`` (:class:`IdentFactors` covering them) or one pass of their own."""

    def __init__(self, ctx, cands, factors: IdentFactors | None = None):
        self.cands = list(cands)
        if factors is None or not factors.covers(self.cands):
            factors = IdentFactors(ctx, self.cands)
        p = factors.p
        self.slices, col = {}, p
        for c in self.cands:
            self.slices[c] = slice(col, col + c.k)
            col += c.k
        k = col - p
        total = p + k + 1
        rows = []
        for j in range(6):
            fac = factors.factors[j]
            src = list(range(p))
            dst = list(range(p))
            for c in self.cands:
                for i, pos in factors.where[c].get(j, []):
                    src.append(pos)
                    dst.append(self.slices[c].start + i)
            src.append(fac.shape[1] - 1)
            dst.append(total - 1)
            e = np.zeros((fac.shape[0], total))
            e[:, dst] = fac[:, src]
            rows.append(e)
        rr = triangle(np.vstack(rows), total)
        self.p, self.k = p, k
        from scipy.linalg import solve_triangular

        self.g = solve_triangular(rr[:p, :p], rr[:p, p:p + k]) if k else np.zeros((p, 0))
        r22 = rr[p:p + k, p:p + k]
        self.gram = r22.T @ r22
        self.fty = r22.T @ rr[p:p + k, -1]
        self.yy = float(np.sum(rr[:, -1] ** 2))

    def cols(self, cands) -> np.ndarray:
        """Indices of ``cands``' columns in :attr:`gram` (relative to the candidate block)."""
        if not cands:
            return np.zeros(0, int)
        return np.concatenate([np.arange(self.slices[c].start, self.slices[c].stop) - self.p for c in cands])

    def g_of(self, c) -> np.ndarray:
        s = self.slices[c]
        return self.g[:, s.start - self.p:s.stop - self.p]


class ValidStats:
    """Per-cell, per-joint Gram matrices of [C' | W' | r0] on the validation set (module doc).
    ``cells``: sample edges; ``cell_fold``, ``cell_block``: each cell's CV fold and bootstrap
    block; W' only when ``need_w`` (identification-mode candidates)."""

    def __init__(self, ctx, cands, need_w: bool, fold: np.ndarray, block_edges: np.ndarray):
        self.cands = list(cands)
        n = ctx.n
        fold_edges = np.r_[0, np.flatnonzero(np.diff(fold) != 0) + 1, n]
        self.cells = np.unique(np.r_[fold_edges, block_edges]).astype(int)
        self.cell_fold = fold[self.cells[:-1]]
        self.cell_block = np.searchsorted(block_edges, self.cells[:-1], side="right") - 1
        self.block_counts = np.diff(block_edges).astype(float)
        self.n_blocks = len(block_edges) - 1
        self.n = n
        cols, idx, self.slices, end = _compact(self.cands, ctx, 0)
        self.need_w = need_w
        p = ctx.n_params if need_w else 0
        self.w = slice(end, end + p)
        self.r = end + p
        d = end + p + 1
        self.d = d
        m = np.zeros((len(self.cells) - 1, 6, d, d))
        r0 = ctx.residual
        act = {j: np.r_[idx[j], np.arange(end, end + p), d - 1] for j in range(6)}
        chunks = ctx.chunks() if need_w else ((a, min(a + 8192, n), None) for a in range(0, n, 8192))
        with one_blas_thread():
            self._accumulate(chunks, cols, act, r0, m, need_w)
        self.m = m

    def _accumulate(self, chunks, cols, act, r0, m, need_w) -> None:
        s_count = m.shape[0]
        for a, b, blocks in chunks:
            first = int(np.searchsorted(self.cells, a, side="right") - 1)
            s = first
            while s < s_count and self.cells[s] < b:
                lo, hi = max(a, self.cells[s]), min(b, self.cells[s + 1])
                for j in range(6):
                    parts = [] if cols[j] is None else [cols[j][lo:hi]]
                    if need_w:
                        parts.append(blocks[lo - a:hi - a, j, :])
                    parts.append(r0[lo:hi, j, None])
                    x = np.hstack(parts)
                    m[s, j][np.ix_(act[j], act[j])] += x.T @ x
                s += 1

    def project(self, g: dict) -> None:
        """Replace the design columns W' by the identification-mode candidates' projected columns
        F' = C' − W'·G (``g``: candidate → G): fits then need only the candidates' columns."""
        d = self.r + 1
        keep = np.r_[np.arange(self.w.start), self.r]
        t = np.zeros((d, len(keep)))
        t[keep, np.arange(len(keep))] = 1.0
        for c, gc in g.items():
            t[self.w, self.slices[c]] = -gc
        self.m = np.matmul(np.matmul(t.T, self.m), t)
        self.r = len(keep) - 1
        self.d = len(keep)
        self.w = slice(self.r, self.r)
        self.need_w = False

    def finish(self) -> None:
        self.m_cell = self.m.sum(axis=1)                  # (S, D, D) over joints
        self.m_total = self.m_cell.sum(axis=0)            # (D, D)
        self._train: dict[int, np.ndarray] = {}

    def train_gram(self, fold: int) -> np.ndarray:
        """(D, D) sum of :attr:`m_cell` over the cells outside CV ``fold`` (its training cells),
        once per fold: every CV fit of the pool uses it."""
        m = self._train.get(fold)
        if m is None:
            m = self._train[fold] = self.m_cell[self.cell_fold != fold].sum(axis=0)
        return m

    def cols(self, cands) -> np.ndarray:
        if not cands:
            return np.zeros(0, int)
        return np.concatenate([np.arange(self.slices[c].start, self.slices[c].stop) for c in cands])

    def unit_residual(self) -> np.ndarray:
        u = np.zeros(self.d)
        u[self.r] = 1.0
        return u

    def cell_ss(self, u: np.ndarray) -> np.ndarray:
        """(S, 6) Σ over each cell's samples of the squared series X·u (``u`` (S, D), per cell)."""
        i = np.flatnonzero(np.any(u != 0, axis=0))
        sub = self.m[:, :, i[:, None], i[None, :]]
        ui = u[:, i]
        # a sum of squares through Gram matrices: rounding can leave it a hair below zero
        return np.maximum(np.einsum("sd,sjde,se->sj", ui, sub, ui), 0.0)

    def cross(self, u: np.ndarray, v: np.ndarray) -> float:
        """Σ over all samples and joints of (X·u)·(X·v)."""
        i = np.flatnonzero(np.any(u != 0, axis=0) | np.any(v != 0, axis=0))
        sub = self.m_cell[:, i[:, None], i[None, :]]
        return float(np.einsum("sd,sde,se->", u[:, i], sub, v[:, i]))

    def block_sums(self, x: np.ndarray) -> np.ndarray:
        """(M, ...) sums over the bootstrap blocks of per-cell values ``x`` (S, ...)."""
        out = np.zeros((self.n_blocks,) + x.shape[1:])
        np.add.at(out, self.cell_block, x)
        return out
