"""The gap scorer's statistics (``urident.gap.stats``) against the in-memory fits they replace.

The reference here is the former scorer, kept as a test: the stacked (6N, p) design matrices, G by
least squares, F = C − W·G explicitly, the blocked CV on per-sample arrays and the block bootstrap
of per-sample improvements. The statistics path must give the same coefficients, residuals, gains
and intervals, and keep no per-sample array of its own.
"""

from __future__ import annotations

import numpy as np
import pytest

from test_gap_diagnose import FAST, simulate, sines
from urident.gap.bootstrap import block_bootstrap_means, default_block_length, interval
from urident.gap.data import build_set
from urident.gap.residual import fit_baseline, make_context
from urident.gap.scoring import Scorer, lstsq
from urident.model import load_robot

EFFECT = ("effects:\n  - name: stribeck\n    joints: [2]\n    static_friction_ratio: 1.6\n"
          "    stribeck_velocity_rad_s: 0.03\n  - name: current_offset\n    joints: [4]\n"
          "    offset_a: 0.05\n")


@pytest.fixture(scope="module")
def pair():
    spec = load_robot("ur10e")
    ident = build_set([simulate(spec, sines(5), EFFECT, seed=31)], spec)
    valid = build_set([simulate(spec, sines(6, vmax=0.4), EFFECT, seed=32)], spec)
    model = fit_baseline(spec, ident)
    return spec, make_context(spec, model, ident), make_context(spec, model, valid)


def _dense(ctx):
    from urident.ident.design import design_matrix

    p = ctx.data.prepared
    return design_matrix(ctx.spec, ctx.model.model, p.q, p.qd, p.qdd, p.segment, p.t)


def _reference(ctx_i, ctx_v, selection, n_folds):
    """The former in-memory evaluation: validation residual (N, 6) and coefficients."""
    w_i, w_v = _dense(ctx_i), _dense(ctx_v)
    r = ctx_v.residual.copy()
    ident = [c for c in selection if c.mode == "ident"]
    cv = [c for c in selection if c.mode == "cv"]
    beta_i = np.zeros(0)
    if ident:
        g = [np.linalg.lstsq(w_i, c.features(ctx_i).reshape(-1, c.k), rcond=None)[0] for c in ident]
        f_id = np.hstack([c.features(ctx_i).reshape(-1, c.k) - w_i @ gc for c, gc in zip(ident, g)])
        f_va = np.hstack([c.features(ctx_v).reshape(-1, c.k) - w_v @ gc for c, gc in zip(ident, g)])
        beta_i = lstsq(f_id, ctx_i.residual.reshape(-1))
        r = r - (f_va @ beta_i).reshape(-1, 6)
    beta_c = np.zeros(0)
    if cv:
        n = ctx_v.n
        fold = np.minimum((np.arange(n) * n_folds) // n, n_folds - 1)
        feats = np.concatenate([c.features(ctx_v) for c in cv], axis=2)
        k = feats.shape[2]
        pred = np.zeros_like(r)
        for b in range(n_folds):
            train = fold != b
            pred[~train] = feats[~train] @ lstsq(feats[train].reshape(-1, k), r[train].reshape(-1))
        beta_c = lstsq(feats.reshape(-1, k), r.reshape(-1))
        r = r - pred
    return r, beta_i, beta_c


def _pool(spec, ctx_i, ctx_v):
    from urident.gap.candidates import current_offset, payload_error, stribeck, thermal_drift

    return [stribeck(1, 0.02), stribeck(1, 0.02, "cv"), current_offset(3), current_offset(3, "cv"),
            thermal_drift(2, "time"), payload_error(spec)]


def test_fits_from_statistics_equal_the_in_memory_fits(pair):
    spec, ctx_i, ctx_v = pair
    scorer = Scorer(ctx_i, ctx_v, FAST.n_folds)
    pool = _pool(spec, ctx_i, ctx_v)
    scorer.prepare(pool)
    for sel in ([pool[0]], [pool[1]], [pool[0], pool[3]], [pool[0], pool[2], pool[4], pool[5]], pool):
        fit = scorer.evaluate(sel)
        ref, beta_i, beta_c = _reference(ctx_i, ctx_v, sel, scorer.n_folds)
        assert np.allclose(fit.beta_ident, beta_i, rtol=1e-8, atol=1e-10), [c.name for c in sel]
        assert np.allclose(fit.beta_cv, beta_c, rtol=1e-8, atol=1e-10), [c.name for c in sel]
        scale = np.max(np.abs(ctx_v.residual))
        assert np.max(np.abs(fit.residual - ref)) < 1e-9 * scale, [c.name for c in sel]
        # the per-cell squared sums the scores use are those of the residual itself
        ss = fit.stats.valid.cell_ss(fit.u).sum(axis=0)
        assert np.allclose(ss, np.sum(ref ** 2, axis=0), rtol=1e-9)


def test_scores_equal_the_per_sample_gains_and_bootstrap(pair):
    from urident.gap.significance import score_all

    spec, ctx_i, ctx_v = pair
    block = default_block_length(ctx_v.n, ctx_v.data.sample_rate)
    scorer = Scorer(ctx_i, ctx_v, FAST.n_folds, block)
    pool = _pool(spec, ctx_i, ctx_v)
    current = scorer.evaluate([pool[0]])
    base = current.residual
    scores = score_all(scorer, current, [c for c in pool if c is not pool[0]], block, FAST)
    for s in scores:
        ref, _, _ = _reference(ctx_i, ctx_v, [pool[0], s.candidate], scorer.n_folds)
        d = np.sum(base ** 2 - ref ** 2, axis=1)
        assert s.gain == pytest.approx(d.mean(), rel=1e-8, abs=1e-12)
        lo, hi = interval(block_bootstrap_means(d, block, FAST.n_boot, FAST.seed), FAST.level)
        assert s.ci == pytest.approx((lo, hi), rel=1e-8, abs=1e-12)
        assert s.rms_after == pytest.approx(np.sqrt(np.mean(ref ** 2, axis=0)), rel=1e-9)
        assert s.change is None and s.d is None           # nothing per sample kept by a score
        s.materialize()
        assert np.allclose(s.change, base - ref, atol=1e-9 * np.max(np.abs(base)))


def test_the_design_kept_during_a_diagnosis_is_built_once_per_set_and_changes_no_number(monkeypatch):
    """A small set's design is built once (the identification set's for the baseline fit and
    its context alike) and reused by every later pass; streamed instead (sets above the byte
    budget) it is rebuilt each pass and the result is the same to the last bit."""
    import urident.gap.residual as residual
    import urident.ident.design as design
    from urident.gap import diagnose

    spec = load_robot("ur10e")
    ident = [simulate(spec, sines(5), EFFECT, seed=31)]
    valid = [simulate(spec, sines(6, vmax=0.4), EFFECT, seed=32)]
    calls = []
    real = design.design_chunks

    def counted(*args, **kw):
        calls.append(1)
        yield from real(*args, **kw)

    monkeypatch.setattr(design, "design_chunks", counted)
    kept = diagnose(ident, valid, spec, config=FAST)
    n_kept = len(calls)
    monkeypatch.setattr(residual, "DESIGN_CACHE_BYTES", 0)
    calls.clear()
    streamed = diagnose(ident, valid, spec, config=FAST)
    assert n_kept == 2 and len(calls) > 4, (n_kept, len(calls))
    assert kept.findings and kept.as_dict() == streamed.as_dict()


def test_a_diagnosis_keeps_no_design_matrix_and_no_feature_cache(pair):
    from urident.gap import diagnose

    spec = load_robot("ur10e")
    res = diagnose([simulate(spec, sines(5), EFFECT, seed=31)],
                   [simulate(spec, sines(6, vmax=0.4), EFFECT, seed=32)], spec, config=FAST)
    assert res.findings                       # the stribeck and offset effects are found
    assert res.ident.w is None and res.valid.w is None
    assert not res.ident.cache and not res.valid.cache
    reported = [s for step in res.steps for s in step if s.change is not None]
    assert len(reported) <= len(res.findings) + len(res.confounds) + 2 * len(res.steps)
