"""Identification in bounded memory: the chunked regressor and its reduced (TSQR) form give the
in-memory path's estimates, σ, training RMS, e_N, cross-validation scores and predictions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from shared_data import UR10E_DATA
from urident.ident import ModelConfig, PreprocessConfig, identify_all, predict, prepare
from urident.ident.crossval import cross_validate
from urident.ident.design import (base_for, column_names, design_blocks, design_chunks, design_matrix,
                                  nonnegative_mask)
from urident.ident.estimate_bounded import estimate_bounded, estimate_bounded_reduced
from urident.ident.estimate_consistent import estimate_consistent, estimate_consistent_reduced
from urident.ident.estimate_ols import estimate_ols, estimate_ols_reduced, solve_ls, solve_reduced
from urident.ident.metrics import error_metrics
from urident.ident.preprocess import Prepared
from urident.ident.reduced import Accumulator, from_stacked, merge, reduce_design
from urident.ident.synthetic import synthetic_recording
from urident.logs import load_log
from urident.model import load_robot

REPO = Path(__file__).resolve().parent.parent
UR10E_IDENT = UR10E_DATA / "ur-20_02_10-30sec_12harm.csv"
# the SDP's solution is defined to the interior-point solver's tolerance (Clarabel, ≈ 1e-8): on the
# synthetic two-segment case a rounding-level change of its data moved it by 1.0e-9 (the shipped
# examples: ≤ 4e-11, held to 1e-9 below); least squares are held to 1e-9 everywhere
TOL = {"ols": 1e-9, "bounded": 1e-9, "consistent": 1e-7}


def rel(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - b)) / np.max(np.abs(b)))


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


@pytest.fixture(scope="module")
def two_segments(ur5):
    """Two synthetic recordings as one data set (two segments), noisy torques."""
    parts = []
    for seed in (4, 5):
        rec, qdd, _ = synthetic_recording(ur5, duration_s=6.0, rate_hz=125.0, current_noise_a=0.05, seed=seed)
        parts.append(Prepared(rec.t, rec.q, rec.qd, qdd, rec.current * ur5.drive_gains, ur5.drive_gains))
    seg = np.r_[np.zeros(len(parts[0])), np.ones(len(parts[1]))].astype(int)
    cat = lambda n: np.concatenate([getattr(p, n) for p in parts])  # noqa: E731
    return Prepared(cat("t"), cat("q"), cat("qd"), cat("qdd"), cat("tau"), ur5.drive_gains, (), seg)


@pytest.mark.parametrize("model", [ModelConfig(), ModelConfig(coulomb="dahl", extras=("dahl", "stribeck")),
                                   ModelConfig(coulomb="hold", extras=("load", "offset")),
                                   ModelConfig(coulomb="dahl", dahl_source="velocity", dahl_rad=3e-3)])
def test_design_chunks_equal_whole_regressor(ur5, two_segments, model):
    d = two_segments
    whole = design_blocks(ur5, model, d.q, d.qd, d.qdd, d.segment, d.t)
    pieces = np.full_like(whole, np.nan)
    covered = []
    for a, b, blocks in design_chunks(ur5, model, d.q, d.qd, d.qdd, d.segment, d.t, chunk=97):
        assert b - a <= 97 and len(set(d.segment[a:b])) == 1   # bounded, never across a seam
        pieces[a:b] = blocks
        covered.append((a, b))
    assert covered[0][0] == 0 and covered[-1][1] == len(d)
    np.testing.assert_allclose(pieces, whole, rtol=1e-12, atol=1e-12 * np.abs(whole).max())


@pytest.mark.parametrize("weighting", ["none", "joint"])
def test_reduced_estimates_equal_in_memory(ur5, two_segments, weighting):
    d = two_segments
    model = ModelConfig(extras=("stribeck",))
    w = design_matrix(ur5, model, d.q, d.qd, d.qdd, d.segment, d.t)
    y = d.tau.reshape(-1)
    red = reduce_design(ur5, model, d, chunk=250)
    names = column_names(ur5, model)
    nn = nonnegative_mask(ur5, model)
    b = base_for(ur5, model.reduced)
    pairs = [(estimate_ols(w, y, names, weighting), estimate_ols_reduced(red, names, weighting)),
             (estimate_bounded(w, y, names, nn, weighting), estimate_bounded_reduced(red, names, nn, weighting)),
             (estimate_consistent(w, y, names, b.combination, ur5.nominal_params, nn[b.n_base:], weighting),
              estimate_consistent_reduced(red, names, b.combination, ur5.nominal_params, nn[b.n_base:], weighting))]
    for ref, got in pairs:
        tol = TOL[ref.method]
        assert rel(got.values, ref.values) < tol, ref.method
        assert rel(got.sigma, ref.sigma) < tol, ref.method
        assert rel(got.train_rms, ref.train_rms) < tol
        assert got.train_e_n == pytest.approx(ref.train_e_n, rel=tol)
        assert got.noise_var == pytest.approx(ref.noise_var, rel=tol)
        np.testing.assert_allclose(got.weights, ref.weights, rtol=1e-9)
    # training figures are those of metrics.error_metrics on the whole residual
    e_n, rms = error_metrics((w @ pairs[0][1].values - y).reshape(-1, 6))
    assert pairs[0][1].train_e_n == pytest.approx(e_n, rel=1e-9)


def test_merge_equals_one_accumulation(ur5, two_segments):
    d = two_segments
    model = ModelConfig()
    whole = reduce_design(ur5, model, d)
    half = len(d) // 2
    parts = [reduce_design(ur5, model, d.select(slice(0, half))),
             reduce_design(ur5, model, d.select(slice(half, None)))]
    x = solve_reduced(whole)
    merged = merge(parts)
    assert merged.n_samples == whole.n_samples
    np.testing.assert_allclose(merged.residual_sq(x), whole.residual_sq(x), rtol=1e-10)
    assert rel(solve_reduced(merged), x) < 1e-10


def test_accumulator_refuses_nan():
    from urident.errors import ConfigError

    acc = Accumulator()
    blocks = np.ones((3, 6, 2))
    blocks[1, 2, 0] = np.nan
    with pytest.raises(ConfigError, match="NaN"):
        acc.add(blocks, np.zeros((3, 6)))


def _cv_in_memory(spec, data, model, weighting, method, folds, target):
    """The whole-regressor blocked CV (the reference the reduced one must reproduce)."""
    w = design_matrix(spec, model, data.q, data.qd, data.qdd, data.segment, data.t)
    y = data.tau.reshape(-1)
    yt = np.asarray(target, float).reshape(-1)
    n = len(data)
    edges = np.linspace(0, n, folds + 1).astype(int)
    names = [str(k) for k in range(w.shape[1])]
    err = np.zeros((n, 6))
    for k in range(folds):
        rows = np.repeat((np.arange(n) >= edges[k]) & (np.arange(n) < edges[k + 1]), 6)
        if method == "bounded":
            est = estimate_bounded(w[~rows], y[~rows], names, nonnegative_mask(spec, model), weighting)
        else:
            est = estimate_ols(w[~rows], y[~rows], names, weighting)
        err[rows.reshape(-1, 6)[:, 0]] = (w[rows] @ est.values - yt[rows]).reshape(-1, 6)
    return error_metrics(err)[1]


@pytest.mark.parametrize("method,weighting", [("ols", "none"), ("ols", "joint"), ("bounded", "none")])
def test_cross_validation_on_reduced_form_equals_in_memory(ur5, two_segments, method, weighting):
    d = two_segments
    model = ModelConfig(coulomb="dahl", dahl_rad=3e-3)
    target = d.tau + np.random.default_rng(0).normal(0, 0.1, d.tau.shape)  # scored against another torque
    got = cross_validate(ur5, d, model, weighting, method, folds=4, target=target)
    ref = _cv_in_memory(ur5, d, model, weighting, method, 4, target)
    np.testing.assert_allclose(got.rms_nm, ref, rtol=1e-9)


def test_identify_and_predict_bounded_memory_path_equal_in_memory(ur5, two_segments):
    d = two_segments
    model = ModelConfig(coulomb="hold")
    got = identify_all(ur5, d, ("ols",), model)["ols"]
    w = design_matrix(ur5, model, d.q, d.qd, d.qdd, d.segment, d.t)
    ref = estimate_ols(w, d.tau.reshape(-1), column_names(ur5, model))
    assert rel(got.values, ref.values) < 1e-9
    pred = predict(got, ur5, d.q, d.qd, d.qdd, d.segment, d.t)
    np.testing.assert_allclose(pred, (w @ got.values).reshape(-1, 6), rtol=1e-12,
                               atol=1e-12 * np.abs(pred).max())


def test_sample_logs_identify_equal_in_memory():
    spec = load_robot("ur5")
    data = prepare([load_log(REPO / "logs" / "sample_ident.csv")], spec)
    model = ModelConfig()
    got = identify_all(spec, data, ("ols", "bounded", "consistent"), model)
    w = design_matrix(spec, model, data.q, data.qd, data.qdd, data.segment, data.t)
    y = data.tau.reshape(-1)
    names = column_names(spec, model)
    b = base_for(spec, False)
    nn = nonnegative_mask(spec, model)
    refs = {"ols": estimate_ols(w, y, names), "bounded": estimate_bounded(w, y, names, nn),
            "consistent": estimate_consistent(w, y, names, b.combination, spec.nominal_params, nn[b.n_base:])}
    for m, ref in refs.items():   # the shipped example: every method to 1e-9 (measured: ≤ 2e-13)
        assert rel(got[m].values, ref.values) < 1e-9, m
        assert rel(got[m].sigma, ref.sigma) < 1e-9, m
        assert got[m].train_e_n == pytest.approx(ref.train_e_n, rel=1e-9)


@pytest.mark.skipif(not UR10E_IDENT.exists(), reason="UR10e data absent")
@pytest.mark.parametrize("reduced", [False, True])
def test_ur10e_reduced_form_equals_in_memory(reduced):
    spec = load_robot("ur10e")
    rec = load_log(UR10E_IDENT, robot="ur10e", rows=(635, 3510), format="dynamic_calibration")
    data = prepare([rec], spec, PreprocessConfig())
    model = ModelConfig(reduced=reduced)
    got = identify_all(spec, data, ("ols", "bounded"), model)
    w = design_matrix(spec, model, data.q, data.qd, data.qdd, data.segment, data.t)
    y = data.tau.reshape(-1)
    names = column_names(spec, model)
    assert rel(got["ols"].values, estimate_ols(w, y, names).values) < 1e-9
    assert rel(got["bounded"].values, estimate_bounded(w, y, names, nonnegative_mask(spec, model)).values) < 1e-9


@pytest.mark.skipif(not UR10E_IDENT.exists(), reason="UR10e data absent")
def test_tsqr_as_accurate_as_svd_on_ill_conditioned_problem():
    """The paper's full base set on the real UR10e data plus a column that nearly repeats the first
    one (cond ≈ 5e5 after column scaling): the chunked QR stays as close to the SVD solution as the
    in-memory path, where normal equations without refinement lose about cond² · eps."""
    spec = load_robot("ur10e")
    rec = load_log(UR10E_IDENT, robot="ur10e", rows=(635, 3510), format="dynamic_calibration")
    data = prepare([rec], spec, PreprocessConfig())
    blocks = design_blocks(spec, ModelConfig(), data.q, data.qd, data.qdd, data.segment, data.t)
    first = blocks[:, :, :1]
    noise = np.random.default_rng(0).normal(size=first.shape)
    cols = np.concatenate([blocks, first + 1e-6 * np.abs(first).max() * noise], axis=2)
    w, y = cols.reshape(-1, cols.shape[2]), data.tau.reshape(-1)
    scale = np.linalg.norm(w, axis=0)
    assert np.linalg.cond(w / scale) > 1e5
    x_svd = np.linalg.lstsq(w / scale, y, rcond=1e-20)[0] / scale
    acc = Accumulator()
    for k in range(0, len(cols), 500):
        acc.add(cols[k:k + 500], data.tau[k:k + 500])
    err_qr = rel(solve_reduced(acc.result()), x_svd)
    err_mem = rel(solve_ls(w, y), x_svd)
    a = w / scale
    x_ne = scipy.linalg.cho_solve(scipy.linalg.cho_factor(a.T @ a), a.T @ y) / scale
    err_ne = rel(x_ne, x_svd)
    assert err_qr < 1e-8 and err_qr <= 10 * err_mem
    assert err_ne > 100 * err_qr


def test_from_stacked_matches_reduce_design(ur5, two_segments):
    d = two_segments
    model = ModelConfig()
    w = design_matrix(ur5, model, d.q, d.qd, d.qdd, d.segment, d.t)
    a = from_stacked(w, d.tau.reshape(-1))
    b = reduce_design(ur5, model, d, chunk=300)
    x = solve_reduced(a)
    assert rel(solve_reduced(b), x) < 1e-10
    np.testing.assert_allclose(b.residual_sq(x), a.residual_sq(x), rtol=1e-10)
