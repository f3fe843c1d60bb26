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
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from urident.gap.candidates import Candidate
from urident.gap.residual import SetContext


def lstsq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares through the (column-scaled) normal equations: x has few columns."""
    gram = x.T @ x
    scale = np.sqrt(np.diag(gram))
    ok = scale > 0
    beta = np.zeros(x.shape[1])
    if ok.any():
        s = scale[ok]
        a = gram[np.ix_(ok, ok)] / np.outer(s, s)
        b, *_ = np.linalg.lstsq(a, (x[:, ok].T @ y) / s, rcond=1e-10)
        beta[ok] = b / s
    return beta


@dataclass(eq=False)
class Fit:
    """A set of candidates fitted together; ``residual`` is the validation residual after them
    (out-of-fold for the CV-mode ones)."""

    ident: list[Candidate]
    beta_ident: np.ndarray
    cv: list[Candidate]
    beta_cv: np.ndarray                  # fitted on all validation samples
    residual: np.ndarray                 # (N, 6)
    g: dict = field(default_factory=dict, repr=False)   # candidate → G (p, k)

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

    def change(self, ctx: SetContext) -> np.ndarray:
        """(N, 6) change of the predicted torque on another set ``ctx`` (same baseline)."""
        out = np.zeros((ctx.n, 6))
        coef = self.coefficients()
        for c in self.ident:
            f = c.features(ctx).reshape(-1, c.k) - ctx.w @ self.g[c]
            out += (f @ coef[c]).reshape(-1, 6)
        for c in self.cv:
            out += (c.features(ctx).reshape(-1, c.k) @ coef[c]).reshape(-1, 6)
        return out


class Scorer:
    """Fits and scores candidates for one (identification, validation) pair."""

    def __init__(self, ident: SetContext, valid: SetContext, n_folds: int = 5):
        self.ident, self.valid = ident, valid
        scale = np.linalg.norm(ident.w, axis=0)
        scale[scale == 0] = 1.0
        self._scale = scale
        self._q, self._r = np.linalg.qr(ident.w / scale)
        self.r_ident = ident.residual.reshape(-1)
        self.r_valid = valid.residual
        n = valid.n
        self.n_folds = int(max(2, min(n_folds, n // 20)))
        self.fold = np.minimum((np.arange(n) * self.n_folds) // n, self.n_folds - 1)
        self._g: dict[Candidate, np.ndarray] = {}

    # ------------------------------------------------------------- identification mode
    def g(self, c: Candidate) -> np.ndarray:
        if c not in self._g:
            f = c.features(self.ident)                          # (N, 6, k)
            rows = np.flatnonzero(np.any(f != 0, axis=(0, 2)))  # joints the columns touch
            q3 = self._q.reshape(-1, 6, self._q.shape[1])
            qtc = sum(q3[:, j, :].T @ f[:, j, :] for j in rows) if rows.size else \
                np.zeros((self._q.shape[1], c.k))
            self._g[c] = np.linalg.solve(self._r, qtc) / self._scale[:, None]
        return self._g[c]

    def f_ident(self, c: Candidate) -> np.ndarray:
        key = ("f_ident", c)
        if key not in self.ident.cache:
            self.ident.cache[key] = c.features(self.ident).reshape(-1, c.k) - self.ident.w @ self.g(c)
        return self.ident.cache[key]

    def f_valid(self, c: Candidate) -> np.ndarray:
        key = ("f_valid", c)
        if key not in self.valid.cache:
            self.valid.cache[key] = c.features(self.valid).reshape(-1, c.k) - self.valid.w @ self.g(c)
        return self.valid.cache[key]

    def training_gain(self, c: Candidate) -> float:
        """Reduction of the fitting data's squared residual by ``c`` alone (choice of variant)."""
        if c.mode == "ident":
            f, y = self.f_ident(c), self.r_ident
        else:
            f, y = c.features(self.valid).reshape(-1, c.k), self.r_valid.reshape(-1)
        beta = lstsq(f, y)
        e = y - f @ beta
        return float(y @ y - e @ e)

    # ------------------------------------------------------------- evaluation
    def evaluate(self, selection: Sequence[Candidate]) -> Fit:
        ident = [c for c in selection if c.mode == "ident"]
        cv = [c for c in selection if c.mode == "cv"]
        r = self.r_valid.copy()
        beta_i = np.zeros(0)
        if ident:
            f_id = np.hstack([self.f_ident(c) for c in ident])
            beta_i = lstsq(f_id, self.r_ident)
            f_va = np.hstack([self.f_valid(c) for c in ident])
            r = r - (f_va @ beta_i).reshape(-1, 6)
        beta_c = np.zeros(0)
        if cv:
            feats = np.concatenate([c.features(self.valid) for c in cv], axis=2)   # (N, 6, k)
            k = feats.shape[2]
            pred = np.zeros_like(r)
            for b in range(self.n_folds):
                train = self.fold != b
                beta_b = lstsq(feats[train].reshape(-1, k), r[train].reshape(-1))
                pred[~train] = feats[~train] @ beta_b
            beta_c = lstsq(feats.reshape(-1, k), r.reshape(-1))
            r = r - pred
        return Fit(ident, beta_i, cv, beta_c, r, {c: self.g(c) for c in ident})
