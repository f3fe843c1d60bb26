"""The diagnosis: where the baseline's residual lies, which catalogue effect explains it, how far
it shrinks.

1. Baseline (paper: OLS, tanh friction, ε = 0.01 rad/s) on the identification logs (or loaded);
   residual r = τ_measured − τ̂ on the validation logs, τ_measured = drive gains × raw current
   (:mod:`.residual`).
2. Where: per joint RMS and share of the residual energy; binned maps and spectra; the regimes
   where the energy concentrates (:mod:`.where`, :mod:`.maps`). Before that, time-localised
   events (contact, collisions, stalls: :mod:`.events`) are found and their samples set aside.
3. Which: every candidate of :mod:`.candidates` (per effect, joint and mode; per family the
   variant that fits the fitting data best) scored on held-out validation data
   (:mod:`.significance`) in a stepwise selection (:mod:`.selection`).
4. How far: validation RMS per joint and e_N before and after the selected effects
   (:class:`~.results.GapResult`).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from urident.gap.bootstrap import default_block_length
from urident.gap.candidates import families
from urident.gap.config import GapConfig
from urident.gap.data import GapSet, build_set
from urident.gap.events import find_events, smooth_basis, without_events
from urident.gap.residual import baseline_design, fit_baseline, make_context
from urident.gap.results import GapResult, e_n, rms
from urident.gap.scoring import Scorer
from urident.gap.selection import select
from urident.gap.significance import choose_variant, unit_gain_variants
from urident.gap.structure import identification_only
from urident.gap.where import describe_unexplained, describe_where
from urident.blas import one_blas_thread


#: A joint is at rest on the validation run when |q̇| < AT_REST_RAD_S on at least AT_REST_SHARE of
#: its samples (events set aside): no candidate on it is tested. Why 5 mrad/s: a joint creeping at
#: 15 mrad/s slides (its friction is determinate); a held joint shows a few mrad/s of encoder noise.
AT_REST_RAD_S = 0.005
AT_REST_SHARE = 0.9
AT_REST_REASON = ("the joint barely moves on the validation run: its friction at rest may take any "
                  "value within the static friction, so no effect on it can be told from that")


def joints_at_rest(qd) -> list[int]:
    """0-based joints whose velocity stays below :data:`AT_REST_RAD_S` on at least
    :data:`AT_REST_SHARE` of the samples ``qd`` (N, 6)."""
    share = np.mean(np.abs(np.asarray(qd, float)) < AT_REST_RAD_S, axis=0)
    return [int(j) for j in np.flatnonzero(share >= AT_REST_SHARE)]


def _corrections(current, ctx_v) -> list:
    """(candidate, (N, 6) its own columns × its coefficients on ``ctx_v``) of the fit ``current``
    (no refit collateral of the base parameters: the effect's own form)."""
    coef = current.coefficients()
    return [(c, c.features(ctx_v) @ coef[c]) for c in list(current.ident) + list(current.cv)]


def _same(f, c) -> bool:
    return (c.effect, c.variant, c.mode) == (f.effect, f.variant, f.mode) and (
        c.joint is None or c.joint + 1 == f.joint)


def _label(c) -> str:
    return f"{c.effect} ({c.variant})" if c.variant else c.effect


def offset_transition(f, own_j, findings) -> dict | None:
    """Whether a Stribeck finding ``f`` (its correction ``own_j`` (N,) on its joint) can be the
    transition of an offset found on the same joint: a Coulomb level that differs by direction by
    2·c reads as an offset c plus c·(sharper sign − tanh(q̇/ε)), a bump of the offset's sign that
    is nowhere taller than |c| (the sign's step is at most 1 above tanh). A Stribeck bump of the
    offset's sign whose largest correction stays within |c| is then no static friction of its own
    that the data could tell (the ``remains`` entry), else None."""
    fs = f.magnitude.get("extra_static_friction_nm")
    for g in findings:
        if g.effect != "current_offset" or g.joint != f.joint or fs is None:
            continue
        c = g.magnitude["offset_nm"]
        peak = float(np.max(np.abs(own_j))) if len(own_j) else 0.0
        if c * fs > 0 and peak <= abs(c):
            return {"axis": "the offset on the same joint", "offset_nm": float(c), "bump_peak_nm": peak,
                    "text": (f"its bump near zero velocity (at most {peak:.3g} N·m) has the sign of the "
                             f"offset on joint {f.joint} ({c:+.3g} N·m) and stays within it: together they "
                             f"are a Coulomb level that differs by direction (by about {2 * c:+.3g} N·m) "
                             f"and changes sign more sharply than tanh(q̇/ε), no static friction of its own")}
    return None


def claims(findings, final_r, ctx_v, config: GapConfig, current=None) -> list:
    """Each finding as a ``cause`` when its form fits, else ``partial`` with what its form leaves
    along its own axis (:func:`urident.gap.structure.form_left`) after all the findings. Also
    ``partial`` (``current``: the fit of the findings): a Stribeck bump that scales with another
    finding of its joint, that finding's sharper transition
    (:func:`urident.gap.structure.transition_of`), and a later finding on a joint that only mends
    an earlier one's form along the joint's velocity (:func:`urident.gap.structure.misfit_of`)."""
    from dataclasses import replace

    from urident.gap.significance import noise_sigma
    from urident.gap.structure import FRICTION_FORMS, form_left, misfit_of, transition_of, velocity_bins

    sigma = noise_sigma(final_r)
    corr = _corrections(current, ctx_v) if current is not None else []
    out = []
    for f in findings:
        j = f.joint - 1
        left = form_left(f.effect, j, final_r[:, j], ctx_v, float(sigma[j]), config.min_shrink_pct,
                         config.cv_min_noise_ratio)
        own = next((x for c, x in corr if _same(f, c)), None)
        if not left and f.effect == "stribeck" and own is not None:
            vs = f.magnitude["stribeck_velocity_rad_s"]
            near = np.exp(-(ctx_v.qd[:, j] / vs) ** 2)
            others = [(_label(c), x[:, j]) for c, x in corr if not _same(f, c) and c.joint == j]
            t = transition_of(own[:, j], final_r[:, j] + own[:, j], others, near, config.parsimony_tol)
            if t:
                left = {"axis": f"the correction of {t['of']}", "share_pct": t["scaled_pct"],
                        "text": (f"its bump near zero velocity scales with the correction of {t['of']} "
                                 f"(scaled: {t['scaled_pct']:.1f} % of the sum of squares, as a constant "
                                 f"static friction: {t['constant_pct']:.1f} %): that friction changes "
                                 f"sign more sharply than tanh(q̇/ε), no static friction of its own")}
            else:
                left = offset_transition(f, own[:, j], findings)
        earlier = [(_label(c), x[:, j]) for g in out if g.joint == f.joint and g.effect != "payload_error"
                   for c, x in corr if _same(g, c) and c.joint == j]
        # an earlier friction finding whose form the residual contradicts along the velocity: a
        # later one that the joint's friction curve, free per velocity bin, explains as well mends it
        earlier += [(_label(g), None) for g in out if g.joint == f.joint
                    and g.effect in FRICTION_FORMS and g.claim == "partial"
                    and str((g.remains or {}).get("axis", "")).startswith("velocity")]
        if not left and own is not None and earlier and f.effect != "payload_error":
            bins, axis = velocity_bins(j, ctx_v)
            m = misfit_of(own[:, j], final_r[:, j] + own[:, j], earlier, bins, config.parsimony_tol)
            if m:
                left = {"axis": f"the form of {m['of']} along the {axis}", "share_pct": m["scaled_pct"],
                        "text": (f"what it explains is the form misfit of {m['of']}: that finding scaled "
                                 f"per bin of the {axis} explains {m['scaled_pct']:.1f} % of the sum of "
                                 f"squares, this one {m['own_pct']:.1f} %; no cause of its own")}
        out.append(replace(f, claim="partial", remains=left) if left else f)
    return out


def diagnose(ident_recordings: Sequence, valid_recordings: Sequence, spec, *, params=None,
             drive_gains=None, config: GapConfig | None = None, preprocess=None,
             payload=None) -> GapResult:
    """Diagnose from recordings only (``urident.logs.Recording``) and the robot ``spec``.
    ``params``: a baseline IdentifiedModel (e.g. from ``load_params``) instead of identifying it;
    ``payload``: a known tool on the flange (its torque is removed from the measured torque)."""
    config = config or GapConfig()
    if drive_gains is None and params is not None:
        drive_gains = params.drive_gains
    ident = build_set(ident_recordings, spec, drive_gains, preprocess, "identification logs", params, payload)
    valid = build_set(valid_recordings, spec, drive_gains, preprocess, "validation logs", params, payload)
    return diagnose_prepared(spec, ident, valid, params=params, config=config)


def diagnose_prepared(spec, ident: GapSet, valid: GapSet, *, params=None,
                      config: GapConfig | None = None) -> GapResult:
    # one BLAS thread: the diagnosis makes thousands of small products and factorisations, where
    # a second OpenBLAS thread mostly spins (docs/scale.md: 2-4x the wall time on a loaded host)
    with one_blas_thread():
        return _diagnose_prepared(spec, ident, valid, params, config or GapConfig())


def _diagnose_prepared(spec, ident: GapSet, valid: GapSet, params, config: GapConfig) -> GapResult:
    design = None     # the identification set's design: built once for the fit and the context
    if params is None:
        design = baseline_design(spec, ident, config.friction_eps)
        model = fit_baseline(spec, ident, config.friction_eps, design)
    else:
        model = params
    ctx_i = make_context(spec, model, ident, keep_design=True, design=design)
    ctx_v = make_context(spec, model, valid, keep_design=True)
    n_valid = ctx_v.n
    events = find_events(ctx_v.residual, valid.run_time, valid.prepared.qd, valid.sample_rate,
                         smooth_basis(ctx_v, spec))
    if events:
        # contact, collisions, stalls: no effect of the arm; set aside from fits, scores and maps
        valid = without_events(valid, events)
        ctx_v = make_context(spec, model, valid, keep_design=True)
    block = default_block_length(ctx_v.n, valid.sample_rate * config.block_s)
    scorer = Scorer(ctx_i, ctx_v, config.n_folds, block)
    r0 = ctx_v.residual
    where = describe_where(ctx_v, ctx_i)

    fams = families(spec, ctx_i, ctx_v, config.effects)
    rest = joints_at_rest(ctx_v.qd)
    if rest:
        # friction at rest takes any value within ± the static friction: nothing that acts on a
        # joint that does not move can be told from it (a pushed arm holding its pose)
        fams = [f for f in fams if (f[0].joint not in rest if f[0].joint is not None else len(rest) < 6)]
        where["at_rest"] = {"joints": [j + 1 for j in rest], "reason": AT_REST_REASON}
    scorer.prepare_gains(fams)
    fams = [unit_gain_variants(f, scorer) for f in fams]
    fams = [f for f in fams if f]
    pool = [choose_variant(f, scorer) for f in fams]
    scorer.prepare(pool)

    findings, steps, confounds, current = select(scorer, pool, block, config, ctx_v, spec, families=fams)
    final_r = current.residual
    findings = claims(findings, final_r, ctx_v, config, current)
    # the last step scored the pool as the selection left it (variants chosen again on top)
    ident_only = identification_only(scorer, [s.candidate for s in steps[-1]], list(current.ident)
                                     + list(current.cv), steps[-1], config.min_shrink_pct)
    where["unexplained"] = describe_unexplained(ctx_v, final_r, min_shrink_pct=config.min_shrink_pct,
                                                noise_ratio=config.cv_min_noise_ratio,
                                                ident_structure=ident_only)   # beyond the catalogue
    for ctx in (ctx_i, ctx_v):
        ctx.cache.clear()              # the result keeps no design matrix (bounded memory)
    return GapResult(spec.name, model, ctx_i, ctx_v, e_n(r0), rms(r0), e_n(final_r), rms(final_r),
                     findings, current, steps, confounds, where, config, scorer, events, n_valid)
