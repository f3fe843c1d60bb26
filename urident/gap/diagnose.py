"""The diagnosis: where the baseline's residual lies, which catalogue effect explains it, how far
it shrinks.

1. Baseline (paper: OLS, tanh friction, ε = 0.01 rad/s) on the identification logs (or loaded);
   residual r = τ_measured − τ̂ on the validation logs, τ_measured = drive gains × raw current.
2. Where: per joint RMS and share of the residual energy; binned maps and spectra
   (:mod:`.maps`); the regimes where the energy concentrates.
3. Which: every candidate of :mod:`.candidates` (per effect, joint and mode; per family the
   variant that fits the fitting data best) is added to the current model and scored on held-out
   validation data: per-sample improvement d_k = Σ_j (r_kj² − r'_kj²) and the same on the
   candidate's own joint. The means get block bootstrap intervals (blocks of ~1 s). A candidate
   is *significant* when the own joint's lower bound is > 0, the summed improvement is positive
   (``test="own"``; ``"total"``: the summed improvement's lower bound > 0) and it shrinks its
   joint's RMS by at least ``min_shrink_pct``; a CV-mode candidate must also be
   material in absolute terms (correction RMS >= ``cv_min_noise_ratio`` × the joint's white-noise
   torque, :func:`material_cv`). Greedy forward selection: the best significant candidate is kept,
   the others are tested again on top, until none is
   significant (or ``max_effects``). None at the first step: "no unmodelled effect found".
   Then the backward half of stepwise selection (:func:`_backward`): each chosen effect is tested
   again on top of the others; those no longer significant are dropped, and the findings are
   ordered by their unique contribution.
   Confounds: a candidate of another effect (or joint) whose predicted correction correlates with
   the chosen one's (uncentred) by |ρ| ≥ ``confound_corr`` and whose improvement interval
   overlaps the chosen one's is reported as confounded with it; when such a candidate has fewer
   columns and a held-out gain the data cannot tell from the chosen one's, it is chosen instead
   (:func:`_simplest_equivalent`).
4. How far: validation RMS per joint and e_N before and after the selected effects.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from urident.errors import ConfigError
from urident.gap import maps
from urident.gap.bootstrap import block_bootstrap_means, default_block_length, interval
from urident.gap.candidates import EFFECTS, Candidate, families
from urident.gap.controller import controller_reference
from urident.gap.data import GapSet, build_set
from urident.gap.residual import SetContext, fit_baseline, make_context
from urident.gap.scoring import Fit, Scorer
from urident.ident.metrics import error_metrics

NO_EFFECT = "no unmodelled effect found"
_PREFER_AXIS = {"stribeck": ("velocity",), "load_friction": ("load",), "thermal_drift": ("time",),
                "position_ripple": ("angle",), "current_offset": ("velocity", "angle"),
                "torque_constant_error": ("load",), "payload_error": ("angle",),
                "current_delay": (), "joint_elasticity": ()}


#: How the materiality floor ``GapConfig.min_shrink_pct`` (3 %) is supported, on effect-free data:
#: with no floor, the held-out test alone passed findings on 73 of 80 effect-free 60 s scenarios
#: (``benchmarks/gap_blind.py --effect-free --min-shrink 0``, seeds 101 and 102), each shrinking
#: its joint by at most 1.3 % (most by < 0.5 %: real but immaterial structure of the baseline's
#: misfit); 3 % is 2.3 x that. A 2 % floor was tried (``--min-shrink 2``, seeds 1, 2, 10, 11): it
#: found effects at 2-3 % on the validation run, but where an effect was present it also named
#: the misfit that effect leaves on *other* joints (an effect-free scan cannot show that): a
#: 2.8 % "joint_elasticity" on joint 2 ahead of the true warm-up on joint 6 (seed 2, scenario 1),
#: and a 2.2 % ripple added on top of a true warm-up that the backward step then dropped (seed 11,
#: scenario 14). So the floor stays at 3 %.
MIN_SHRINK_CALIBRATION = "3 %: 2.3 x the largest effect-free shrink (1.3 %) over 80 scenarios"


@dataclass(frozen=True)
class GapConfig:
    effects: tuple[str, ...] = EFFECTS
    n_folds: int = 5                 # CV blocks inside the validation logs
    n_boot: int = 1000               # bootstrap resamples
    level: float = 0.95              # interval level
    min_shrink_pct: float = 3.0      # a finding must shrink its joint's RMS by at least this
                                     # (calibration: MIN_SHRINK_CALIBRATION above)
    cv_min_noise_ratio: float = 0.5  # a CV-mode finding's correction RMS on its joint must be at
                                     # least this multiple of the joint's white-noise torque
    max_effects: int = 3
    confound_corr: float = 0.8
    parsimony_tol: float = 0.05      # a confounded alternative with fewer columns is chosen when
                                     # its held-out gain is within this share of the best's
    shortlist_ratio: float = 0.8     # phase A: in-sample gain at least this share of the best's
    shortlist_size: int = 4
    block_s: float = 1.0             # bootstrap block length [s]
    friction_eps: float = 0.01       # [rad/s] the baseline's tanh slope
    seed: int = 0
    test: str = "own"                # held-out test: "own" (interval of the gain on the
                                     # candidate's joint above 0, summed gain positive) or "total"
                                     # (interval of the gain summed over joints above 0)

    def __post_init__(self) -> None:
        unknown = [e for e in self.effects if e not in EFFECTS]
        if unknown:
            raise ConfigError(f"effect {unknown[0]!r} unknown (known: {', '.join(EFFECTS)})")
        if self.test not in ("own", "total"):
            raise ConfigError(f"gap config: test must be 'own' or 'total', not {self.test!r}")
        if not (0 <= self.parsimony_tol < 1):
            raise ConfigError("gap config: parsimony_tol in [0, 1)")
        if not (0 < self.level < 1) or self.n_boot < 50 or self.max_effects < 0:
            raise ConfigError("gap config: level in (0, 1), n_boot >= 50, max_effects >= 0")


@dataclass(eq=False)
class Score:
    """One candidate scored on top of the current model."""

    candidate: Candidate
    fit: Fit
    gain: float                      # mean per-sample improvement Σ_j Δr² [N·m²]
    ci: tuple[float, float]
    joint: int                       # 0-based joint it helps most (its own for one-joint effects)
    rms_before: np.ndarray
    rms_after: np.ndarray
    significant: bool
    change: np.ndarray = field(repr=False)       # (N, 6) correction of the prediction
    d: np.ndarray = field(repr=False)            # (N,) per-sample improvement

    @property
    def shrink_pct(self) -> float:
        b, a = self.rms_before[self.joint], self.rms_after[self.joint]
        return float(100.0 * (1.0 - a / b)) if b > 0 else 0.0

    def row(self, spec=None) -> dict:
        c = self.candidate
        coef = self.fit.coefficients()[c]
        return {"effect": c.effect, "joint": self.joint + 1, "variant": c.variant, "mode": c.mode,
                "gain_nm2": self.gain, "gain_ci95_nm2": list(self.ci),
                "rms_before_nm": float(self.rms_before[self.joint]),
                "rms_after_nm": float(self.rms_after[self.joint]), "shrink_pct": self.shrink_pct,
                "significant": bool(self.significant), "magnitude": c.magnitude(coef, spec)}


@dataclass(frozen=True)
class Finding:
    joint: int                       # 1-based
    effect: str
    variant: str
    mode: str
    regime: str
    rms_before_nm: float
    rms_after_nm: float
    shrink_pct: float
    confidence: str                  # high | medium | confounded
    gain_ci95_nm2: tuple[float, float]
    magnitude: dict
    confounded_with: tuple[str, ...] = ()
    joints: tuple[int, ...] = ()     # 1-based; an effect on all joints: every joint where its
                                     # share of the joint's torque is >= MAIN_SHARE of the largest

    def as_dict(self) -> dict:
        return {"joint": self.joint, "joints": list(self.joints or (self.joint,)), "effect": self.effect, "variant": self.variant, "mode": self.mode,
                "regime": self.regime, "rms_before_nm": self.rms_before_nm,
                "rms_after_nm": self.rms_after_nm, "shrink_pct": self.shrink_pct,
                "confidence": self.confidence, "gain_ci95_nm2": list(self.gain_ci95_nm2),
                "magnitude": self.magnitude, "confounded_with": list(self.confounded_with)}


@dataclass(eq=False)
class GapResult:
    robot: str
    model: object                    # the baseline IdentifiedModel
    ident: SetContext
    valid: SetContext
    baseline_e_n: float
    baseline_rms: np.ndarray
    final_e_n: float
    final_rms: np.ndarray
    findings: list[Finding]
    fit: Fit                         # the selected candidates, fitted
    steps: list[list[Score]]         # every candidate scored at every greedy step
    confounds: list[dict]
    where: dict                      # per-joint maps and regimes
    config: GapConfig
    scorer: Scorer | None = None     # to fit any candidates on the same data (benchmarks)

    @property
    def verdict(self) -> str:
        if not self.findings:
            return NO_EFFECT
        return "; ".join(f"{f.effect} on joint {f.joint}" for f in self.findings)

    def chosen(self) -> list[Candidate]:
        return list(self.fit.ident) + list(self.fit.cv)

    def best_of(self, effect: str, joint: int | None) -> Candidate | None:
        """The best-scoring first-step candidate of ``effect`` on 0-based ``joint`` (any joint
        for effects on all joints)."""
        best = None
        for s in self.steps[0] if self.steps else []:
            c = s.candidate
            if c.effect == effect and (c.joint is None or c.joint == joint):
                if best is None or s.gain > best.gain:
                    best = s
        return None if best is None else best.candidate

    def correction(self, candidates: Sequence[Candidate]) -> Fit:
        """``candidates`` fitted together on this diagnosis' data (as the selection would be);
        ``.change(make_context(spec, result.model, other_set))`` applies them elsewhere."""
        return self.scorer.evaluate(list(candidates))

    def as_dict(self) -> dict:
        from urident.gap.report import result_dict

        return result_dict(self)


def _rms(r: np.ndarray) -> np.ndarray:
    return error_metrics(r)[1]


def _e_n(r: np.ndarray) -> float:
    return error_metrics(r)[0]


def diagnose(ident_recordings: Sequence, valid_recordings: Sequence, spec, *, params=None,
             drive_gains=None, config: GapConfig | None = None, preprocess=None) -> GapResult:
    """Diagnose from recordings only (``urident.logs.Recording``) and the robot ``spec``.
    ``params``: a baseline IdentifiedModel (e.g. from ``load_params``) instead of identifying it."""
    config = config or GapConfig()
    if drive_gains is None and params is not None:
        drive_gains = params.drive_gains
    ident = build_set(ident_recordings, spec, drive_gains, preprocess, "identification logs", params)
    valid = build_set(valid_recordings, spec, drive_gains, preprocess, "validation logs", params)
    return diagnose_prepared(spec, ident, valid, params=params, config=config)


def diagnose_prepared(spec, ident: GapSet, valid: GapSet, *, params=None,
                      config: GapConfig | None = None) -> GapResult:
    config = config or GapConfig()
    model = params if params is not None else fit_baseline(spec, ident, config.friction_eps)
    ctx_i = make_context(spec, model, ident)
    ctx_v = make_context(spec, model, valid)
    scorer = Scorer(ctx_i, ctx_v, config.n_folds)
    r0 = ctx_v.residual
    where = describe_where(ctx_v, ctx_i)

    fams = families(spec, ctx_i, ctx_v, config.effects)
    pool = [max(f, key=scorer.training_gain) if len(f) > 1 else f[0] for f in fams]
    block = default_block_length(ctx_v.n, valid.sample_rate * config.block_s)

    selected: list[Candidate] = []
    findings: list[Finding] = []
    steps: list[list[Score]] = []
    confounds: list[dict] = []
    current = scorer.evaluate([])
    consistent = False          # phase A (identification consistency) over
    for step in range(config.max_effects + 1):
        taken = {c.key for c in selected}
        free = [c for c in pool if c.key not in taken]
        scores = _score_all(scorer, current, free, block, config)
        steps.append(scores)
        if step == config.max_effects:
            break
        best = None
        if not consistent:
            # A: an effect present in the identification logs distorts the base parameters and
            # spreads its error over other joints of the validation logs, where a CV-mode
            # effect (an offset "of the day", a payload) would explain it. So first make the
            # identification consistent: short-list the identification-mode candidates by how
            # much they reduce the identification residual on top of those already chosen,
            # and keep the one the validation logs confirm (significant held-out gain).
            short = {id(c) for c in _ident_shortlist(scorer, selected, free, config)}
            sig = [s for s in scores if s.significant and id(s.candidate) in short]
            if sig:
                best = max(sig, key=lambda s: s.gain)
            else:
                consistent = True
        if best is None:
            # B: any candidate (identification or CV mode) by its held-out gain alone
            sig = [s for s in scores if s.significant and _admissible(s, scores)]
            if not sig:
                break
            best = max(sig, key=lambda s: s.gain)
        conf = _confounded(best, scores, block, config)
        simpler = _simplest_equivalent(best, conf, scores, block, config)
        if simpler is not best:
            best = simpler
            conf = _confounded(best, scores, block, config)
        confounds += _confound_rows(step, best, conf)
        findings.append(_finding(best, conf, ctx_v, spec))
        selected.append(best.candidate)
        current = best.fit

    if len(selected) > 1:
        kept = _backward(scorer, selected, block, config)
        if [id(c) for c in kept] != [id(c) for c in selected]:
            # findings and confounds again, step by step in the kept order
            findings, confounds, current = [], [], scorer.evaluate([])
            for step, c in enumerate(kept):
                done = {o.key for o in kept[:step]}
                scores = _score_all(scorer, current, [o for o in pool if o.key not in done], block, config)
                s = next(x for x in scores if x.candidate is c)
                conf = _confounded(s, scores, block, config)
                confounds += _confound_rows(step, s, conf)
                findings.append(_finding(s, conf, ctx_v, spec))
                current = s.fit

    final_r = current.residual
    return GapResult(spec.name, model, ctx_i, ctx_v, _e_n(r0), _rms(r0), _e_n(final_r), _rms(final_r),
                     findings, current, steps, confounds, where, config, scorer)


def _confound_rows(step: int, chosen: Score, conf: list[Score]) -> list[dict]:
    """The report's rows for the candidates confounded with ``chosen`` at 0-based ``step``."""
    return [{"step": step + 1, "chosen": _label(chosen), "alternative": _label(other),
             "correlation": float(_corr(chosen.change, other.change)), "gain_nm2": [chosen.gain, other.gain]}
            for other in conf]


def _backward(scorer: Scorer, selected: list[Candidate], block: int, config: GapConfig) -> list[Candidate]:
    """The backward half of stepwise selection, on the forward pass's choices: each chosen effect
    is tested again on top of all the others (same tests as when it was chosen); the weakest one
    that is no longer significant is dropped, until all are. The kept ones are returned ordered
    by that unique contribution, largest first.

    Why: the first forward step compares single effects, and an identification-mode effect
    distorts the base parameters shared by neighbouring joints (e.g. a drive-gain error of joint
    2 shows on joint 3 too), so a wrong joint can win it by a hair; once the right effect has
    been added as well, the wrong one explains nothing more."""
    kept = list(selected)
    while True:
        tests = []
        for c in kept:
            rest = scorer.evaluate([o for o in kept if o is not c])
            tests.append(_score_all(scorer, rest, [c], block, config)[0])
        weakest = min(tests, key=lambda s: s.gain)
        if len(kept) == 1 or weakest.significant:
            return [s.candidate for s in sorted(tests, key=lambda s: -s.gain)]
        kept.remove(weakest.candidate)


def _ident_shortlist(scorer: Scorer, selected: list[Candidate], free: list[Candidate],
                     config: GapConfig) -> list[Candidate]:
    """Identification-mode candidates whose in-sample reduction of the identification residual
    (jointly with the identification-mode effects already chosen) is at least
    ``shortlist_ratio`` of the best one's, at most ``shortlist_size`` of them."""
    from urident.gap.scoring import _lstsq

    y = scorer.r_ident
    chosen = [c for c in selected if c.mode == "ident"]
    f0 = np.hstack([scorer.f_ident(c) for c in chosen]) if chosen else np.zeros((len(y), 0))
    e0 = y - f0 @ _lstsq(f0, y) if chosen else y
    ss0 = float(e0 @ e0)
    gains = []
    for c in free:
        if c.mode != "ident":
            continue
        f = np.hstack([f0, scorer.f_ident(c)])
        e = y - f @ _lstsq(f, y)
        gains.append((ss0 - float(e @ e), c))
    if not gains:
        return []
    gains.sort(key=lambda g: -g[0])
    top = gains[0][0]
    if top <= 0:
        return []
    return [c for g, c in gains[:config.shortlist_size] if g >= config.shortlist_ratio * top]


def _admissible(s: Score, scores: list[Score]) -> bool:
    """A CV-mode candidate claims the effect changed between the runs; it must beat the same
    columns fitted on the identification logs (ident mode) where the catalogue has that mode,
    else it only re-fits what the identification got wrong."""
    c = s.candidate
    if c.mode != "cv":
        return True
    twins = [o for o in scores if o.candidate.mode == "ident" and o.candidate.key == c.key]
    if not twins:
        return True
    twin = max(twins, key=lambda o: o.gain)
    return s.gain > twin.gain


def _simplest_equivalent(best: Score, conf: list[Score], scores: list[Score], block: int,
                         config: GapConfig) -> Score:
    """Among ``best`` and the candidates confounded with it (:func:`_confounded`) that are
    significant and admissible, the one with the fewest fitted columns whose held-out gain the data
    does not tell from ``best``'s in practice: the paired block-bootstrap interval of the
    per-sample difference of their improvements contains 0, or the alternative keeps at least
    1 − ``parsimony_tol`` of ``best``'s gain. Equal column counts keep the larger gain, so
    ``best`` stays unless a simpler explanation is as good.

    Why: between two explanations whose corrections are nearly the same, the extra columns of the
    larger one also soak up a little of the baseline's own misfit on the validation run. Seen on
    benchmark seed 5, scenario 13: a 4 % current offset on joint 2 and a second-harmonic ripple
    there, correlation 0.99, gains 0.00743 vs 0.00726 N·m²; the ripple's two coefficients won by
    2 % of the gain, an interval just above 0. The one with fewer parameters is the better bet
    (Occam); the confound is still reported either way."""
    alts = [s for s in conf if s.significant and _admissible(s, scores)
            and s.candidate.k < best.candidate.k]
    if not alts:
        return best
    diffs = np.stack([best.d - s.d for s in alts], axis=1)
    boot = block_bootstrap_means(diffs, block, config.n_boot, config.seed)
    equal = [s for i, s in enumerate(alts) if interval(boot[:, i], config.level)[0] <= 0
             or s.gain >= (1.0 - config.parsimony_tol) * best.gain]
    if not equal:
        return best
    return min(equal, key=lambda s: (s.candidate.k, -s.gain))


def _label(s: Score) -> str:
    c = s.candidate
    return f"{c.effect} on joint {s.joint + 1}" + (f" ({c.variant})" if c.variant else "")


def _score_all(scorer: Scorer, current: Fit, pool: list[Candidate], block: int,
               config: GapConfig) -> list[Score]:
    base = current.residual
    sel = list(current.ident) + list(current.cv)
    fits = [scorer.evaluate(sel + [c]) for c in pool]
    if not fits:
        return []
    d = np.stack([np.sum(base ** 2 - f.residual ** 2, axis=1) for f in fits], axis=1)   # (N, m)
    # the same improvement on the candidate's own joint (all-joint candidates: the total)
    d_own = np.stack([base[:, c.joint] ** 2 - f.residual[:, c.joint] ** 2 if c.joint is not None
                      else d[:, i] for i, (c, f) in enumerate(zip(pool, fits))], axis=1)
    boot_all = block_bootstrap_means(np.hstack([d, d_own]), block, config.n_boot, config.seed)
    boot, boot_own = boot_all[:, :len(pool)], boot_all[:, len(pool):]
    rms0 = _rms(base)
    sigma = noise_sigma(scorer.valid.residual)
    out = []
    for i, (c, f) in enumerate(zip(pool, fits)):
        rms1 = _rms(f.residual)
        joint = c.joint if c.joint is not None else _main_joint(base - f.residual, scorer.valid.tau)
        lo, hi = interval(boot[:, i], config.level)
        s = Score(c, f, float(d[:, i].mean()), (lo, hi), joint, rms0, rms1, False,
                  base - f.residual, d[:, i])
        # Why the own joint by default: an identification-mode candidate refits the base parameters,
        # and that moves the other joints' predictions by a little, consistently, either way. Summed
        # in, this collateral can hide a clear gain on the candidate's joint (a warm-up on joint 2
        # with 15 % shrink there, summed interval touching 0). The summed mean must still be > 0 so
        # a candidate that costs the other joints more than it gains is never taken. Checked on
        # effect-free scenarios only (42 of benchmarks/gap_blind.py, seeds 1-6): no false alarm.
        if config.test == "own":
            held_out = interval(boot_own[:, i], config.level)[0] > 0 and s.gain > 0
        else:
            held_out = lo > 0
        s.significant = bool(held_out and s.shrink_pct >= config.min_shrink_pct
                             and plausible(c, f.coefficients()[c])
                             and (c.mode != "cv" or material_cv(s.change[:, joint], sigma[joint],
                                                                config.cv_min_noise_ratio)))
        out.append(s)
    out.sort(key=lambda s: -s.gain)
    return out


def noise_sigma(r: np.ndarray) -> np.ndarray:
    """Per joint white-noise torque [N·m] of the residual ``r`` (N, 6), estimated from its first
    differences (robust: MAD / 0.6745 / √2): the slowly varying structure of unmodelled effects
    cancels in a difference of neighbouring samples, the sensor's current noise does not."""
    dr = np.diff(np.asarray(r, float), axis=0)
    if len(dr) == 0:
        return np.zeros(r.shape[1])
    return np.median(np.abs(dr - np.median(dr, axis=0)), axis=0) / (0.6745 * np.sqrt(2.0))


def material_cv(change_j: np.ndarray, sigma_j: float, ratio: float) -> bool:
    """Materiality of a CV-mode candidate (columns fitted inside the validation logs, the
    baseline fixed): its correction on its joint must have an RMS of at least ``ratio`` times the
    joint's white-noise torque :func:`noise_sigma`.

    Why CV mode only: such a candidate claims that the effect *differs between the runs* and is
    fitted on the validation residual itself, so besides a real effect it also soaks up the
    baseline's small trajectory-dependent misfit (the identification and validation motions
    differ), a few mA of apparent offset or friction that is real structure but no effect of the
    catalogue. Identification-mode candidates are fitted on other data and need no floor.
    Calibration (effect-free scenarios only, never the truth of effect scenarios): over the
    28 effect-free scenarios of ``benchmarks/gap_blind.py`` (seeds 1-4) the CV-mode candidates that
    passed the other tests had corrections of 0.25-0.40 σ (5-8 mA offsets on joints 2-3); the
    default 0.5 σ (correction energy >= 25 % of the noise energy) sits above them with a margin.
    A CV effect of realistic size (a payload, an offset of tens of mA) is several σ."""
    if ratio <= 0:
        return True
    crms = float(np.sqrt(np.mean(np.asarray(change_j, float) ** 2)))
    return crms >= ratio * float(sigma_j)


#: Payload findings need at least this fitted mass [kg] (a mass of ~0 with a few first-moment
#: terms is an identification error of body 6, not a payload).
MIN_PAYLOAD_KG = 0.1


def plausible(c: Candidate, beta: np.ndarray) -> bool:
    """Sign and size constraints of the catalogue's physics on the fitted coefficients:
    Stribeck adds friction near zero velocity, load friction grows with load, a delay is
    positive, an elastic joint has positive J/k, a payload has a mass (|m| >= MIN_PAYLOAD_KG,
    negative: a modelled payload removed) with its centre within 0.5 m of the tool point.
    Other effects may have either sign."""
    b = np.asarray(beta, float)
    if c.effect in ("stribeck", "load_friction"):
        return bool(b[0] > 0)
    if c.effect in ("current_delay", "joint_elasticity"):
        return bool(b[0] < 0)
    if c.effect == "payload_error":
        m = float(b[0])
        return bool(abs(m) >= MIN_PAYLOAD_KG and np.linalg.norm(b[1:4]) <= 0.5 * abs(m) + 1e-12)
    return True


#: An effect on all joints "affects" every joint where its share of the torque is at least this
#: fraction of the largest share (the main joint's).
MAIN_SHARE = 0.7


def _shares(change: np.ndarray, tau: np.ndarray) -> np.ndarray:
    rms_tau = _rms(tau)
    return _rms(change) / np.where(rms_tau > 0, rms_tau, np.inf)


def _main_joint(change: np.ndarray, tau: np.ndarray) -> int:
    """The joint of an effect on all joints (payload_error): where its torque is the largest
    share of the joint's measured torque (RMS over RMS). The blind benchmark names the true
    payload's joint the same way."""
    return int(np.argmax(_shares(change, tau)))


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    """Uncentred correlation (cosine) of two corrections: regression columns have no intercept,
    so a constant and a nearly constant correction are the same explanation."""
    a = a.reshape(-1)
    b = b.reshape(-1)
    den = np.sqrt((a @ a) * (b @ b))
    return float(a @ b / den) if den > 0 else 0.0


def _confounded(best: Score, scores: list[Score], block: int, config: GapConfig) -> list[Score]:
    """Candidates of another (effect, joint) whose correction is nearly the same as ``best``'s
    (uncentred correlation ≥ ``confound_corr``) and whose improvement interval overlaps
    ``best``'s: the data cannot tell them apart."""
    out = []
    seen = set()
    for s in scores:
        key = s.candidate.key
        if s is best or key == best.candidate.key or key in seen or s.gain <= 0:
            continue
        if s.ci[1] < best.ci[0]:
            continue
        if abs(_corr(best.change, s.change)) < config.confound_corr:
            continue
        seen.add(key)
        out.append(s)
    return out


def _signed_load(ctx: SetContext) -> np.ndarray:
    return np.sign(ctx.qd) * np.abs(ctx.tau_hat)


def _finding(best: Score, conf: list[Score], ctx: SetContext, spec) -> Finding:
    c = best.candidate
    j = best.joint
    before = best.rms_before[j]
    after = best.rms_after[j]
    base_r = best.change + best.fit.residual          # residual before this step
    gain_j = base_r[:, j] ** 2 - best.fit.residual[:, j] ** 2
    reg = maps.best_regime(j, gain_j, ctx.qd[:, j], _signed_load(ctx)[:, j], ctx.q[:, j],
                           ctx.data.run_time, _PREFER_AXIS.get(c.effect, ()))
    if reg is not None:
        regime = reg.text("of the improvement")
    else:
        regime = f"joint {j + 1}: spread over all regimes"
    if c.effect == "current_delay":
        fm = maps.frequency_map(base_r[:, j], ctx.data.sample_rate, ctx.dtau[:, j])
        regime += f"; residual vs dτ̂/dt correlation {fm.corr_dtau:+.2f}"
    lo, hi = best.ci
    labels = tuple(_label(s) for s in conf)
    if labels:
        confidence = "confounded"
    else:
        z = best.gain / max((hi - lo) / (2 * 1.96), 1e-300)
        confidence = "high" if (z > 4 and best.shrink_pct >= 10) else "medium"
    coef = best.fit.coefficients()[c]
    joints = (j + 1,)
    if c.joint is None:
        share = _shares(best.change, ctx.tau)
        joints = tuple(int(k) + 1 for k in np.flatnonzero(share >= MAIN_SHARE * share.max()))
    return Finding(j + 1, c.effect, c.variant, c.mode, regime, float(before), float(after),
                   best.shrink_pct, confidence, (lo, hi), c.magnitude(coef, spec),
                   labels, joints)


def describe_where(ctx: SetContext, ident: SetContext | None = None) -> dict:
    """Per joint: RMS, share of the residual energy, maps, angle spectrum, frequency map and the
    regimes where the residual concentrates (texts)."""
    r = ctx.residual
    energy = np.sum(r * r, axis=0)
    total = float(energy.sum()) or 1.0
    load = _signed_load(ctx)
    out = {"joints": []}
    fs = ctx.data.sample_rate
    for j in range(6):
        jm = maps.joint_maps(r[:, j], ctx.qd[:, j], load[:, j], ctx.q[:, j], ctx.data.run_time)
        regimes = maps.concentrated_regimes(j, jm)
        spec_a = maps.angle_spectrum(r[:, j], ctx.q[:, j], ctx.qd[:, j], ctx.friction_eps)
        fm = maps.frequency_map(r[:, j], fs, ctx.dtau[:, j])
        out["joints"].append({
            "joint": j + 1, "rms_nm": float(np.sqrt(energy[j] / len(r))),
            "energy_share": float(energy[j] / total), "mean_nm": float(r[:, j].mean()),
            "maps": {k: [b.as_dict() for b in v] for k, v in jm.items()},
            "angle_spectrum": spec_a.as_dict(), "frequency": fm.as_dict(),
            "regimes": [g.text() for g in regimes]})
    out["controller_model"] = controller_reference(ctx, ident)
    return out
