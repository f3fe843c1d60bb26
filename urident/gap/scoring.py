"""Fitting candidate columns and scoring them on held-out data.

Identification mode (Frisch–Waugh–Lovell): with W the baseline's design matrix on the
identification set and C a candidate's columns there, G = W⁺C and F = C − W·G are the columns
with the base parameters' share removed; regressing the baseline residual on F gives the
candidate's coefficient β of the *joint* refit [W C] (the base parameters move by −G·β). On any
other set the prediction changes by (C' − W'·G)·β. Several candidates are fitted jointly by
stacking their F.

CV mode: the baseline (and the identification-mode candidates already fitted) stay fixed; the
candidate's columns are fitted to the remaining validation residual on K − 1 contiguous time
blocks and predict the held-out block; every validation sample gets an out-of-fold prediction.
For use on other data the coefficients fitted on all validation samples are kept.

No fit forms a (6N, ·) matrix: G, the Gram matrices of F and every validation residual's squared
sums per bootstrap block and CV fold come from the statistics of :mod:`.stats`, built once per set
of candidates (the diagnosis' pool); per-sample residuals are recomputed only when asked for
(:attr:`Fit.residual`, :meth:`Fit.change`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from urident.gap.candidates import Candidate
from urident.gap.bootstrap import block_edges, default_block_length
from urident.gap.residual import SetContext
from urident.gap.stats import IdentFactors, IdentStats, ValidStats, joint_parts


def lstsq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares through the (column-scaled) normal equations: x has few columns."""
    return lstsq_gram(x.T @ x, x.T @ y)


def lstsq_gram(gram: np.ndarray, xty: np.ndarray) -> np.ndarray:
    """:func:`lstsq` from the Gram matrix xᵀx and xᵀy."""
    scale = np.sqrt(np.maximum(np.diag(gram), 0.0))
    ok = scale > 0
    beta = np.zeros(gram.shape[0])
    if ok.any():
        s = scale[ok]
        a = gram[np.ix_(ok, ok)] / np.outer(s, s)
        b, *_ = np.linalg.lstsq(a, xty[ok] / s, rcond=1e-10)
        beta[ok] = b / s
    return beta


def _ss_after(gram: np.ndarray, xty: np.ndarray, yy: float) -> tuple[np.ndarray, float]:
    """(β, ‖y − xβ‖²) of the least-squares fit from its Gram statistics."""
    beta = lstsq_gram(gram, xty)
    return beta, float(yy - 2.0 * beta @ xty + beta @ gram @ beta)


class _Stats:
    """Both sets' statistics for one set of candidates (see :mod:`.stats`)."""

    def __init__(self, scorer: "Scorer", cands: Sequence[Candidate], block: int):
        self.cands = list(dict.fromkeys(cands))
        self.members = set(self.cands)
        self.block = block
        ident = [c for c in self.cands if c.mode == "ident"]
        self.ident = IdentStats(scorer.ident, ident, scorer._factors) if ident else None
        self.valid = ValidStats(scorer.valid, self.cands, bool(ident), scorer.fold,
                                block_edges(scorer.valid.n, block))
        if ident:
            self.valid.project({c: self.ident.g_of(c) for c in ident})
        self.valid.finish()


@dataclass(eq=False)
class Fit:
    """A set of candidates fitted together; ``residual`` is the validation residual after them
    (out-of-fold for the CV-mode ones), recomputed from the coefficients when first asked for.
    ``u`` (S, D): per cell of ``stats`` the residual's coefficients on its columns."""

    ident: list[Candidate]
    beta_ident: np.ndarray
    cv: list[Candidate]
    beta_cv: np.ndarray                  # fitted on all validation samples
    g: dict = field(default_factory=dict, repr=False)   # candidate → G (p, k)
    stats: object = field(default=None, repr=False)
    u: np.ndarray | None = field(default=None, repr=False)
    beta_folds: np.ndarray | None = field(default=None, repr=False)   # (K, k_cv)
    scorer: object = field(default=None, repr=False)
    _residual: np.ndarray | None = field(default=None, repr=False)

    def coefficients(self) -> dict[Candidate, np.ndarray]:
        out, i = {}, 0
        for c in self.ident:
            out[c] = self.beta_ident[i:i + c.k]
            i += c.k
        i = 0
        for c in self.cv:
            out[c] = self.beta_cv[i:i + c.k]
            i += c.k
        return out

    def _ident_change(self, ctx: SetContext) -> np.ndarray:
        out = np.zeros((ctx.n, 6))
        if not self.ident:
            return out
        coef = self.coefficients()
        g = sum(self.g[c] @ coef[c] for c in self.ident)
        out -= ctx.design_product(g)
        for c in self.ident:
            out += c.features(ctx) @ coef[c]
        return out

    @property
    def residual(self) -> np.ndarray:
        """(N, 6) validation residual after the candidates."""
        if self._residual is None:
            v = self.scorer.valid
            r = v.residual - self._ident_change(v)
            if self.cv:
                fold = self.scorer.fold
                pred = np.zeros_like(r)
                for c, sl in zip(self.cv, _slices(self.cv)):
                    f = c.features(v)
                    for b in range(self.scorer.n_folds):
                        rows = fold == b
                        pred[rows] += f[rows] @ self.beta_folds[b, sl]
                r = r - pred
            self._residual = r
        return self._residual

    def change(self, ctx: SetContext) -> np.ndarray:
        """(N, 6) change of the predicted torque on another set ``ctx`` (same baseline)."""
        out = self._ident_change(ctx)
        coef = self.coefficients()
        for c in self.cv:
            out += c.features(ctx) @ coef[c]
        return out


def _slices(cands) -> list[slice]:
    out, i = [], 0
    for c in cands:
        out.append(slice(i, i + c.k))
        i += c.k
    return out


class Scorer:
    """Fits and scores candidates for one (identification, validation) pair. ``block``: the
    bootstrap block length the statistics are cut for (default about one second)."""

    def __init__(self, ident: SetContext, valid: SetContext, n_folds: int = 5, block: int | None = None):
        self.ident, self.valid = ident, valid
        n = valid.n
        self.n_folds = int(max(2, min(n_folds, n // 20)))
        self.fold = np.minimum((np.arange(n) * self.n_folds) // n, self.n_folds - 1)
        self.block = block or default_block_length(n, valid.data.sample_rate)
        self._factors: IdentFactors | None = None   # identification-mode candidates' R factors
        self._stats: _Stats | None = None
        self._gains: dict[Candidate, float] = {}
        self._betas: dict[Candidate, np.ndarray] = {}   # identification-mode training coefficients

    # ------------------------------------------------------------- statistics
    def prepare(self, cands: Sequence[Candidate], block: int | None = None) -> None:
        """Build the statistics of ``cands`` (the pool) once; later fits among them are cheap."""
        self._stats = _Stats(self, cands, block or self.block)

    def stats_for(self, cands: Sequence[Candidate], block: int | None = None, keep: bool = False) -> _Stats:
        """Statistics covering ``cands``: the kept ones when they do, else new ones (kept as the
        scorer's own with ``keep``: a pool about to be scored)."""
        block = block or self.block
        st = self._stats
        if st is not None and st.block == block and all(c in st.members for c in cands):
            return st
        new = _Stats(self, cands, block)
        if keep:
            self._stats = new
        return new

    def g(self, c: Candidate) -> np.ndarray:
        """G = W⁺C of an identification-mode candidate."""
        st = self.stats_for([c])
        return st.ident.g_of(c)

    def ident_ss(self, cands: Sequence[Candidate]) -> float:
        """Squared identification residual after refitting identification-mode ``cands`` jointly."""
        cands = [c for c in cands if c.mode == "ident"]
        if not cands:
            return float(np.sum(self.ident.residual ** 2))
        st = self.stats_for(cands).ident
        i = st.cols(cands)
        return _ss_after(st.gram[np.ix_(i, i)], st.fty[i], st.yy)[1]

    # ------------------------------------------------------------- variant choice
    def prepare_gains(self, families: Sequence[Sequence[Candidate]]) -> None:
        """One pass over the identification set for every identification-mode candidate of
        ``families`` (their R factors, :class:`~urident.gap.stats.IdentFactors`), and
        :meth:`training_gain` of every variant of the families with more than one."""
        ident = [c for fam in families for c in fam if c.mode == "ident"]
        if ident:
            self._factors = IdentFactors(self.ident, ident)
        for fam in families:
            if len(fam) > 1:
                for c in fam:
                    self.training_gain(c)

    def _cv_fit(self, c: Candidate, y: np.ndarray) -> tuple[float, np.ndarray]:
        """Reduction of the validation residual ``y``'s sum of squares by ``c`` alone, and its
        coefficients."""
        gram = np.zeros((c.k, c.k))
        xty = np.zeros(c.k)
        for j, x in joint_parts(c, self.valid):
            gram += x.T @ x
            xty += x.T @ y[:, j]
        beta = lstsq_gram(gram, xty)
        return float(2.0 * beta @ xty - beta @ gram @ beta), beta

    def _cv_gain(self, c: Candidate) -> float:
        gain, self._betas[c] = self._cv_fit(c, self.valid.residual)
        return gain

    def training_gain(self, c: Candidate) -> float:
        """Reduction of the fitting data's squared residual by ``c`` alone (choice of variant),
        to 12 significant digits: variants equal after the projection (e.g. temperature offsets
        that differ by a constant, absorbed by the viscous and Coulomb columns) tie, and the
        first one is kept, whatever the rounding."""
        if c not in self._gains:
            if c.mode == "ident":
                st = IdentStats(self.ident, [c], self._factors)
                beta = lstsq_gram(st.gram, st.fty)
                gain = float(2.0 * beta @ st.fty - beta @ st.gram @ beta)
                self._betas[c] = beta
            else:
                gain = self._cv_gain(c)
            self._gains[c] = float(f"{gain:.12g}")
        return self._gains[c]

    def gains_on_top(self, selected: Sequence[Candidate], current: "Fit", variants: Sequence[Candidate]) -> list[float]:
        """:meth:`training_gain` of each of ``variants`` on top of the ``selected`` candidates
        (``current``: their fit): in identification mode refitted jointly with the selected
        identification-mode ones, in CV mode on the validation residual they leave."""
        chosen = [c for c in selected if c.mode == "ident"]
        ident = [c for c in variants if c.mode == "ident"]
        if ident:
            st = IdentStats(self.ident, chosen + ident, self._factors)
            i0 = st.cols(chosen) if chosen else np.zeros(0, int)
            ss0 = _ss_after(st.gram[np.ix_(i0, i0)], st.fty[i0], st.yy)[1] if chosen else st.yy
        y = current.residual
        out = []
        for c in variants:
            if c.mode == "ident":
                i = st.cols(chosen + [c])
                out.append(ss0 - _ss_after(st.gram[np.ix_(i, i)], st.fty[i], st.yy)[1])
                continue
            out.append(self._cv_fit(c, y)[0])
        return out

    def training_beta(self, c: Candidate) -> np.ndarray | None:
        """The coefficients behind :meth:`training_gain`."""
        self.training_gain(c)
        return self._betas.get(c)

    # ------------------------------------------------------------- evaluation
    def evaluate(self, selection: Sequence[Candidate], stats: _Stats | None = None) -> Fit:
        ident = [c for c in selection if c.mode == "ident"]
        cv = [c for c in selection if c.mode == "cv"]
        st = stats if stats is not None else self.stats_for(list(selection))
        vs = st.valid
        u0 = vs.unit_residual()
        beta_i = np.zeros(0)
        g = {}
        if ident:
            i = st.ident.cols(ident)
            beta_i = lstsq_gram(st.ident.gram[np.ix_(i, i)], st.ident.fty[i])
            for c, sl in zip(ident, _slices(ident)):
                g[c] = st.ident.g_of(c)
                u0[vs.slices[c]] -= beta_i[sl]          # the projected columns F' = C' − W'·G
        u = np.tile(u0, (len(vs.cells) - 1, 1))
        beta_c = np.zeros(0)
        folds = None
        if cv:
            k = vs.cols(cv)
            folds = np.zeros((self.n_folds, len(k)))
            for b in range(self.n_folds):
                train = vs.cell_fold != b
                m = vs.train_gram(b)
                folds[b] = lstsq_gram(m[np.ix_(k, k)], m[k] @ u0)
                u[np.ix_(~train, k)] -= folds[b]
            beta_c = lstsq_gram(vs.m_total[np.ix_(k, k)], vs.m_total[k] @ u0)
        return Fit(ident, beta_i, cv, beta_c, g, st, u, folds, self)
