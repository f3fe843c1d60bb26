"""Post-hoc Rerun views: the API other commands use, and ``urident view`` (issue 7).

Recordings are written to .rrd files and read back through Rerun's own chunk reader
(``urident.viz.readback.read_rrd`` wraps ``rerun.chunk.RrdReader``)."""

from __future__ import annotations

import numpy as np
import pytest

from urident.cli.main import main
from urident.logs import LogWriter
from urident.model import joint_torques, load_robot
from urident.model.kinematics import frame_poses
from urident.viz import (
    ViewerUnavailable,
    close_recording,
    log_metrics,
    log_robot_motion,
    log_text,
    log_torque_comparison,
    open_recording,
    read_rrd,
    torque_metrics,
)

SERIES = ("measured", "predicted", "residual")


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5e")


def _motion(n: int, rate_hz: float = 500.0, t0: float = 50.0):
    t = t0 + np.arange(n) / rate_hz
    phase = np.arange(6)[None, :]
    w = 2 * np.pi * 0.4
    q = 0.6 * np.sin(w * t[:, None] + phase)
    qd = 0.6 * w * np.cos(w * t[:, None] + phase)
    qdd = -0.6 * w * w * np.sin(w * t[:, None] + phase)
    return t, q, qd, qdd


@pytest.fixture(scope="module")
def synthetic_log(tmp_path_factory, spec):
    """A urident log (1500 samples at 500 Hz) whose currents follow the nominal model."""
    path = tmp_path_factory.mktemp("logs") / "run.csv"
    t, q, qd, qdd = _motion(1500)
    current = joint_torques(spec, spec.nominal_params, q, qd, qdd) / spec.drive_gains
    fields = ["timestamp", "actual_q", "actual_qd", "actual_current", "target_q"]
    with LogWriter(path, fields=fields, metadata={"robot": "ur5e", "rate_hz": 500.0}) as writer:
        for k in range(len(t)):
            writer.append_sample(t[k], q=q[k], qd=qd[k], current=current[k], target_q=q[k] + 1e-3)
    return path


def test_torque_comparison_metrics_text_round_trip(tmp_path, spec):
    out = tmp_path / "cmp.rrd"
    n = 400
    t = np.arange(n) * 0.002
    rng = np.random.default_rng(1)
    measured = rng.normal(size=(n, 6))
    predicted = measured + 0.1 * rng.normal(size=(n, 6))
    rec = open_recording("urident_test", save=out)
    log_torque_comparison(rec, t, measured, predicted, prefix="validate/torque",
                          joint_names=spec.joint_names)
    metrics = torque_metrics(measured, predicted, spec.joint_names)
    log_metrics(rec, metrics, prefix="validate/metrics", t=float(t[-1]))
    log_text(rec, "validate/summary", "# Validation\n\nall good\n")
    close_recording(rec)

    contents = read_rrd(out)
    assert contents.application_id == "urident_test"
    for j, joint in enumerate(spec.joint_names):
        for series, expected in zip(SERIES, (measured, predicted, measured - predicted)):
            times, values = contents.scalars(f"validate/torque/{joint}/{series}")
            assert len(values) == n
            np.testing.assert_allclose(times, t, atol=1e-9)
            np.testing.assert_allclose(values, expected[:, j])
        _, rms = contents.scalars(f"validate/metrics/rms/{joint}")
        assert rms[-1] == pytest.approx(metrics[f"rms/{joint}"])
    _, e_n = contents.scalars("validate/metrics/e_N")
    assert 0.0 < e_n[-1] < 0.5
    (_, text), = contents.rows("validate/summary", "TextDocument:text")
    assert "all good" in text[0]


def test_metrics_definition():
    measured = np.ones((10, 6))
    metrics = torque_metrics(measured, 0.9 * measured)
    # The paper's eq. (22): ‖e‖ / m over m = 10 samples of six joints with e = 0.1 each.
    assert metrics["e_N"] == pytest.approx(np.sqrt(60 * 0.01) / 10)
    assert metrics["rms/elbow"] == pytest.approx(0.1)


def test_robot_motion_is_decimated_and_follows_kinematics(tmp_path, spec):
    out = tmp_path / "motion.rrd"
    t, q, _, _ = _motion(1000)  # 2 s at 500 Hz
    rec = open_recording("urident_test", save=out)
    n_poses = log_robot_motion(rec, spec, t, q, rate_hz=25.0)
    close_recording(rec)
    assert n_poses == 50
    contents = read_rrd(out)
    tool = contents.rows("robot/tool", "Points3D:positions")
    tool = [r for r in tool if r[0] is not None]
    assert len(tool) == n_poses
    # first logged pose is the first sample: its tool point matches frame_poses
    _, origins = frame_poses(spec, q[:1])
    np.testing.assert_allclose(tool[0][1][0], origins[0, 6], atol=1e-5)
    n_caps = sum(len(j.collision) for j in spec.joints)
    links = contents.rows("robot/links", "Capsules3D:translations")
    assert len(links) == n_poses and all(len(cell) == n_caps for _, cell in links)
    skeleton = contents.rows("robot/skeleton", "LineStrips3D:strips")
    assert len(skeleton) == n_poses and len(skeleton[0][1][0]) == 8
    assert contents.rows("robot/base", "Capsules3D:radii")


def test_view_command_saves_a_complete_recording(tmp_path, synthetic_log, spec, capsys):
    out = tmp_path / "view.rrd"
    assert main(["view", str(synthetic_log), "--save", str(out)]) == 0
    assert "e_N" in capsys.readouterr().out
    contents = read_rrd(out)
    assert contents.has_blueprint
    for joint in spec.joint_names:
        for series in SERIES:
            times, values = contents.scalars(f"torque/{joint}/{series}")
            assert len(values) == 1500
        # the log's currents follow the nominal model: the prediction matches closely
        _, measured = contents.scalars(f"torque/{joint}/measured")
        _, residual = contents.scalars(f"torque/{joint}/residual")
        assert np.sqrt(np.mean(residual[50:-50] ** 2)) < 0.05 * max(np.abs(measured).max(), 1.0)
        assert len(contents.scalars(f"tracking/{joint}")[1]) == 1500
        assert len(contents.scalars(f"metrics/rms/{joint}")[1]) == 1
    assert len(contents.scalars("metrics/e_N")[1]) == 1
    (_, text), = contents.rows("summary", "TextDocument:text")
    assert "e_N" in text[0] and "wrist_3" in text[0]
    poses = contents.rows("robot/links", "Capsules3D:lengths")
    assert 80 <= len(poses) <= 100  # 3 s at 30 Hz


def test_view_rows_and_params_file(tmp_path, synthetic_log, spec):
    params = tmp_path / "params.npy"
    np.save(params, spec.nominal_params)
    out = tmp_path / "rows.rrd"
    assert main(["view", str(synthetic_log), "--rows", "101:600", "--params", str(params),
                 "--save", str(out), "--pose-rate", "50"]) == 0
    contents = read_rrd(out)
    times, _ = contents.scalars("torque/elbow/predicted")
    assert len(times) == 500
    assert times[0] == pytest.approx(50.0 + 100 / 500.0)


def test_view_bad_params_is_one_line_error(tmp_path, synthetic_log, capsys):
    params = tmp_path / "params.txt"
    params.write_text("1 2 3\n")
    code = main(["view", str(synthetic_log), "--params", str(params),
                 "--save", str(tmp_path / "x.rrd")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f"urident: error: {params}: prediction parameters") and err.count("\n") == 1


def test_view_headless_suggests_save(monkeypatch, synthetic_log, capsys):
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    code = main(["view", str(synthetic_log)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("urident: error: cannot spawn a Rerun viewer") and "--save" in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_connect_to_nothing_is_viewer_unavailable():
    import socket

    with socket.socket() as s:  # a free port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ViewerUnavailable, match="--save"):
        open_recording("urident_test", connect=f"rerun+http://127.0.0.1:{port}/proxy")


def test_base_parameter_prediction_matches_standard(spec):
    from urident.ident import parameters_from_vector, predict
    from urident.model.base import base_parameters

    _, q, qd, qdd = _motion(50)
    tau = joint_torques(spec, spec.nominal_params, q, qd, qdd)
    from_standard = parameters_from_vector(spec, spec.nominal_params)
    np.testing.assert_allclose(predict(from_standard, spec, q, qd, qdd), tau, atol=1e-8)
    base = base_parameters(spec)
    from_base = parameters_from_vector(spec, base.from_standard(spec.nominal_params))
    np.testing.assert_allclose(predict(from_base, spec, q, qd, qdd), tau, atol=1e-8)


def test_acceleration_estimates():
    from urident.ident.preprocess import CausalAcceleration, accelerations

    t, _, qd, qdd = _motion(2000)
    est = accelerations(t, qd)
    np.testing.assert_allclose(est[100:-100], qdd[100:-100], atol=0.02 * np.abs(qdd).max())
    causal = CausalAcceleration(filter_hz=10.0)
    # constant acceleration 2 rad/s²: the causal estimate settles on it
    tt = np.arange(200) * 0.002
    out = np.concatenate([causal.update(tt[:100], np.outer(2 * tt[:100], np.ones(6))),
                          causal.update(tt[100:], np.outer(2 * tt[100:], np.ones(6)))])
    np.testing.assert_allclose(out[-1], 2.0, rtol=1e-3)


def test_rerun_cli_options_for_other_commands(tmp_path, monkeypatch):
    import argparse

    from urident.cli.options import add_rerun_arguments, check_rerun_args, open_recording_from_args

    parser = argparse.ArgumentParser()
    add_rerun_arguments(parser)
    assert open_recording_from_args(parser.parse_args([]), "urident_test") is None
    out = tmp_path / "other.rrd"
    args = parser.parse_args(["--save", str(out)])
    check_rerun_args(args)
    rec = open_recording_from_args(args, "urident_identify")
    log_text(rec, "identify/summary", "# Identification\n")
    close_recording(rec)
    assert "identify/summary" in read_rrd(out).entities
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.raises(ViewerUnavailable, match="--save"):
        check_rerun_args(parser.parse_args(["--rerun"]))


def test_view_with_identified_params_file(tmp_path, synthetic_log, spec):
    ident = pytest.importorskip("urident.ident")
    from urident.logs import load_log

    recording = load_log(synthetic_log)
    model = ident.identify(spec, ident.prepare([recording], spec), "ols")
    params = tmp_path / "PARAMS.yaml"
    ident.save_params(model, params)
    out = tmp_path / "ident.rrd"
    assert main(["view", str(synthetic_log), "--params", str(params), "--save", str(out)]) == 0
    _, e_n = read_rrd(out).scalars("metrics/e_N")
    assert e_n[-1] < 0.05
