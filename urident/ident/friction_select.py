"""Per-joint friction terms chosen by blocked cross-validation on the identification data
(``urident identify --preset auto``).

The family (:func:`family`) covers the friction forms labs publish for UR-type harmonic drives, as
columns linear in their coefficients (:mod:`urident.ident.features`): a constant offset, Coulomb
asymmetry |z|, Gaz et al.'s sigmoid with a velocity offset (linearised: tanh(q̇/ε) and tanh²(q̇/ε),
ε on a grid), a smooth sigmoid alone, Stribeck (v_s on a grid), square-root and quadratic viscous
(linear viscous is in the base set), load-dependent Coulomb and position-dependent Coulomb
friction at harmonics 1-3 of the joint angle, and, when every log carries joint temperatures,
viscous and Coulomb friction changing with the temperature (q̇·(T − T_ref), z·(T − T_ref), T_ref
each joint's mean temperature in the data; offered on a joint only where its temperature moved by
at least :data:`MIN_TEMPERATURE_SPAN_C` in the data); the Dahl presliding state is a choice of the joint's
Coulomb state (below), not a term beside it. Choices and measurements:
``docs/friction-selection.md``.

Procedure, for each Coulomb state of the base model (tanh, ε = the model's; a Dahl state driven by
∫q̇ with δ from :data:`DAHL_GRID`):

1. one pass over the data (:func:`urident.ident.design.design_chunks`, bounded memory) builds,
   per CV block (``folds`` contiguous blocks, fixed) and joint j, the QR factor of
   [Θ_base,j | E_j | τ_j], E_j every candidate column of joint j;
2. greedy forward selection, all joints per round: each joint's candidate is scored by the
   held-out error of joint j with the weighted least-squares fit of the whole model (the other
   joints' extra columns are profiled out of their factors, which is exact, so one candidate costs
   one small QR per fold); joint weights 1/σ_j from a plain fit of each training fold, as
   ``--weighting joint``.

A term joins joint j when the per-fold decrease of joint j's held-out mean square error has a mean
above :data:`MIN_T` standard errors of its fold-to-fold spread (a paired test over the folds:
a fold's difficulty cancels, what stays is whether the term helps consistently), or is positive
on every fold (a sign test: a friction term that matters near velocity reversals gains most in
the folds that hold them, and that spread must not count against it; :func:`fold_test`) and lowers
joint j's held-out RMS by at least :data:`MIN_GAIN` (a gain below the noise of the choice itself
is not worth a parameter). A term that makes the two directions of motion differ
(:data:`DIRECTIONAL`: offset, |z|, the sigmoid's offset column) must also lower joint j's held-out
squared error on the held-out samples of each direction (q̇_j ≥ 0 and q̇_j < 0, summed over the
folds): where the joint moved one way only, such a term is not told apart from the odd friction
columns, and what it predicts for the other way is a guess. Such terms are not offered at all on a
joint that travelled less than :data:`MIN_DIRECTION_SHARE` of its way (Σ|q̇|) in one direction: a
few reversals then decide the held-out test of that direction. Of the terms that pass, the largest
gain is taken. The Coulomb state
with the lowest mean held-out RMS over joints is shared; a joint takes another (its own best,
with the terms selected on it) only when that passes the same rule against the shared one.

Then, on the chosen states together, each joint whose single terms all failed tries every pair of
candidate terms (:func:`_best_pair`): one term at a time, forward selection misses two terms that
pay only together (each alone helps some folds and hurts another). The pair search is some 100
candidates a joint instead of 15, so a pair must pass both fold tests (mean above :data:`MIN_T`
standard errors *and* positive on every fold), lower the joint's held-out RMS by 2 × :data:`MIN_GAIN`,
and each of its terms must pass the rule beside the other (the pair against each term alone);
the direction test holds for it as for one term. A joint that took a pair goes on as before.
Pairs come after the states: let into the choice of the state, the wider search moved the real
UR10e's shared presliding distance and cost it on its other recordings
(``docs/friction-selection.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from urident.ident.design import TEMPERATURE_FEATURES, ModelConfig, base_for, design_chunks, parse_term, term_text
from urident.ident.preprocess import Prepared
from urident.blas import one_blas_thread

DAHL_GRID = (5e-5, 7e-5, 1e-4, 1.5e-4, 2e-4, 3e-4, 5e-4)   # [rad] presliding distance of the base state
# [rad/s] sigmoid smoothness ε = 2/φ2 (φ2 = 40, 10 s/rad); the sharp one is the tanh base. Not
# offered on a Dahl base: beside a state that is tanh-like in motion, a sharp tanh changes mostly
# what the model does at stops (it drops the friction there), which excitation runs cannot score
SIGMOID_EPS = (0.05, 0.2)
STRIBECK_VS = (0.02, 0.05, 0.1)       # [rad/s]
HARMONICS = (1, 2, 3)                 # periods per joint revolution
# [°C] least span of a joint's temperature for its temperature terms: friction changes by 1-2 %/°C,
# so a smaller span moves it less than the MIN_GAIN a term must earn, and what such a term fits is
# any other slow drift of the run, extrapolated as soon as the temperature leaves that span
MIN_TEMPERATURE_SPAN_C = 1.0
# least share of a joint's travel (Σ|q̇|) in its rarer direction for the terms that make the two
# directions differ: below it the other direction's friction rests on a few reversals, and a
# directional term fitted there mostly reshapes the one direction seen (module doc)
MIN_DIRECTION_SHARE = 0.1
MIN_T = 2.0          # mean fold gain / its standard error (≈ 95 % one-sided with 5 folds)
MIN_GAIN = 0.005     # relative held-out RMS decrease of the joint
MAX_TERMS = 6        # per joint
FOLDS = 5
# features with a part that is the same in both directions of motion: they set the difference
# between the directions, which only samples of both directions can score
DIRECTIONAL = ("offset", "asym", "sigoffset")
PAIR_JOIN = " with "


@dataclass(frozen=True)
class Term:
    """A candidate: a label for reports and the per-joint features it adds (``name@value``)."""

    label: str
    features: tuple[str, ...]


def family(base: ModelConfig, temperature: bool = False) -> tuple[Term, ...]:
    """The candidate terms on top of ``base`` (module doc); features identical to the base's
    Coulomb column are left out (a term that keeps none is dropped). ``temperature``: the data
    carry joint temperatures (the temperature terms are offered; their features are named without
    T_ref here, each joint's is set by :func:`joint_feature`)."""
    terms = [Term("offset", ("offset",)), Term("asymmetric Coulomb", ("asym",))]
    terms += [Term(f"sigmoid+offset eps={e:g}", (f"sigmoid@{e:g}", f"sigoffset@{e:g}")) for e in SIGMOID_EPS]
    terms += [Term(f"sigmoid eps={e:g}", (f"sigmoid@{e:g}",)) for e in SIGMOID_EPS]
    terms += [Term(f"Stribeck vs={v:g}", (f"stribeck@{v:g}",)) for v in STRIBECK_VS]
    terms += [Term("sqrt viscous", ("sqrtvisc",)), Term("quadratic viscous", ("quadvisc",)),
              Term("load Coulomb", ("load",))]
    terms += [Term(f"position k={k}", (f"poscos@{k}", f"possin@{k}")) for k in HARMONICS]
    if temperature:
        terms += [Term("temperature viscous", ("tempvisc",)), Term("temperature Coulomb", ("tempcoul",))]
    out = []
    for t in terms:
        kept = tuple(f for f in t.features if not _same_as_coulomb(base, f))
        if kept and all(kept != o.features for o in out):
            out.append(Term(t.label, kept))
    return tuple(out)


def joint_feature(feature: str, t_ref: np.ndarray | None, j: int) -> str:
    """The feature as joint ``j`` carries it: a temperature term with that joint's T_ref [°C]."""
    return term_text(feature, float(t_ref[j])) if feature in TEMPERATURE_FEATURES else feature


def temperature_spans(data: Prepared) -> np.ndarray | None:
    """(6,) how far each joint's logged temperature moved over the data [°C] (None without
    temperatures); a joint's temperature terms are offered where it is at least
    :data:`MIN_TEMPERATURE_SPAN_C`."""
    return None if data.temperature is None else np.ptp(data.temperature, axis=0)


def direction_shares(data: Prepared) -> np.ndarray:
    """(6,) each joint's share of its travel (Σ|q̇| over the samples) in its rarer direction of
    motion, 0 to 0.5; a joint's directional terms are offered where it is at least
    :data:`MIN_DIRECTION_SHARE`."""
    fwd = np.clip(data.qd, 0.0, None).sum(axis=0)
    back = np.clip(-data.qd, 0.0, None).sum(axis=0)
    total = fwd + back
    return np.where(total > 0, np.minimum(fwd, back) / np.where(total > 0, total, 1.0), 0.0)


def reference_temperatures(data: Prepared) -> np.ndarray | None:
    """(6,) each joint's mean logged temperature [°C] to 0.1 °C (None without temperatures)."""
    return None if data.temperature is None else np.round(np.mean(data.temperature, axis=0), 1)


def _same_as_coulomb(base: ModelConfig, feature: str) -> bool:
    if feature in TEMPERATURE_FEATURES:
        return False
    name, value = parse_term(feature)
    if base.coulomb == "tanh" and name == "sigmoid":
        return np.isclose(value, base.friction_eps)
    return False


@dataclass(frozen=True)
class Step:
    """One term added to a joint: held-out RMS of the joint before and after [N·m], t statistic;
    for a term of :data:`DIRECTIONAL` features, the decrease of the joint's held-out squared error
    on the samples of each direction (q̇ ≥ 0, q̇ < 0) [N²·m²], else None."""

    term: str
    rms_before: float
    rms_after: float
    t_stat: float
    by_direction: tuple[float, float] | None = None
    every_fold: bool = False         # the term lowered the held-out error of every fold
    pair: bool = False               # two terms taken together (``term`` joins their labels)

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(self.term.split(PAIR_JOIN)) if self.pair else (self.term,)

    @property
    def gain_pct(self) -> float:
        return 100.0 * (1.0 - self.rms_after / self.rms_before)


@dataclass(frozen=True)
class JointChoice:
    coulomb: str                     # the joint's Coulomb state: 'tanh' or 'dahl@delta'
    steps: tuple[Step, ...]          # terms added on that state, in order
    rejected: Step | None            # the best term of the last round, which did not pass
    rms: float                       # held-out RMS of the joint in the chosen model [N·m]


@dataclass(frozen=True)
class FrictionSelection:
    """The chosen model (``model``), per joint its Coulomb state, what was added and what was
    not, and the Coulomb states compared (label → (6,) held-out RMS per joint after selection)."""

    model: ModelConfig
    joints: tuple[JointChoice, ...]
    bases: tuple[tuple[str, np.ndarray], ...]
    family: tuple[str, ...]
    folds: int
    t_ref: tuple[float, ...] | None = None   # per joint [°C]; None: the logs carry no joint temperature
    t_span: tuple[float, ...] | None = None  # per joint, how far its temperature moved in the data [°C]
    direction_share: tuple[float, ...] = (0.5,) * 6   # per joint, its travel's share in the rarer direction

    @property
    def temperature_joints(self) -> tuple[int, ...]:
        """The joints (0-based) whose temperature terms were offered."""
        return () if self.t_span is None else tuple(j for j, v in enumerate(self.t_span) if v >= MIN_TEMPERATURE_SPAN_C)

    @property
    def directional_joints(self) -> tuple[int, ...]:
        """The joints (0-based) whose directional terms (offset, |z|, sigmoid offset) were offered."""
        return tuple(j for j, v in enumerate(self.direction_share) if v >= MIN_DIRECTION_SHARE)

    @property
    def mean_rms_nm(self) -> float:
        return float(np.mean([j.rms for j in self.joints]))

    def text(self) -> str:
        lines = [f"friction terms chosen per joint by {self.folds}-fold blocked CV on the identification "
                 f"data (a term kept when its fold gains have mean > {MIN_T:g} standard errors or are positive "
                 f"on every fold, and the "
                 f"joint's held-out RMS falls >= {100 * MIN_GAIN:g} %; a term that makes the two directions "
                 "of motion differ also lowers the held-out error of each direction's samples)",
                 f"  terms tried per joint: {'; '.join(self.family)}",
                 "  joint temperature: " + self._temperature_text(),
                 "  both directions of motion: " + self._direction_text(),
                 "  Coulomb states tried, each joint's held-out RMS [N·m] after its selection (the state with the "
                 "lowest mean is shared; a joint takes its own best when that passes the term rule):"]
        lines += [f"    {b:<18}" + " ".join(f"{v:6.3f}" for v in r) for b, r in self.bases]
        for j, c in enumerate(self.joints):
            chosen = ", ".join(f"{s.term} ({s.rms_before:.3f} -> {s.rms_after:.3f}, -{s.gain_pct:.1f} %, "
                               f"t {s.t_stat:.1f}{', every fold' if s.every_fold else ''}"
                               f"{', together' if s.pair else ''})"
                               for s in c.steps) or "none"
            rej = ("" if c.rejected is None else
                   f"; best rejected: {c.rejected.term} ({-c.rejected.gain_pct:+.1f} %, t {c.rejected.t_stat:.1f}"
                   + ("" if c.rejected.by_direction is None or min(c.rejected.by_direction) > 0 else
                      ", no gain on the samples of one direction") + ")")
            lines.append(f"  J{j + 1}: {c.coulomb}; {chosen}{rej}; CV RMS {c.rms:.3f}")
        lines.append(f"  mean CV RMS {self.mean_rms_nm:.3f} N·m")
        return "\n".join(lines)

    def _temperature_text(self) -> str:
        if self.t_ref is None:
            return "not offered: the logs carry no joint temperature"
        spans = "span [°C] per joint " + " ".join(f"{v:.2f}" for v in self.t_span)
        if not self.temperature_joints:
            return f"not offered: no joint's temperature moved {MIN_TEMPERATURE_SPAN_C:g} °C ({spans})"
        return (f"offered on {', '.join(f'J{j + 1}' for j in self.temperature_joints)} (moved >= "
                f"{MIN_TEMPERATURE_SPAN_C:g} °C; {spans}), T_ref [°C] per joint (the data's mean): "
                + " ".join(f"{v:g}" for v in self.t_ref))

    def _direction_text(self) -> str:
        shares = "share of travel in the rarer direction per joint " + " ".join(f"{v:.2f}" for v in self.direction_share)
        left = [j for j in range(6) if j not in self.directional_joints]
        if not left:
            return f"offset, |z| and sigmoid offset offered on every joint ({shares})"
        return (f"offset, |z| and sigmoid offset not offered on {', '.join(f'J{j + 1}' for j in left)} "
                f"(moved < {100 * MIN_DIRECTION_SHARE:g} % of its travel one way; {shares})")

    def to_dict(self) -> dict:
        return {"model": self.model.as_dict(), "folds": self.folds, "family": list(self.family),
                "temperature_ref_c": None if self.t_ref is None else list(self.t_ref),
                "temperature_span_c": None if self.t_span is None else list(self.t_span),
                "temperature_joints": [j + 1 for j in self.temperature_joints],
                "direction_share": list(self.direction_share),
                "directional_joints": [j + 1 for j in self.directional_joints],
                "bases": {b: [float(v) for v in r] for b, r in self.bases}, "mean_cv_rms_nm": self.mean_rms_nm,
                "joints": [{"coulomb": c.coulomb, "terms": [x for s in c.steps for x in s.labels], "cv_rms_nm": c.rms,
                            "steps": [vars(s) | {"gain_pct": s.gain_pct, "by_direction": None if s.by_direction is None
                                                  else list(s.by_direction)} for s in c.steps],
                            "rejected": None if c.rejected is None else c.rejected.term}
                           for c in self.joints]}


class _Factors:
    """Per fold and joint, the training and held-out factors of [Θ_base,j | E_j | τ_j]."""

    def __init__(self, spec, base: ModelConfig, terms: tuple[Term, ...], data: Prepared, folds: int):
        feats = list(dict.fromkeys(f for t in terms for f in t.features))
        self.index = {f: k for k, f in enumerate(feats)}
        m = len(feats)
        nb = base_for(spec, base.reduced).n_base
        self.nb, self.m = nb, m
        t_ref = reference_temperatures(data)
        sup = replace(base, extras=(), joint_extras=tuple(tuple(joint_feature(f, t_ref, j) for f in feats)
                                                          for j in range(6)))
        n = len(data)
        edges = np.linspace(0, n, folds + 1).astype(int)
        width = nb + m + 1
        blocks_r = [[np.zeros((0, width)) for _ in range(6)] for _ in range(folds)]
        # the held-out rows of each joint split by its direction of motion (q̇_j ≥ 0, q̇_j < 0)
        blocks_d = [[[np.zeros((0, width)) for _ in range(2)] for _ in range(6)] for _ in range(folds)]
        with one_blas_thread():
            for a, b, blocks in design_chunks(spec, sup, data.q, data.qd, data.qdd, data.segment, data.t,
                                              chunk=4096, temperature=data.temperature):
                for f in range(folds):
                    lo, hi = max(a, edges[f]), min(b, edges[f + 1])
                    if lo >= hi:
                        continue
                    part = blocks[lo - a:hi - a]
                    for j in range(6):
                        cols = np.r_[np.arange(nb), nb + j * m + np.arange(m)]
                        rows = np.hstack([part[:, j, cols], data.tau[lo:hi, j, None]])
                        blocks_r[f][j] = _tri(np.vstack([blocks_r[f][j], rows]), width)
                        back = data.qd[lo:hi, j] < 0
                        for d, sel in enumerate((~back, back)):
                            blocks_d[f][j][d] = _tri(np.vstack([blocks_d[f][j][d], rows[sel]]), width)
            self.test = blocks_r
            self.test_by_direction = blocks_d
            self.train = [[_tri(np.vstack([blocks_r[g][j] for g in range(folds) if g != f]), width)
                           for j in range(6)] for f in range(folds)]
        self.n_test = np.diff(edges)
        self.folds = folds

    def cols(self, sel: list[str]) -> np.ndarray:
        return np.r_[np.arange(self.nb), self.nb + np.array([self.index[f] for f in sel], dtype=int),
                     self.nb + self.m]

    def profile(self, f: int, j: int, sel: list[str]) -> np.ndarray:
        """(nb + 1)² factor of joint j's training rows on [Θ_base | τ] with its extras ``sel``
        eliminated (‖P [θ; −1]‖² = min over those coefficients)."""
        c = self.cols(sel)
        k = len(sel)
        a = self.train[f][j][:, np.r_[c[self.nb:-1], c[:self.nb], c[-1]]]
        return _tri(a, a.shape[1])[k:, k:]

    def held_out(self, sels: list[list[str]]) -> np.ndarray:
        """(folds, 6) held-out squared error per fold and joint of the model with extras ``sels``."""
        out = np.zeros((self.folds, 6))
        for f in range(self.folds):
            others, w = self.others(f, sels)
            for j in range(6):
                out[f, j] = self.candidate(f, j, sels[j], others[j], w[j])[0]
        return out

    def others(self, f: int, sels: list[list[str]]) -> tuple[list[np.ndarray], np.ndarray]:
        """For each joint j, the weighted factor of every other joint's profiled rows; and the
        joint weights 1/σ_j of a plain fit of training fold ``f``."""
        prof = [self.profile(f, i, sels[i]) for i in range(6)]
        theta = _solve(_tri(np.vstack(prof), self.nb + 1))
        std = np.array([np.linalg.norm(p @ np.r_[theta, -1.0]) for p in prof])
        std = np.sqrt(std ** 2 / (np.sum(self.n_test) - self.n_test[f]))
        w = 1.0 / np.maximum(std, 1e-9 * max(std.max(), 1e-300))
        return [_tri(np.vstack([w[i] * prof[i] for i in range(6) if i != j]), self.nb + 1) for j in range(6)], w

    def candidate(self, f: int, j: int, sel: list[str], other: np.ndarray, weight: float) -> tuple[float, np.ndarray]:
        """Held-out squared error of joint j in fold f with its extras ``sel``, the other joints'
        rows given as their weighted profiled factor ``other``, joint j's rows weighted ``weight``;
        and (2,) that of its held-out samples with q̇_j ≥ 0 and with q̇_j < 0."""
        c = self.cols(sel)
        k = len(sel)
        p = self.nb + k
        mine = weight * self.train[f][j][:, c]
        pad = np.zeros((other.shape[0], p + 1))
        pad[:, :self.nb] = other[:, :self.nb]
        pad[:, p] = other[:, self.nb]
        x = np.r_[_solve(_tri(np.vstack([pad, mine]), p + 1)), -1.0]
        e = self.test[f][j][:, c] @ x
        by_direction = [self.test_by_direction[f][j][d][:, c] @ x for d in range(2)]
        return float(e @ e), np.array([float(v @ v) for v in by_direction])


def _tri(a: np.ndarray, n: int) -> np.ndarray:
    r = np.linalg.qr(a, mode="r")
    if r.shape[0] < n:
        r = np.vstack([r, np.zeros((n - r.shape[0], n))])
    return r[:n]


def _solve(r: np.ndarray) -> np.ndarray:
    """argmin ‖R [x; −1]‖ for a square upper-triangular R (least squares if near singular)."""
    a, z = r[:-1, :-1], r[:-1, -1]
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    a = a / scale
    d = np.abs(np.diag(a))
    if d.size and d.min() > 1e-10 * d.max():
        import scipy.linalg

        x = scipy.linalg.solve_triangular(a, z)
    else:
        x, *_ = np.linalg.lstsq(a, z, rcond=1e-10)
    return x / scale


def _is_directional(t: Term) -> bool:
    return any(parse_term(x)[0] in DIRECTIONAL for x in t.features if x not in TEMPERATURE_FEATURES)


def _select(fac: _Factors, terms: tuple[Term, ...], offered: np.ndarray,
            directional: np.ndarray, pairs: bool = False,
            start=None) -> tuple[list[list[str]], list[JointChoice]]:
    """Greedy forward selection of each joint's terms (module doc); ``offered`` (6,): the joints
    whose temperature terms are tried; ``directional`` (6,): those whose directional terms are.
    ``pairs``: a joint whose single terms fail tries pairs; ``start``: (features, steps) per joint
    already chosen, whose single terms have failed (the joints try pairs first)."""
    sels: list[list[str]] = [list(x) for x in start[0]] if start else [[] for _ in range(6)]
    steps: list[list[Step]] = [list(x) for x in start[1]] if start else [[] for _ in range(6)]
    rejected: list[Step | None] = [None] * 6
    open_ = [True] * 6
    # from a start, each joint's single terms have failed already: it looks at pairs first
    singles_failed = [bool(start)] * 6
    n = np.sum(fac.n_test)
    while any(open_):
        base_sq = np.zeros((fac.folds, 6))
        base_dir = np.zeros((6, 2))      # per joint, held-out squared error by direction, summed over folds
        cand: list[list[tuple[Term, np.ndarray, np.ndarray]]] = [[] for _ in range(6)]
        others = [fac.others(f, sels) for f in range(fac.folds)]
        for f in range(fac.folds):
            ow, w = others[f]
            for j in range(6):
                if not open_[j]:
                    continue
                base_sq[f, j], by_dir = fac.candidate(f, j, sels[j], ow[j], w[j])
                base_dir[j] += by_dir
                for t in terms:
                    if any(x in sels[j] for x in t.features) or (
                            not offered[j] and any(x in TEMPERATURE_FEATURES for x in t.features)) or (
                            not directional[j] and _is_directional(t)):
                        continue
                    if f == 0:
                        cand[j].append((t, np.zeros(fac.folds), np.zeros(2)))
                    entry = next(c for c in cand[j] if c[0] is t)
                    entry[1][f], by_dir = fac.candidate(f, j, sels[j] + list(t.features), ow[j], w[j])
                    entry[2][:] += by_dir
        for j in range(6):
            if not open_[j]:
                continue
            before = np.sqrt(base_sq[:, j].sum() / n)
            best: tuple[float, Step] | None = None
            best_any: Step | None = None
            for t, sq, sq_dir in cand[j]:
                t_stat, every, consistent = fold_test((base_sq[:, j] - sq) / fac.n_test)
                by_dir = tuple(float(v) for v in base_dir[j] - sq_dir) if _is_directional(t) else None
                step = Step(t.label, float(before), float(np.sqrt(sq.sum() / n)), t_stat, by_dir, every)
                if best_any is None or step.rms_after < best_any.rms_after:
                    best_any = step
                if (consistent and not singles_failed[j] and step.gain_pct >= 100 * MIN_GAIN
                        and (by_dir is None or min(by_dir) > 0)):
                    if best is None or step.rms_after < best[0]:
                        best = (step.rms_after, step, t.features)
            n_terms = sum(len(s.labels) for s in steps[j])
            if pairs and best is None and n_terms + 2 <= MAX_TERMS:
                best = _best_pair(fac, j, sels[j], others, base_sq[:, j], base_dir[j], cand[j], n)
            if best is None or n_terms >= MAX_TERMS:
                open_[j] = False
                rejected[j] = best_any if best is None else best[1]
                continue
            step = best[1]
            sels[j] += list(best[2])
            steps[j].append(step)
            singles_failed[j] = False
    sq = fac.held_out(sels)
    rms = np.sqrt(sq.sum(axis=0) / n)
    return sels, [(tuple(steps[j]), rejected[j], float(rms[j])) for j in range(6)], sq / fac.n_test[:, None]


def _best_pair(fac: _Factors, j: int, sel: list[str], others, base_sq: np.ndarray, base_dir: np.ndarray,
               singles, n: float):
    """The best pair of joint j's candidate terms that passes the term rule together where neither
    passed alone (module doc), as (held-out RMS, :class:`Step`, features), or None. ``singles``:
    each candidate (term, per-fold held-out squared error, by direction) of this round."""
    before = np.sqrt(base_sq.sum() / n)
    best = None
    for a in range(len(singles)):
        for b in range(a + 1, len(singles)):
            (ta, sq_a, _), (tb, sq_b, _) = singles[a], singles[b]
            feats = ta.features + tb.features
            if len(set(feats)) < len(feats):
                continue
            sq = np.zeros(fac.folds)
            sq_dir = np.zeros(2)
            for f in range(fac.folds):
                ow, w = others[f]
                sq[f], by_dir = fac.candidate(f, j, sel + list(feats), ow[j], w[j])
                sq_dir += by_dir
            rms = float(np.sqrt(sq.sum() / n))
            t_stat, every, _ = fold_test((base_sq - sq) / fac.n_test)
            if not (every and t_stat > MIN_T) or rms > (1 - 2 * MIN_GAIN) * before:
                continue
            if best is not None and rms >= best[0]:
                continue
            # each term pays for itself beside the other
            if not all(fold_test((one - sq) / fac.n_test)[2] and rms <= (1 - MIN_GAIN) * np.sqrt(one.sum() / n)
                       for one in (sq_a, sq_b)):
                continue
            directional = _is_directional(ta) or _is_directional(tb)
            by_dir = tuple(float(v) for v in base_dir - sq_dir) if directional else None
            if by_dir is not None and min(by_dir) <= 0:
                continue
            best = (rms, Step(ta.label + PAIR_JOIN + tb.label, float(before), rms, t_stat, by_dir, every, True),
                    feats)
    return best


def fold_test(d: np.ndarray) -> tuple[float, bool, bool]:
    """Whether per-fold gains ``d`` (held-out mean square error before − after) are consistent:
    their mean is above :data:`MIN_T` standard errors, or they are positive on every fold (a
    sign test, p = 2^−folds: one fold's large gain widens the spread without being evidence
    against the term). Returns the t statistic, every fold positive, and the verdict."""
    se = np.std(d, ddof=1) / np.sqrt(len(d)) if len(d) > 1 else np.inf
    t_stat = float(np.mean(d) / se) if se > 0 else (np.inf if np.mean(d) > 0 else 0.0)
    every = bool(len(d) > 1 and np.all(d > 0))
    return t_stat, every, t_stat > MIN_T or every


def _coulomb_states(rms: np.ndarray, mse: np.ndarray) -> np.ndarray:
    """(6,) index of each joint's Coulomb state: the one with the lowest mean held-out RMS over
    joints, unless a joint's own best passes the term rule against it (``rms`` (S, 6); ``mse``
    (S, folds, 6) held-out mean square error per fold): a joint departs from the shared state
    only when CV says it pays, so a flat CV curve does not pick a state by its noise."""
    shared = int(np.argmin(rms.mean(axis=1)))
    pick = np.full(6, shared)
    for j in range(6):
        own = int(np.argmin(rms[:, j]))
        passes = fold_test(mse[shared, :, j] - mse[own, :, j])[2]
        if own != shared and passes and rms[own, j] <= (1 - MIN_GAIN) * rms[shared, j]:
            pick[j] = own
    return pick


def base_models(model: ModelConfig, dahl_grid=DAHL_GRID) -> list[tuple[str, ModelConfig]]:
    """The base Coulomb states compared: tanh (the model's ε) and the Dahl state driven by ∫q̇ at
    each distance of ``dahl_grid``."""
    out = [(f"tanh eps={model.friction_eps:g}", replace(model, coulomb="tanh", dahl_source="velocity",
                                                        extras=(), joint_extras=()))]
    out += [(f"Dahl delta={d:g}", replace(model, coulomb="dahl", dahl_source="velocity", dahl_rad=d,
                                          extras=(), joint_extras=())) for d in dahl_grid]
    return out


def select_friction(spec, data: Prepared, model: ModelConfig | None = None, folds: int = FOLDS,
                    dahl_grid=DAHL_GRID) -> FrictionSelection:
    """Each joint's friction terms chosen by blocked CV on ``data`` (module doc). ``model``: the
    base-parameter set and tanh slope (default: the reduced base set, ε = 0.01 rad/s); its
    friction extras are replaced by the choice. Weighting: per joint (``'joint'``)."""
    from urident.progress import Progress

    from urident.ident.crossval import cross_validate

    model = model or ModelConfig(reduced=True)
    bases = base_models(model, dahl_grid)
    t_ref = reference_temperatures(data)
    spans = temperature_spans(data)
    offered = np.zeros(6, dtype=bool) if spans is None else spans >= MIN_TEMPERATURE_SPAN_C
    shares = direction_shares(data)
    results = []
    with Progress("friction selection (Coulomb states)", len(bases)) as progress:
        for label, base in bases:
            terms = family(base, bool(offered.any()))
            fac = _Factors(spec, base, terms, data, folds)
            with one_blas_thread():
                sels, joints, mse = _select(fac, terms, offered, shares >= MIN_DIRECTION_SHARE)
            results.append((label, base, sels, joints, mse))
            progress.advance(1)
    rms = np.array([[j[2] for j in r[3]] for r in results])     # (bases, 6)
    pick = _coulomb_states(rms, np.stack([r[4] for r in results]))
    states = tuple("tanh" if results[b][1].coulomb == "tanh" else f"dahl@{results[b][1].dahl_rad:g}"
                   for b in pick)
    # the chosen states together; on them the selection goes on with pairs of terms too (the
    # wider search comes after the states are chosen, so it cannot pick them)
    mixed = replace(model, coulomb="tanh", dahl_source="velocity", extras=(), joint_coulomb=states,
                    joint_extras=())
    terms = family(mixed, bool(offered.any()))
    own = [results[b][3][j] for j, b in enumerate(pick)]       # (steps, rejected, rms) per joint
    with Progress("friction selection (pairs of terms)", 1) as progress:
        fac = _Factors(spec, mixed, terms, data, folds)
        with one_blas_thread():
            sels, chosen_joints, _ = _select(fac, terms, offered, shares >= MIN_DIRECTION_SHARE, pairs=True,
                                             start=([results[b][2][j] for j, b in enumerate(pick)],
                                                    [o[0] for o in own]))
        progress.advance(1)
    chosen = replace(mixed, joint_extras=tuple(tuple(joint_feature(f, t_ref, j) for f in sels[j])
                                               for j in range(6)))
    # scored as a whole by the same CV the report's users run
    final = cross_validate(spec, data, chosen, "joint", "ols", folds).rms_nm
    # a joint that took no pair keeps what its own run rejected last (its singles were not retried)
    joints = tuple(JointChoice(states[j], *(c[:2] if len(c[0]) > len(o[0]) else o[:2]), float(final[j]))
                   for j, (c, o) in enumerate(zip(chosen_joints, own)))
    return FrictionSelection(chosen, joints, tuple((r[0], rms[k]) for k, r in enumerate(results)),
                             tuple(t.label for t in family(bases[0][1], bool(offered.any()))), folds,
                             None if t_ref is None else tuple(float(v) for v in t_ref),
                             None if spans is None else tuple(float(v) for v in spans),
                             tuple(float(v) for v in shares))
