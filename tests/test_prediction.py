"""The one prediction path (issue 15, item 1): ``urident.ident.predict_recordings`` serves validate,
view, gap --params and the live view; e_N and RMS come from ``urident.ident.metrics``.

End to end through the CLI: ``urident view`` and ``urident validate`` predict the same torques
(read back from their .rrd files) and report the same e_N and RMS, on the real UR10e validation run
with ``--preset real-robot`` parameters (``auto``: per-joint terms and a torque lead, which both
apply) and on a urident log."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from shared_data import UR10E_DATA
from urident.cli.main import main
from urident.ident import (RunningMetrics, StreamPredictor, error_metrics, identify, load_params,
                           prediction_config, predict_recordings, prepare, save_params)
from urident.logs import load_log
from urident.model import load_robot
from urident.viz import read_rrd

ROOT = Path(__file__).resolve().parent.parent
SAMPLE_IDENT = ROOT / "logs" / "sample_ident.csv"
SAMPLE_VALID = ROOT / "logs" / "sample_valid.csv"
UR10E_IDENT = UR10E_DATA / "ur-20_02_10-30sec_12harm.csv"
UR10E_VALID = UR10E_DATA / "ur-20_01_17-ptp_10_points.csv"
UR10E = ["--format", "dynamic_calibration"]
VIEW_LINE = re.compile(r"(\d+) samples, e_N = ([0-9.]+), RMS residual \[N m\] = \[([^\]]*)\]")


def _view_and_validate(tmp_path, capsys, params, log_args, robot):
    """Run view and validate on the same log; return (view predicted, view measured, validate
    predicted, validate measured) as (N, 6) arrays from the .rrd files, view's printed line and
    validate's JSON."""
    view_rrd, val_rrd, val_json = tmp_path / "view.rrd", tmp_path / "val.rrd", tmp_path / "val.json"
    capsys.readouterr()
    assert main(["view", *log_args, "--robot", robot, "--params", str(params), "--save", str(view_rrd)]) == 0
    line = VIEW_LINE.search(capsys.readouterr().out)
    assert line, "view printed no metrics line"
    assert main(["validate", *log_args, "--params", str(params), "--json-out", str(val_json),
                 "--save", str(val_rrd)]) == 0
    spec = load_robot(robot)
    label = params.stem.replace(".", "_")
    view, val = read_rrd(view_rrd), read_rrd(val_rrd)
    out = []
    for contents, prefix in ((view, "torque"), (val, f"validate/{label}/torque")):
        for series in ("predicted", "measured"):
            out.append(np.column_stack([contents.scalars(f"{prefix}/{j}/{series}")[1]
                                        for j in spec.joint_names]))
    return (*out, line, json.loads(val_json.read_text()))


def _assert_same(tmp_path, capsys, params, log_args, robot, n_samples):
    view_p, view_m, val_p, val_m, line, report = _view_and_validate(tmp_path, capsys, params, log_args, robot)
    assert view_p.shape == val_p.shape == (n_samples, 6)
    assert np.max(np.abs(view_p - val_p)) <= 1e-9
    assert np.max(np.abs(view_m - val_m)) <= 1e-9
    # what view prints is validate's figures, formatted
    assert int(line.group(1)) == report["n_samples"] == n_samples
    assert line.group(2) == f"{report['e_n']:.4f}"
    assert line.group(3) == ", ".join(f"{v:.3g}" for v in report["rms_nm"])
    return report


@pytest.mark.skipif(not (UR10E_IDENT.exists() and UR10E_VALID.exists()), reason="UR10e data absent")
def test_view_and_validate_agree_on_real_ur10e_with_real_robot_preset(tmp_path, capsys):
    params = tmp_path / "ur10e_rr.yaml"
    assert main(["identify", str(UR10E_IDENT), "--robot", "ur10e", *UR10E, "--rows", "635-3510",
                 "--preset", "real-robot", "--method", "ols", "--out", str(params)]) == 0
    assert "preset auto (asked for as real-robot)" in capsys.readouterr().out
    identified = load_params(params)
    assert identified.model.dahl_source == "velocity" and identified.preprocess.torque_lead_s > 0
    report = _assert_same(tmp_path, capsys, params, [str(UR10E_VALID), *UR10E, "--rows", "700-4200"],
                          "ur10e", 3501)
    # the README's real-robot row (OLS): e_N 0.0545, RMS 0.42 / 0.68 on joints 5 / 6
    assert identified.preprocess.filter_hz == 45.0
    assert report["e_n"] == pytest.approx(0.0545, abs=5e-4)
    np.testing.assert_allclose(report["rms_nm"][4:], [0.42, 0.68], atol=0.01)


def test_view_and_validate_agree_on_a_urident_log(tmp_path, capsys):
    params = tmp_path / "sample_fixed.yaml"
    assert main(["identify", str(SAMPLE_IDENT), "--robot", "ur5", "--preset", "ur10e-2020",
                 "--method", "ols", "--out", str(params)]) == 0
    n = len(load_log(SAMPLE_VALID))
    _assert_same(tmp_path, capsys, params, [str(SAMPLE_VALID)], "ur5", n)


@pytest.fixture(scope="module")
def sample():
    spec = load_robot("ur5")
    ident, valid = load_log(SAMPLE_IDENT), load_log(SAMPLE_VALID)
    return spec, ident, valid


@pytest.fixture(scope="module")
def dahl_params(sample):
    from urident.ident.presets import PRESETS

    spec, ident, _ = sample
    preset = PRESETS["ur10e-2020"]   # a fixed Dahl model with extras
    return identify(spec, prepare([ident], spec), "ols", preset.model, preset.weighting)


def test_prediction_follows_the_parameters_file(sample, dahl_params, tmp_path):
    from dataclasses import replace

    from urident.ident import PreprocessConfig

    spec, _, valid = sample
    recorded = replace(dahl_params, preprocess=PreprocessConfig(filter_hz=7.0, torque_filter_hz=5.0, decimate=2),
                       drive_gains=1.1 * np.asarray(spec.drive_gains))
    path = tmp_path / "p.yaml"
    save_params(recorded, path)
    params = load_params(path)
    config = prediction_config(params)
    # the file's acceleration filter; raw torques, every sample, rest kept
    assert (config.filter_hz, config.torque_filter_hz, config.decimate, config.trim_rest) == (7.0, None, 1, False)
    assert prediction_config(params, trim_rest=True, decimate=None).trim_rest
    p = predict_recordings(params, valid)
    assert len(p.data) == len(valid)
    np.testing.assert_allclose(p.data.tau, np.asarray(valid.current) * 1.1 * np.asarray(spec.drive_gains))
    other = predict_recordings(params, valid, config=replace(config, filter_hz=10.0))
    assert np.max(np.abs(other.tau_predicted - p.tau_predicted)) > 1e-3   # the corner matters
    from urident.errors import ConfigError

    with pytest.raises(ConfigError, match="Payload"):   # a payload is a urident.ident.payload.Payload
        predict_recordings(params, valid, payload=object())


@pytest.mark.parametrize("coulomb", ["dahl", "hold"])
def test_stream_equals_causal_mode_batch_by_batch(sample, dahl_params, coulomb):
    from dataclasses import replace

    spec, ident, valid = sample
    params = dahl_params
    if coulomb == "hold":
        params = identify(spec, prepare([ident], spec), "ols", replace(params.model, coulomb="hold"))
    whole = predict_recordings(params, valid, spec, causal=True)
    stream = StreamPredictor(params, spec)
    rng = np.random.default_rng(3)
    edges = np.unique(np.r_[0, np.sort(rng.integers(1, len(valid), 60)), len(valid)])
    parts = [stream.update(valid.t[a:b], valid.q[a:b], valid.qd[a:b], valid.current[a:b])
             for a, b in zip(edges[:-1], edges[1:])]
    qdd, tau, pred = (np.vstack([p[k] for p in parts]) for k in range(3))
    np.testing.assert_allclose(qdd, whole.data.qdd, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(tau, whole.data.tau)
    assert np.max(np.abs(pred - whole.tau_predicted)) <= 1e-9
    # the friction state is carried: restarting it at each batch would differ
    restart = np.vstack([StreamPredictor(params, spec).update(valid.t[a:b], valid.q[a:b], valid.qd[a:b],
                                                              valid.current[a:b])[2]
                         for a, b in zip(edges[:-1], edges[1:])])
    assert np.max(np.abs(restart - whole.tau_predicted)) > 1e-3


def test_causal_mode_lags_the_zero_phase_one(sample, dahl_params):
    spec, _, valid = sample
    zero = predict_recordings(dahl_params, valid, spec)
    causal = predict_recordings(dahl_params, valid, spec, causal=True)
    np.testing.assert_array_equal(causal.data.tau, zero.data.tau)
    lag = 1.0 / (2 * np.pi * dahl_params.preprocess.filter_hz)
    dt = float(np.median(np.diff(valid.t)))
    shift = int(round(lag / dt))
    k = slice(50, -50)
    # the causal q̈ is roughly the zero-phase one delayed by 1/w
    delayed = np.abs(causal.data.qdd[k] - np.roll(zero.data.qdd, shift, axis=0)[k]).mean()
    assert delayed < np.abs(causal.data.qdd[k] - zero.data.qdd[k]).mean()


def test_live_view_draws_the_causal_prediction(sample, dahl_params, tmp_path):
    from urident.viz import LiveStreamer

    spec, _, valid = sample
    n = 400
    out = tmp_path / "live.rrd"
    with LiveStreamer(spec, dahl_params, save=out, backend="thread", queue_size=n + 10) as live:
        for k in range(n):
            live.push(valid.t[k], list(valid.q[k]), list(valid.qd[k]), list(valid.current[k]))
    assert live.stats.processed == n and live.stats.error is None
    expected = predict_recordings(dahl_params, valid.select(slice(0, n)), spec, causal=True)
    contents = read_rrd(out)
    predicted = np.column_stack([contents.scalars(f"torque/{j}/predicted")[1] for j in spec.joint_names])
    measured = np.column_stack([contents.scalars(f"torque/{j}/measured")[1] for j in spec.joint_names])
    assert np.max(np.abs(predicted - expected.tau_predicted)) <= 1e-9
    assert np.max(np.abs(measured - expected.data.tau)) <= 1e-9
    e_n = contents.scalars("metrics/e_N")[1][-1]
    assert e_n == pytest.approx(error_metrics(expected.residual)[0], rel=1e-9)


def test_gap_with_params_predicts_through_the_one_path(sample, dahl_params):
    from urident.gap.data import build_set
    from urident.gap.residual import make_context

    spec, _, valid = sample
    gset = build_set([valid], spec, params=dahl_params)
    ctx = make_context(spec, dahl_params, gset)
    expected = predict_recordings(dahl_params, valid, spec, config=prediction_config(dahl_params, trim_rest=True))
    np.testing.assert_array_equal(ctx.tau, expected.data.tau)
    assert np.max(np.abs(ctx.tau_hat - expected.tau_predicted)) <= 1e-9


def test_running_metrics_equal_the_batch_metrics():
    rng = np.random.default_rng(0)
    r = rng.normal(size=(1000, 6))
    running = RunningMetrics()
    for a, b in ((0, 1), (1, 400), (400, 1000)):
        running.add(r[a:b])
    e_n, rms = error_metrics(r)
    assert running.n == 1000
    assert running.e_n == pytest.approx(e_n, rel=1e-12)
    np.testing.assert_allclose(running.rms, rms, rtol=1e-12)
    # the paper's eq. (22): ‖e‖ / m over m time samples
    assert error_metrics(np.full((10, 6), 0.1))[0] == pytest.approx(np.sqrt(60 * 0.01) / 10)
