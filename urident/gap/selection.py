"""Stepwise selection of the catalogue effects that explain the residual.

Greedy forward selection: every candidate of the pool is scored on top of the current model
(:func:`urident.gap.significance.score_all`); the best significant one is kept and the others are
tested again on top, until none is significant (or ``max_effects``). Phase A first makes the
identification consistent (identification-mode candidates short-listed by their in-sample gain,
:func:`ident_shortlist`; when none is significant alone, a pair significant each on top of the
other, :func:`masked_pair`); phase B takes any candidate by its held-out gain (an
identification-mode one under the floor on its own joint when a CV-mode one would otherwise take
its spill on a neighbour: :func:`urident.gap.significance.spill_of`; the backward step keeps it
while it fails only materiality). None at the first
step: "no unmodelled effect found". Then the backward half (:func:`backward`): each chosen effect is
tested again on top of the others; those no longer significant are dropped, and the findings are
ordered by their unique contribution; an identification-mode finding whose ties the validation
run could not tell apart keeps the one the identification logs fit best (:func:`settle_ties`).

Confounds: a candidate of another effect (or joint) whose correction correlates with the chosen
one's (uncentred) by |ρ| ≥ ``confound_corr`` and whose improvement interval overlaps the chosen
one's is reported as confounded with it (:func:`confounded`); when such a candidate has fewer
columns and a held-out gain the data cannot tell from the chosen one's, it is chosen instead
(:func:`simplest_equivalent`).
"""

from __future__ import annotations

import numpy as np

from urident.gap.bootstrap import block_bootstrap_means, bootstrap_block_sums, interval
from urident.gap.candidates import Candidate
from urident.gap.config import GapConfig
from urident.gap.residual import SetContext
from urident.gap.results import Finding, Score, rms
from urident.gap.scoring import Fit, Scorer
from urident.gap.significance import admissible, choose_variant, noise_sigma, score_all, spill_of
from urident.gap.structure import FRICTION_FORMS
from urident.gap.where import finding_regime


def select(scorer: Scorer, pool: list[Candidate], block: int, config: GapConfig, ctx_v: SetContext,
           spec, prefer=None, families=None) -> tuple[list[Finding], list[list[Score]], list[dict], Fit]:
    """Forward, then backward selection over ``pool`` (module doc): the findings, every step's
    scores, the confound rows and the fit of the selected candidates. ``prefer(candidate)``: in
    phase B, a significant preferred candidate is taken before any other. ``families``: each pool
    member's family (same order); after a friction finding, the other friction families on its
    joint choose their variant again on top of the findings (a Stribeck velocity chosen against
    the bare residual mimics the sharp transition a presliding finding then takes)."""
    fam_of = {id(c): f for c, f in zip(pool, families)} if families is not None else {}
    selected: list[Candidate] = []
    findings: list[Finding] = []
    steps: list[list[Score]] = []
    confounds: list[dict] = []
    current = scorer.evaluate([])
    consistent = False          # phase A (identification consistency) over
    ties: dict = {}             # id of a finding → its identification-mode ties
    spilled: set = set()        # ids of identification-mode candidates material by spill_of
    for step in range(config.max_effects + 1):
        taken = {c.key for c in selected}
        free = [c for c in pool if c.key not in taken]
        scores = score_all(scorer, current, free, block, config)
        steps.append(scores)
        if len(selected) >= config.max_effects:
            break
        best = None
        taking: list[tuple[Score, list[Score]]] = []
        if not consistent:
            # A: an effect present in the identification logs distorts the base parameters and
            # spreads its error over other joints of the validation logs, where a CV-mode
            # effect (an offset "of the day", a payload) would explain it. So first make the
            # identification consistent: short-list the identification-mode candidates by how
            # much they reduce the identification residual on top of those already chosen,
            # and keep the one the validation logs confirm (significant held-out gain).
            shortlist = ident_shortlist(scorer, selected, free, config)
            short = {id(c) for c in shortlist}
            sig = [s for s in scores if s.significant and id(s.candidate) in short]
            if sig:
                best = max(sig, key=lambda s: s.gain)
            else:
                # two effects in the identification logs bias each other's fit alone (each
                # absorbs part of the other's distortion of the base parameters): a pair, each
                # significant on top of the other, is taken at once
                pair = masked_pair(scorer, selected, shortlist, free, block, config) \
                    if len(selected) + 2 <= config.max_effects else None
                if pair:
                    taking = [(s, []) for s in pair]
                else:
                    consistent = True
        if best is None and not taking:
            # B: any candidate (identification or CV mode) by its held-out gain alone
            mp = config.ident_max_projection
            sig = [s for s in scores if s.significant and admissible(s, scores, mp)]
            # an identification error whose spill a CV-mode effect would take is the finding
            # instead: the neighbour's residual it mends is real structure (spill_of)
            spills = [spill_of(s, scores, mp) for s in scores if s.significant and s.candidate.mode == "cv"]
            spills = [o for o in spills if o is not None]
            spilled.update(id(o.candidate) for o in spills)
            sig += [o for o in spills if o not in sig]
            if not sig:
                break
            preferred = [s for s in sig if prefer is not None and prefer(s.candidate)]
            best = max(preferred or sig, key=lambda s: s.gain)
        if best is not None:
            conf = confounded(best, scores, block, config)
            simpler = simplest_equivalent(best, conf, scores, block, config)
            if simpler is not best:
                best = simpler
                conf = confounded(best, scores, block, config)
            taking = [(best, conf)]
            ties[id(best.candidate)] = identification_ties(best, conf, scores, block, config)
        for chosen, conf in taking:
            confounds += confound_rows(step, chosen, conf)
            findings.append(make_finding(chosen.materialize(), conf, ctx_v, spec, config))
            selected.append(chosen.candidate)
        current = taking[-1][0].fit if len(taking) == 1 else scorer.evaluate(selected)
        for chosen, _ in taking:
            j = chosen.candidate.joint
            if fam_of and j is not None and chosen.candidate.effect in FRICTION_FORMS:
                taken = {c.key for c in selected}
                again = []
                for c in pool:
                    fam = fam_of[id(c)]
                    new = c if c.key in taken or c.joint != j or c.effect not in FRICTION_FORMS \
                        else choose_variant(fam, scorer, selected, current)
                    fam_of[id(new)] = fam
                    again.append(new)
                pool = again

    kept = backward(scorer, selected, block, config, spilled) if len(selected) > 1 else list(selected)
    kept = settle_ties(scorer, kept, ties, block, config)
    if kept:
        pool = pool + [c for c in kept if c not in pool]
        if [id(c) for c in kept] != [id(c) for c in selected]:
            # findings and confounds again, step by step in the kept order
            findings, confounds, current = [], [], scorer.evaluate([])
            for step, c in enumerate(kept):
                done = {o.key for o in kept[:step]}
                scores = score_all(scorer, current, [o for o in pool if o.key not in done], block, config)
                s = next(x for x in scores if x.candidate is c)
                conf = confounded(s, scores, block, config)
                confounds += confound_rows(step, s, conf)
                findings.append(make_finding(s.materialize(), conf, ctx_v, spec, config))
                current = s.fit

    return findings, steps, confounds, current


def confound_rows(step: int, chosen: Score, conf: list[Score]) -> list[dict]:
    """The report's rows for the candidates confounded with ``chosen`` at 0-based ``step``."""
    return [{"step": step + 1, "chosen": label(chosen), "alternative": label(other),
             "correlation": float(score_corr(chosen, other)), "gain_nm2": [chosen.gain, other.gain]}
            for other in conf]


def masked_pair(scorer: Scorer, selected: list[Candidate], shortlist: list[Candidate], free: list[Candidate],
                block: int, config: GapConfig) -> list[Score] | None:
    """Two identification-mode candidates, one of the ``shortlist``, each significant on top of
    the ``selected`` ones and the other (the tests of :func:`score_all`, as in the backward step),
    the pair with the largest gain together; their scores (each on top of the other), the larger
    first, or None.

    Why: an effect fitted alone on identification logs that hold another one absorbs part of the
    other's distortion of the base parameters; its coefficient is biased and the validation
    residual holds far more than its correction along it (:func:`urident.gap.significance.aligned`
    fails for both; seen: an offset of joint 4 with load friction of joint 3, each 2-3 times its
    correction alone, 0.9 together, docs/gap-calibration.md). Forward selection one effect at a
    time cannot take either."""
    alone = {id(s.candidate): s.gain for s in score_all(scorer, scorer.evaluate(selected), shortlist, block, config)}
    best, best_gain = None, 0.0
    for a in shortlist:
        others = [c for c in free if c.mode == "ident" and c.key != a.key]
        for sb in score_all(scorer, scorer.evaluate(selected + [a]), others, block, config):
            if not sb.significant or sb.gain <= 0:
                continue
            sa = score_all(scorer, scorer.evaluate(selected + [sb.candidate]), [a], block, config)[0]
            if sa.significant:
                total = alone[id(a)] + sb.gain
                if total > best_gain:
                    best, best_gain = sorted([sa, sb], key=lambda s: -s.gain), total
                break                       # scores are sorted: the largest valid partner of a
    return best


def backward(scorer: Scorer, selected: list[Candidate], block: int, config: GapConfig,
             spilled=frozenset()) -> list[Candidate]:
    """The backward half of stepwise selection, on the forward pass's choices: each chosen effect
    is tested again on top of all the others (same tests as when it was chosen); the weakest one
    that is no longer significant is dropped, until all are. The kept ones are returned ordered
    by that unique contribution, largest first. Why: a wrong joint can win the first forward step
    by a hair (docs/gap-calibration.md)."""
    kept = list(selected)
    while True:
        tests = []
        for c in kept:
            rest = scorer.evaluate([o for o in kept if o is not c])
            tests.append(score_all(scorer, rest, [c], block, config)[0])
        weakest = min(tests, key=lambda s: s.gain)
        if len(kept) == 1 or weakest.significant or (weakest.short_of_floor and id(weakest.candidate) in spilled):
            return [s.candidate for s in sorted(tests, key=lambda s: -s.gain)]
        kept.remove(weakest.candidate)


def ident_shortlist(scorer: Scorer, selected: list[Candidate], free: list[Candidate],
                    config: GapConfig) -> list[Candidate]:
    """Identification-mode candidates whose in-sample reduction of the identification residual
    (jointly with the identification-mode effects already chosen) is at least
    ``shortlist_ratio`` of the best one's, at most ``shortlist_size`` of them."""
    chosen = [c for c in selected if c.mode == "ident"]
    ss0 = scorer.ident_ss(chosen)
    gains = []
    for c in free:
        if c.mode != "ident":
            continue
        gains.append((ss0 - scorer.ident_ss(chosen + [c]), c))
    if not gains:
        return []
    gains.sort(key=lambda g: -g[0])
    top = gains[0][0]
    if top <= 0:
        return []
    return [c for g, c in gains[:config.shortlist_size] if g >= config.shortlist_ratio * top]


def simplest_equivalent(best: Score, conf: list[Score], scores: list[Score], block: int,
                        config: GapConfig) -> Score:
    """Among ``best`` and the candidates confounded with it (:func:`confounded`) that are
    significant and admissible, the one with the fewest fitted columns whose held-out gain the data
    does not tell from ``best``'s in practice: the paired block-bootstrap interval of the
    per-sample difference of their improvements contains 0, or the alternative keeps at least
    1 − ``parsimony_tol`` of ``best``'s gain. Equal column counts keep the larger gain, so
    ``best`` stays unless a simpler explanation is as good (those of equal columns:
    :func:`identification_ties`).

    Why: the larger one's extra columns also soak up the baseline's own misfit (Occam; the
    confound is still reported either way; docs/gap-calibration.md)."""
    equal = _equivalent(best, [s for s in conf if s.candidate.k < best.candidate.k], scores, block, config)
    if not equal:
        return best
    return min(equal, key=lambda s: (s.candidate.k, -s.gain))


def identification_ties(best: Score, conf: list[Score], scores: list[Score], block: int,
                        config: GapConfig) -> list[Candidate]:
    """The identification-mode candidates confounded with an identification-mode ``best`` that
    have as many columns and a held-out gain the data does not tell from its own (the test of
    :func:`simplest_equivalent`), significant or not on top of the findings so far (one may be
    significant only once the later ones are fitted): the validation run cannot choose among them
    (:func:`settle_ties` lets the identification logs do it, and tests the one it keeps)."""
    if best.candidate.mode != "ident":
        return []
    same = [s for s in conf if s.candidate.mode == "ident" and s.candidate.k == best.candidate.k]
    return [s.candidate for s in _equivalent(best, same, scores, block, config, significant=False)]


def _equivalent(best: Score, alts: list[Score], scores: list[Score], block: int,
                config: GapConfig, significant: bool = True) -> list[Score]:
    """The admissible ones of ``alts`` (and ``significant`` ones) whose held-out gain the data
    does not tell from ``best``'s (:func:`simplest_equivalent`)."""
    alts = [s for s in alts if (s.significant or not significant)
            and admissible(s, scores, config.ident_max_projection)]
    if not alts:
        return []
    if best.d_blocks is not None and all(s.d_blocks is not None for s in alts):
        diffs = np.stack([best.d_blocks - s.d_blocks for s in alts], axis=1)   # block sums
        boot = bootstrap_block_sums(diffs, best.block_counts, config.n_boot, config.seed)
    else:
        diffs = np.stack([best.d - s.d for s in alts], axis=1)
        boot = block_bootstrap_means(diffs, block, config.n_boot, config.seed)
    return [s for i, s in enumerate(alts) if interval(boot[:, i], config.level)[0] <= 0
            or s.gain >= (1.0 - config.parsimony_tol) * best.gain]


def settle_ties(scorer: Scorer, kept: list[Candidate], ties: dict, block: int,
                config: GapConfig) -> list[Candidate]:
    """``kept`` with each identification-mode finding that had ties (``ties``: id → the
    candidates of :func:`identification_ties`) replaced by the one of them whose refit, with the
    other kept identification-mode findings, leaves the smallest identification residual, when
    that one is still significant on top of the other findings.

    Why: an identification-mode effect claims to act in the identification logs, where it was
    fitted with as many columns as its ties; when the held-out data cannot tell them apart (a
    drive-gain error of joint 3 or of its parallel neighbour 2), those logs can, once the other
    effects they hold are fitted too (alone, another effect there can favour the wrong one;
    docs/gap-calibration.md)."""
    out = list(kept)
    for i, c in enumerate(kept):
        alts = ties.get(id(c))
        if not alts:
            continue
        others = [o for o in out if o is not c]
        chosen = [o for o in others if o.mode == "ident"]
        taken = {o.key for o in others}
        options = [c] + [a for a in alts if a.key not in taken]
        pick = min(options, key=lambda x: scorer.ident_ss(chosen + [x]))
        if pick is not c and score_all(scorer, scorer.evaluate(others), [pick], block, config)[0].significant:
            out[i] = pick
    return out


def label(s: Score) -> str:
    c = s.candidate
    return f"{c.effect} on joint {s.joint + 1}" + (f" ({c.variant})" if c.variant else "")


def corr(a: np.ndarray, b: np.ndarray) -> float:
    """Uncentred correlation (cosine) of two corrections: regression columns have no intercept,
    so a constant and a nearly constant correction are the same explanation."""
    a = a.reshape(-1)
    b = b.reshape(-1)
    den = np.sqrt((a @ a) * (b @ b))
    return float(a @ b / den) if den > 0 else 0.0


def score_corr(a: Score, b: Score) -> float:
    """:func:`corr` of two scores' corrections, from the scorer's statistics when both were
    scored on the same ones (no per-sample series needed)."""
    fa, fb = a.fit, b.fit
    same = (fa is not None and fb is not None and a.base is not None and b.base is not None
            and fa.stats is not None and fa.stats is fb.stats and a.base.stats is fa.stats
            and b.base.stats is fa.stats)
    if not same:
        return corr(a.materialize().change, b.materialize().change)
    vs = fa.stats.valid
    da, db = a.base.u - fa.u, b.base.u - fb.u
    den = np.sqrt(vs.cross(da, da) * vs.cross(db, db))
    return float(vs.cross(da, db) / den) if den > 0 else 0.0


def confounded(best: Score, scores: list[Score], block: int, config: GapConfig) -> list[Score]:
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
        if abs(score_corr(best, s)) < config.confound_corr:
            continue
        seen.add(key)
        out.append(s)
    return out


def make_finding(best: Score, conf: list[Score], ctx: SetContext, spec,
                 config: GapConfig | None = None) -> Finding:
    """The report's finding of ``best``. An effect on all joints (payload_error) is reported on
    every joint it changes (:func:`changed_joints`), ordered by the torque it explains there;
    its ``joint`` (and the RMS and shrink figures) is the first of them, the most affected."""
    c = best.candidate
    j = best.joint
    lo, hi = best.ci
    labels = tuple(label(s) for s in conf)
    if labels:
        confidence = "confounded"
    else:
        z = best.gain / max((hi - lo) / (2 * 1.96), 1e-300)
        confidence = "high" if (z > 4 and best.shrink_pct >= 10) else "medium"
    coef = best.fit.coefficients()[c]
    torque = rms(best.change)
    joints = (j,)
    if c.joint is None:
        ratio = (config or GapConfig()).cv_min_noise_ratio
        joints = changed_joints(best.change, noise_sigma(ctx.residual), ratio) or (j,)
        j = joints[0]
    regime = finding_regime(best, ctx, j)
    before, after = best.rms_before, best.rms_after
    shrink = [float(100.0 * (1.0 - after[k] / before[k])) if before[k] > 0 else 0.0 for k in joints]
    return Finding(j + 1, c.effect, c.variant, c.mode, regime, float(before[j]), float(after[j]),
                   shrink[0], confidence, (lo, hi), c.magnitude(coef, spec),
                   labels, tuple(k + 1 for k in joints), tuple(float(torque[k]) for k in joints),
                   tuple(shrink))


def changed_joints(change: np.ndarray, sigma: np.ndarray, ratio: float) -> tuple[int, ...]:
    """0-based joints where a correction ``change`` (N, 6) has an RMS of at least ``ratio`` times
    the joint's white-noise torque ``sigma``, ordered by that RMS (absolute torque explained),
    largest first. Why absolute torque: a payload's largest *relative* shrink is on a wrist joint
    whose torque is small; the joints it loads most are the shoulder and elbow."""
    t = rms(change)
    keep = [k for k in np.argsort(-t, kind="stable") if t[k] > 0 and t[k] >= ratio * sigma[k]]
    return tuple(int(k) for k in keep)
