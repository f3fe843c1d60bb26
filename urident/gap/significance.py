"""Significance tests of a candidate scored on top of the current model.

Per-sample improvement d_k = Σ_j (r_kj² − r'_kj²) on held-out validation data and the same on the
candidate's own joint; the means get block bootstrap intervals (blocks of ~1 s). A candidate is
*significant* when the own joint's lower bound is > 0 and the summed improvement is positive
(``test="own"``; ``"total"``: the summed improvement's lower bound > 0), it shrinks its joint's
RMS by at least ``min_shrink_pct`` (counting no more than its correction's own energy:
:func:`own_shrink_pct`; in identification mode, when the identification logs hold it, on the
joint its refit mends most: :func:`spill_shrink_pct`), its coefficients are physically plausible (:func:`plausible`),
in identification mode its joint holds no more than ``ident_max_projection`` times its correction
along it (:func:`aligned`) and, in CV mode, its correction is material in absolute terms
(:func:`material_cv`). A CV-mode
candidate must also beat its identification-mode twin and not re-fit the spill of an
identification-mode candidate that passed every test but materiality (:func:`admissible`,
:func:`spill_of`).
"""

from __future__ import annotations

import numpy as np

from urident.gap.bootstrap import bootstrap_block_sums, interval
from urident.gap.candidates import Candidate
from urident.gap.config import GapConfig
from urident.gap.results import Score, rms
from urident.gap.scoring import Fit, Scorer


def score_all(scorer: Scorer, current: Fit, pool: list[Candidate], block: int,
              config: GapConfig) -> list[Score]:
    """Each candidate of ``pool`` added to ``current`` and scored on the held-out validation data
    with its significance tests (module doc), best gain first. Every sum over samples comes from
    the scorer's per-cell statistics (:mod:`urident.gap.stats`): nothing per sample is kept."""
    if not pool:
        return []
    sel = list(current.ident) + list(current.cv)
    st = scorer.stats_for(sel + list(pool), block, keep=True)
    base = current if current.stats is st else scorer.evaluate(sel, st)
    if base._residual is None and current._residual is not None:
        base._residual = current._residual
    vs = st.valid
    n = vs.n
    ss0 = vs.cell_ss(base.u)                                   # (S, 6)
    rms0 = np.sqrt(ss0.sum(axis=0) / n)
    rms_tau = rms(scorer.valid.tau)
    fits, d_cells, own_cells, rms1s, change_rms = [], [], [], [], []
    for c in pool:
        f = scorer.evaluate(sel + [c], st)
        ss1 = vs.cell_ss(f.u)
        d = (ss0 - ss1).sum(axis=1)
        crms = np.sqrt(vs.cell_ss(base.u - f.u).sum(axis=0) / n)
        fits.append(f)
        d_cells.append(d)
        # the same improvement on the candidate's own joint (all-joint candidates: the total)
        own_cells.append(ss0[:, c.joint] - ss1[:, c.joint] if c.joint is not None else d)
        rms1s.append(np.sqrt(np.maximum(ss1.sum(axis=0), 0.0) / n))
        change_rms.append(crms)
    sums = vs.block_sums(np.stack(d_cells + own_cells, axis=1))
    boot_all = bootstrap_block_sums(sums, vs.block_counts, config.n_boot, config.seed)
    boot, boot_own = boot_all[:, :len(pool)], boot_all[:, len(pool):]
    sigma = noise_sigma(scorer.valid.residual)
    out = []
    for i, (c, f) in enumerate(zip(pool, fits)):
        rms1 = rms1s[i]
        joint = c.joint if c.joint is not None else _largest_share(change_rms[i], rms_tau)
        lo, hi = interval(boot[:, i], config.level)
        s = Score(c, f, float(d_cells[i].sum() / n), (lo, hi), joint, rms0, rms1, False,
                  base=base, d_blocks=sums[:, i], block_counts=vs.block_counts, change_rms=change_rms[i])
        # own joint by default: a refit's collateral on the other joints can hide a clear gain on
        # the candidate's joint; the summed mean must still be > 0 (docs/gap-calibration.md)
        if config.test == "own":
            held_out = interval(boot_own[:, i], config.level)[0] > 0 and s.gain > 0
        else:
            held_out = lo > 0
        mat = own_shrink_pct(float(rms0[joint]), float(rms1[joint]), float(change_rms[i][joint]))
        if c.mode == "ident" and c.joint is not None and mat < config.min_shrink_pct:
            # its refit also mends the joints sharing the base parameters it distorted: that
            # counts when the identification logs hold the effect (docs/gap-calibration.md)
            spill = spill_shrink_pct(rms0, rms1, change_rms[i], joint, n, config.ident_max_projection)
            if spill >= config.min_shrink_pct and ident_shrink_pct(scorer, sel, c) >= config.min_shrink_pct:
                mat = spill
        valid = bool(held_out and plausible(c, f.coefficients()[c], _offset_on(f, c.joint))
                     and (c.mode != "ident" or aligned(n * float(rms0[joint] ** 2 - rms1[joint] ** 2), n,
                                                       float(change_rms[i][joint]),
                                                       config.ident_max_projection))
                     and (c.mode != "cv" or _material(float(change_rms[i][joint]), sigma[joint],
                                                      config.cv_min_noise_ratio)))
        s.significant = valid and mat >= config.min_shrink_pct
        s.short_of_floor = valid and not s.significant and c.mode == "ident"
        out.append(s)
    out.sort(key=lambda s: -s.gain)
    return out


def own_shrink_pct(rms0: float, rms1: float, crms: float) -> float:
    """The RMS shrink [%] of a joint (RMS ``rms0`` before, ``rms1`` after a correction whose RMS
    there is ``crms``) counting at most the correction's own energy c·c as removed: the
    materiality of a finding.

    Why: the energy removed is 2⟨r, c⟩ − ⟨c, c⟩; when the effect is the correction, ⟨r, c⟩ ≈
    ⟨c, c⟩ (:func:`aligned`). What it removes beyond ⟨c, c⟩ is residual the correction only points
    along (an identification-mode refit nudged towards the validation run's misfit): a correction
    of a fifth of the white noise then passed the 3 % floor on an effect-free scenario
    (docs/gap-calibration.md)."""
    if rms0 <= 0:
        return 0.0
    removed = min(rms0 ** 2 - rms1 ** 2, crms ** 2)
    return float(100.0 * (1.0 - np.sqrt(max(rms0 ** 2 - removed, 0.0)) / rms0))


def spill_shrink_pct(rms0, rms1, crms, joint: int, n: int, max_projection: float) -> float:
    """The largest :func:`own_shrink_pct` of a correction (per joint: RMS ``rms0`` before,
    ``rms1`` after, ``crms`` its own, over ``n`` samples) on a joint other than its own ``joint``
    where it passes :func:`aligned`, or 0.

    Why: an effect in the identification logs distorts the base parameters the joints share (a
    drive gain of joint 4 those of the parallel joints 2-4); its identification-mode candidate
    refits them, and its correction on the validation run lands mostly on the neighbours."""
    out = 0.0
    for k in range(len(rms0)):
        r0, r1, ck = float(rms0[k]), float(rms1[k]), float(crms[k])
        if k != joint and aligned(n * (r0 ** 2 - r1 ** 2), n, ck, max_projection):
            out = max(out, own_shrink_pct(r0, r1, ck))
    return out


def ident_shrink_pct(scorer, selected, c) -> float:
    """In-sample shrink [%] of the identification residual of ``c``'s joint by ``c`` refitted
    with the base parameters and the identification-mode ones of ``selected`` (the total
    reduction over the joints against that joint's sum of squares, as
    :func:`urident.gap.structure.identification_only` reads it)."""
    chosen = [o for o in selected if o.mode == "ident"]
    d = scorer.ident_ss(chosen) - scorer.ident_ss(chosen + [c])
    rr = float(np.sum(np.asarray(scorer.ident.residual, float)[:, c.joint] ** 2))
    return float(100.0 * (1.0 - np.sqrt(max(rr - d, 0.0) / rr))) if rr > 0 and d > 0 else 0.0


def admissible(s: Score, scores: list[Score], max_projection: float | None = None) -> bool:
    """A CV-mode candidate claims the effect changed between the runs; it must beat the same
    columns fitted on the identification logs (ident mode) where the catalogue has that mode,
    else it only re-fits what the identification got wrong; and it must not take the spill of
    another identification-mode candidate (:func:`spill_of`, ``max_projection``: the limit of
    :func:`aligned`, by default the configuration's)."""
    c = s.candidate
    if c.mode != "cv":
        return True
    if spill_of(s, scores, max_projection) is not None:
        return False
    twins = [o for o in scores if o.candidate.mode == "ident" and o.candidate.key == c.key]
    if not twins:
        return True
    twin = max(twins, key=lambda o: o.gain)
    return s.gain > twin.gain


def spill_of(s: Score, scores: list[Score], max_projection: float | None = None) -> Score | None:
    """The identification-mode score of ``scores`` (same step) whose residual a CV-mode ``s``
    would take, or None: one that passes every test but materiality (``short_of_floor``), has a
    larger held-out gain and mends ``s``'s joint, aligned there, by at least as much as ``s``.

    Why: an identification-mode candidate is fitted on other data; when the validation run
    confirms it (held out) but its own joint cannot size it (an effect in the identification logs
    that distorted the base parameters the joints share: its correction lands on the
    neighbours), a CV-mode effect fitted on a neighbour only re-fits that spill, the wrong cause
    (docs/gap-calibration.md)."""
    j = s.joint
    if s.rms_before is None or s.rms_after is None:
        return None
    if max_projection is None:
        max_projection = GapConfig().ident_max_projection
    mine = float(100.0 * (1.0 - s.rms_after[j] / s.rms_before[j])) if s.rms_before[j] > 0 else 0.0
    best = None
    for o in scores:
        if not o.short_of_floor or o.gain <= s.gain or o.change_rms is None or o.joint == j:
            continue
        r0, r1, ck = float(o.rms_before[j]), float(o.rms_after[j]), float(o.change_rms[j])
        if not aligned(r0 ** 2 - r1 ** 2, 1, ck, max_projection):
            continue
        if own_shrink_pct(r0, r1, ck) >= mine and (best is None or o.gain > best.gain):
            best = o
    return best


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
    The default 0.5 σ sits above what effect-free scenarios pass (docs/gap-calibration.md)."""
    return _material(float(np.sqrt(np.mean(np.asarray(change_j, float) ** 2))), sigma_j, ratio)


def aligned(removed: float, n: int, crms: float, max_projection: float) -> bool:
    """An identification-mode candidate's coefficients come from other data: when it is the
    effect, the validation residual holds about its correction c along it, ⟨r, c⟩/⟨c, c⟩ ≈ 1;
    far more means the correction only points along a larger misfit of the baseline (its refit
    of the base parameters nudged towards what the validation run prefers). From the removed
    energy Σr² − Σ(r − c)² = 2⟨r, c⟩ − ⟨c, c⟩ of the candidate's joint (docs/gap-calibration.md)."""
    cc = n * crms ** 2
    return max_projection <= 0 or cc <= 0 or (removed / cc + 1.0) / 2.0 <= max_projection


def _material(crms: float, sigma_j: float, ratio: float) -> bool:
    """:func:`material_cv` of a correction whose RMS on its joint is ``crms``."""
    return ratio <= 0 or crms >= ratio * float(sigma_j)


#: Payload findings need at least this fitted mass [kg] (a mass of ~0 with a few first-moment
#: terms is an identification error of body 6, not a payload).
MIN_PAYLOAD_KG = 0.1


#: The exact forms of a lag or a delay (the filtered or shifted model torque minus itself) have
#: coefficient 1 when they are the effect; far from it the column only stands in for dτ̂/dt.
UNIT_GAIN = (0.5, 2.0)


def unit_gain(c: Candidate) -> bool:
    """Whether ``c``'s coefficient should be 1 (:data:`UNIT_GAIN`): a lag, an exact-shift delay."""
    return c.effect == "current_lag" or (c.effect == "current_delay" and "delay_s" in c.settings)


def unit_gain_variants(fam: list, scorer) -> list:
    """``fam`` without the lag and exact-shift variants whose training coefficient
    (``scorer.training_beta``) is outside :data:`UNIT_GAIN`: such a fit uses the form as a
    stand-in for dτ̂/dt (a 2 ms lag scaled ×14 mimics an 8 ms delay), not as the effect."""
    def ok(c):
        b = scorer.training_beta(c) if unit_gain(c) else None
        return b is None or UNIT_GAIN[0] <= float(b[0]) <= UNIT_GAIN[1]
    return [c for c in fam if ok(c)]


def choose_variant(fam: list, scorer, selected=(), current=None) -> Candidate:
    """The variant of ``fam`` the diagnosis scores: the one that fits the identification data
    best (the validation data in CV mode), on top of the ``selected`` candidates (``current``:
    their fit) when given."""
    if len(fam) == 1:
        return fam[0]
    if current is None:
        return max(fam, key=scorer.training_gain)
    gains = scorer.gains_on_top(selected, current, fam)
    return fam[int(np.argmax(gains))]


def _offset_on(f: Fit, j: int | None) -> float | None:
    """The coefficient of a current offset on joint ``j`` among ``f``'s candidates, or None."""
    return next((float(b[0]) for o, b in f.coefficients().items()
                 if o.effect == "current_offset" and o.joint == j and j is not None), None)


def plausible(c: Candidate, beta: np.ndarray, offset: float | None = None) -> bool:
    """Sign and size constraints of the catalogue's physics on the fitted coefficients:
    Stribeck adds friction near zero velocity (or, beside an ``offset`` found on its joint, has
    that offset's sign: a Coulomb level that differs by direction and changes sign more sharply
    than tanh(q̇/ε), :func:`urident.gap.diagnose.offset_transition`), load friction grows with
    load, drag grows with speed, presliding
    friction holds (same sign as the motion before the stop), a delay is
    positive (its exact shift, like a lag, has a gain near 1: :data:`UNIT_GAIN`), an elastic joint has positive J/k, a payload has a mass (|m| >= MIN_PAYLOAD_KG,
    negative: a modelled payload removed) with its centre within 0.5 m of the tool point.
    Other effects may have either sign."""
    b = np.asarray(beta, float)
    if unit_gain(c):
        return bool(UNIT_GAIN[0] <= b[0] <= UNIT_GAIN[1])
    if c.effect == "stribeck" and offset is not None and b[0] * offset > 0:
        return True
    if c.effect in ("stribeck", "load_friction", "presliding", "quadratic_viscous", "neighbour_load_friction",
                    "current_lag"):
        return bool(b[0] > 0)
    if c.effect in ("current_delay", "joint_elasticity"):
        return bool(b[0] < 0)
    if c.effect == "payload_error":
        m = float(b[0])
        return bool(abs(m) >= MIN_PAYLOAD_KG and np.linalg.norm(b[1:4]) <= 0.5 * abs(m) + 1e-12)
    return True


def shares(change: np.ndarray, tau: np.ndarray) -> np.ndarray:
    rms_tau = rms(tau)
    return rms(change) / np.where(rms_tau > 0, rms_tau, np.inf)


def _largest_share(change_rms: np.ndarray, rms_tau: np.ndarray) -> int:
    """:func:`main_joint` from the RMS of the change and of the measured torque per joint."""
    return int(np.argmax(change_rms / np.where(rms_tau > 0, rms_tau, np.inf)))


def main_joint(change: np.ndarray, tau: np.ndarray) -> int:
    """The joint of an effect on all joints (payload_error): where its torque is the largest
    share of the joint's measured torque (RMS over RMS): the joint its significance is tested
    on. Its finding is reported on the joints it changes most in absolute torque
    (:func:`urident.gap.selection.changed_joints`)."""
    return int(np.argmax(shares(change, tau)))
