"""Identification: preprocessing, estimation on simulated data, parameter files, URDF, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from urident.errors import ConfigError, LogFormatError
from urident.ident import (ModelConfig, PreprocessConfig, accelerations, identify, identify_all,
                           load_params, metrics, predict, prepare, preprocess, save_params, validate)
from urident.ident.design import base_for, design_matrix, nonnegative_mask
from urident.ident.estimate_consistent import is_physically_consistent
from urident.ident.friction import dahl_state
from urident.ident.preprocess import Prepared, rest_trim_range
from urident.ident.synthetic import random_multisine, synthetic_recording
from urident.ident.torque import DriveGainError, estimate_drive_gains, payload_params, payload_torque
from urident.model import joint_torques, load_robot


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


@pytest.fixture(scope="module")
def sim(spec):
    """20 s at 250 Hz, current noise 0.03 A, true accelerations known."""
    rec, qdd, tau = synthetic_recording(spec, duration_s=20.0, rate_hz=250.0, current_noise_a=0.03, seed=3)
    return rec, qdd, tau


def exact_prepared(spec, rec, qdd) -> Prepared:
    return Prepared(rec.t, rec.q, rec.qd, qdd, rec.current * spec.drive_gains, spec.drive_gains)


# ----------------------------------------------------------------------------- preprocessing
def test_accelerations_zero_phase_on_jittery_timestamps(rng):
    t = np.cumsum(rng.uniform(0.006, 0.014, size=3000))  # 100 Hz nominal, heavy jitter
    f = 0.7
    qd = np.sin(2 * np.pi * f * t)[:, None] * np.ones(6)
    qdd = accelerations(t, qd, filter_hz=10.0)
    true = 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    inner = slice(100, -100)
    # |L|^2 at 0.7 Hz is 0.995: no lag, small attenuation
    err = qdd[inner, 0] - true[inner]
    assert np.max(np.abs(err)) < 0.02 * 2 * np.pi * f
    # a naive filtfilt of s/(s/w+1) would give minus the derivative of qdd: check we are not that
    assert np.corrcoef(qdd[inner, 0], true[inner])[0, 1] > 0.999


def test_preprocess_trims_rest_and_decimates(spec):
    rec, _, _ = synthetic_recording(spec, duration_s=4.0, rate_hz=200.0, seed=1)
    qd = np.array(rec.qd)
    qd[:50] = 0.0
    qd[-30:] = 1e-4
    q = np.array(rec.q)
    from dataclasses import replace

    rec2 = replace(rec, qd=qd, q=q)
    assert rest_trim_range(qd, 1e-3) == (50, len(qd) - 30)
    data = preprocess(rec2, spec, PreprocessConfig(decimate=2))
    assert len(data) == len(range(50, len(qd) - 30, 2))
    assert data.provenance[0].samples_used == (50, len(qd) - 30)
    np.testing.assert_allclose(data.tau, (rec.current * spec.drive_gains)[50:-30:2])


def test_preprocess_rejects_nan_and_wrong_robot(spec):
    rec, _, _ = synthetic_recording(spec, duration_s=1.0, rate_hz=100.0)
    from dataclasses import replace

    cur = np.array(rec.current)
    cur[10, 2] = np.nan
    with pytest.raises(LogFormatError, match="current holds NaN"):
        preprocess(replace(rec, current=cur), spec)
    with pytest.raises(ConfigError, match="recorded on robot 'ur10e'"):
        preprocess(replace(rec, robot="ur10e"), spec)


def test_drive_gains_option_and_errors(spec, capsys):
    from urident.cli.main import main
    from urident.cli.options import drive_gains

    np.testing.assert_allclose(drive_gains("1,2,3,4,5,6"), [1, 2, 3, 4, 5, 6])
    for bad in ("1,2,3", "1,2,3,4,5,x", "1,2,3,4,5,-6"):
        assert main(["identify", "x.csv", "--robot", "ur5", "--out", "p.yaml", "--drive-gains", bad]) == 2
        err = capsys.readouterr().err
        assert err.startswith("urident: error: argument --drive-gains: ") and err.count("\n") == 1


def test_drive_gain_estimation_from_payload_runs():
    spec = load_robot("ur10e")
    rng = np.random.default_rng(7)
    true_gains = spec.drive_gains * rng.uniform(0.9, 1.1, size=6)
    payload = payload_params(8.0, [0.05, 0.08, 0.1])
    runs = []
    for k, load in enumerate((None, payload)):
        traj = random_multisine(spec, np.random.default_rng(10 + k), speed_fraction=0.5)
        t = np.arange(0, 20.0, 0.004)
        q, qd, qdd = traj(t)
        tau = joint_torques(spec, spec.nominal_params, q, qd, qdd)
        if load is not None:
            tau = tau + payload_torque(spec, q, qd, qdd, load)
        current = tau / true_gains + rng.normal(0, 0.01, size=tau.shape)
        runs.append((q, qd, qdd, current))
    est = estimate_drive_gains(spec, runs[0], runs[1], payload)
    np.testing.assert_allclose(est.gains, true_gains, rtol=0.02)
    assert np.all(np.abs(est.gains - true_gains) < 4 * est.sigma)
    # the payload's torque fixes the scale: a load given 10x too light gives gains 10x too large,
    # which no drive has (refused, not returned); the runs swapped give negative ones
    with pytest.raises(DriveGainError, match="does not show the given load"):
        estimate_drive_gains(spec, runs[0], runs[1], 0.1 * payload)
    with pytest.raises(DriveGainError, match="negative") as swapped:
        estimate_drive_gains(spec, runs[1], runs[0], payload)
    assert swapped.value.swapped


# ----------------------------------------------------------------------------- estimation
@pytest.mark.parametrize("reduced", [False, True])
def test_ols_recovers_base_parameters_within_sigma(spec, sim, reduced):
    rec, qdd, _ = sim
    base = base_for(spec, reduced)
    params = spec.nominal_params.copy()
    if reduced:  # simulate a robot the reduced model describes exactly
        params[np.setdiff1d(np.arange(78), base.modelled)] = 0.0
    noise = np.random.default_rng(4).normal(0, 0.03, (len(rec), 6)) * spec.drive_gains
    tau = joint_torques(spec, params, rec.q, rec.qd, qdd) + noise
    data = Prepared(rec.t, rec.q, rec.qd, qdd, tau, spec.drive_gains)
    model = identify(spec, data, "ols", ModelConfig(reduced=reduced))
    true = base.from_standard(params)
    z = np.abs(model.values - true) / model.sigma
    assert np.mean(z < 4) >= 0.95, z
    assert model.values.shape == ((33,) if reduced else (base.n_base,))
    # σ² is the noise variance: current noise 0.03 A times the drive gains
    expected = np.mean((0.03 * spec.drive_gains) ** 2)
    assert 0.8 * expected < model.noise_var < 1.2 * expected


def test_full_pipeline_recovers_parameters(spec, sim):
    """Accelerations from the filter, not the truth: the filter's small attenuation at the
    trajectory's frequencies (<= 0.5 Hz) keeps estimates close to the truth."""
    rec, _, _ = sim
    data = prepare([rec], spec, PreprocessConfig(filter_hz=10.0))
    model = identify(spec, data, "ols")
    true = base_for(spec, False).from_standard(spec.nominal_params)
    z = np.abs(model.values - true) / model.sigma
    assert np.mean(z < 4) >= 0.9, z
    res = validate(model, spec, prepare([rec], spec))
    assert res.mean_rms_nm < 1.3 * np.sqrt(model.noise_var)


def test_bounded_respects_positivity_and_matches_ols(spec, sim):
    rec, qdd, _ = sim
    data = exact_prepared(spec, rec, qdd)
    models = identify_all(spec, data, ("ols", "bounded"))
    mask = nonnegative_mask(spec, ModelConfig())
    names = np.array(models["ols"].names)
    assert {"IM4", "fv1", "fc6"} <= set(names[mask])
    assert not any(n.startswith("mr") for n in names[mask])
    assert np.all(models["bounded"].values[mask] >= 0)
    true = base_for(spec, False).from_standard(spec.nominal_params)
    z = np.abs(models["bounded"].values - true) / models["bounded"].sigma
    assert np.mean(z < 4) >= 0.95


def test_bounded_enforces_bounds_when_data_pull_negative(spec, sim):
    rec, qdd, _ = sim
    params = spec.nominal_params.copy()
    params[72:78] = 0.0  # no Coulomb friction: noisy OLS gives some negative fc
    tau = joint_torques(spec, params, rec.q, rec.qd, qdd) + np.random.default_rng(1).normal(0, 2.0, (len(rec), 6))
    data = Prepared(rec.t, rec.q, rec.qd, qdd, tau, spec.drive_gains)
    models = identify_all(spec, data, ("ols", "bounded"))
    fc = [k for k, n in enumerate(models["ols"].names) if n.startswith("fc")]
    assert np.any(models["ols"].values[fc] < 0)
    assert np.all(models["bounded"].values[fc] >= 0)


def test_consistent_is_physical_and_accurate(spec, sim):
    rec, qdd, _ = sim
    data = exact_prepared(spec, rec, qdd)
    model = identify(spec, data, "consistent")
    assert is_physically_consistent(model.standard, tol=1e-7)
    base = base_for(spec, False)
    np.testing.assert_allclose(model.values, base.from_standard(model.standard), atol=1e-12)
    true = base.from_standard(spec.nominal_params)
    z = np.abs(model.values - true) / model.sigma
    assert np.mean(z < 4) >= 0.95, z


def test_consistent_fixes_unphysical_ols(spec, sim):
    """Heavy noise and a short window: OLS base values imply no realisable body; the SDP's do."""
    rec, qdd, _ = sim
    n = 300
    tau = joint_torques(spec, spec.nominal_params, rec.q[:n], rec.qd[:n], qdd[:n])
    tau = tau + np.random.default_rng(2).normal(0, 3.0, tau.shape)
    data = Prepared(rec.t[:n], rec.q[:n], rec.qd[:n], qdd[:n], tau, spec.drive_gains)
    models = identify_all(spec, data, ("ols", "consistent"))
    assert is_physically_consistent(models["consistent"].standard, tol=1e-7)
    mask = nonnegative_mask(spec, ModelConfig())
    assert np.all(models["consistent"].values[mask] >= -1e-7)


def test_urdf_export_reproduces_rigid_body_torques(spec, sim, tmp_path):
    pin = pytest.importorskip("pinocchio")
    from urident.ident.urdf import write_urdf
    from urident.model import regressor_blocks

    rec, qdd, _ = sim
    model = identify(spec, exact_prepared(spec, rec, qdd), "consistent")
    path = write_urdf(spec, model.standard, tmp_path / "arm.urdf")
    pm = pin.buildModelFromUrdf(str(path))
    data = pm.createData()
    assert pm.nq == 6
    idx = slice(0, len(rec), 500)
    blocks = regressor_blocks(spec, rec.q[idx], rec.qd[idx], qdd[idx])
    rigid = blocks[:, :, :60] @ model.standard[:60]
    for k, (q, v, a) in enumerate(zip(rec.q[idx], rec.qd[idx], qdd[idx])):
        np.testing.assert_allclose(pin.rnea(pm, data, q, v, a), rigid[k], atol=1e-8, rtol=1e-8)
    with pytest.raises(ConfigError, match="physically consistent"):
        bad = model.standard.copy()
        bad[0] = -1.0
        write_urdf(spec, bad, tmp_path / "bad.urdf")


# ----------------------------------------------------------------------------- friction, metrics
def test_dahl_state_holds_at_standstill():
    q = np.r_[np.linspace(0, 0.2, 100), np.full(50, 0.2), np.linspace(0.2, 0.1, 100)][:, None] * np.ones(6)
    z = dahl_state(q, 0.01)
    assert z[99, 0] > 0.99          # moved +: saturated at +1
    assert np.all(z[100:150, 0] == z[99, 0])  # holds while still
    assert z[-1, 0] < -0.99         # moved back: -1
    seg = np.r_[np.zeros(100, int), np.ones(150, int)]
    assert dahl_state(q, 0.01, seg)[100, 0] == 0.0


def test_metrics_definitions():
    meas = np.ones((4, 6))
    pred = meas.copy()
    pred[:, 0] += 0.5
    e_n, rms, rre = metrics(meas, pred)
    assert e_n == pytest.approx(np.sqrt(4 * 0.25) / 4)  # ‖e‖/m with m time samples
    np.testing.assert_allclose(rms, [0.5, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(rre, [50, 0, 0, 0, 0, 0])


# ----------------------------------------------------------------------------- files and CLI
def test_params_roundtrip_and_errors(spec, sim, tmp_path):
    rec, qdd, _ = sim
    data = exact_prepared(spec, rec, qdd)
    model = identify(spec, data, "ols", ModelConfig(extras=("offset",), friction_eps=0.02))
    path = tmp_path / "p.yaml"
    save_params(model, path)
    back = load_params(path)
    assert back.model == model.model and back.names == model.names
    np.testing.assert_allclose(predict(back, spec, rec.q[:50], rec.qd[:50], qdd[:50]),
                               predict(model, spec, rec.q[:50], rec.qd[:50], qdd[:50]))
    text = path.read_text()
    for old, new, msg in [("format: urident-params", "format: other", "bad.yaml: format: "),
                          ("method: ols", "method: magic", "bad.yaml: method: "),
                          ("robot: ur5", "robot: ur10e", "robot 'ur10e'")]:
        bad = tmp_path / "bad.yaml"
        bad.write_text(text.replace(old, new, 1))
        with pytest.raises(ConfigError, match=msg):
            m = load_params(bad)
            predict(m, spec, rec.q[:5], rec.qd[:5], qdd[:5])
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.strip().startswith("value:"))
    lines[k] = lines[k].split(":")[0] + ": .nan"
    bad.write_text("\n".join(lines))
    with pytest.raises(ConfigError, match=r"bad.yaml: base_parameters\[0\].value: must be finite"):
        load_params(bad)
    with pytest.raises(ConfigError, match="parameters file not found"):
        load_params(tmp_path / "missing.yaml")


def _write_log(rec, path):
    from urident.logs import LogWriter

    with LogWriter(path, fields=["timestamp", "actual_q", "actual_qd", "actual_current"],
                   metadata={"robot": rec.robot, "rate_hz": rec.rate_hz}) as w:
        for k in range(len(rec)):
            w.append_sample(float(rec.t[k]), q=rec.q[k], qd=rec.qd[k], current=rec.current[k])


def test_cli_identify_validate(spec, tmp_path, capsys):
    from urident.cli.main import main

    rec, _, _ = synthetic_recording(spec, duration_s=12.0, rate_hz=125.0, current_noise_a=0.03, seed=5)
    val, _, _ = synthetic_recording(spec, duration_s=6.0, rate_hz=125.0, current_noise_a=0.03, seed=6)
    _write_log(rec, tmp_path / "id.csv")
    _write_log(val, tmp_path / "val.csv")
    out = tmp_path / "params.yaml"
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--method", "all", "--urdf", str(tmp_path / "arm.urdf"), "--friction-eps", "0.01"]) == 0
    report = capsys.readouterr().out
    assert "ols:train" in report and "consistent:train" in report
    assert out.exists() and (tmp_path / "params.ols.yaml").exists() and (tmp_path / "arm.urdf").exists()
    assert load_params(out).standard is not None
    js = tmp_path / "v.json"
    assert main(["validate", str(tmp_path / "val.csv"), "--params", str(tmp_path / "params.ols.yaml"),
                 "--json-out", str(js), "--png", str(tmp_path / "png")]) == 0
    result = json.loads(js.read_text())
    assert {"e_n", "rms_nm", "rre_pct", "n_samples", "method"} <= set(result)
    assert result["method"] == "ols" and len(result["rms_nm"]) == 6
    assert max(result["rms_nm"]) < 2 * 0.03 * max(spec.drive_gains)
    assert (tmp_path / "png" / "validation_params.ols.png").stat().st_size > 1000
    # errors: one line, non-zero exit, no traceback
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: urident-params\nrobot: ur5\n")
    assert main(["validate", str(tmp_path / "val.csv"), "--params", str(bad)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("urident: error: ") and "bad.yaml" in err[-1]
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--drive-gains", "1,2"]) == 2
    assert "--drive-gains" in capsys.readouterr().err


# ----------------------------------------------------------------------------- friction extensions
def test_velocity_displacement_integrates_qd_and_restarts_per_segment():
    from urident.ident.friction import velocity_displacement

    t = np.array([0.0, 0.01, 0.03, 0.04, 0.05, 0.06])
    qd = np.tile(np.array([1.0, -2.0, 0, 0, 0, 0.5]), (6, 1))
    x = velocity_displacement(t, qd)
    np.testing.assert_allclose(x, (t - t[0])[:, None] * qd[0])
    seg = np.array([0, 0, 0, 1, 1, 1])
    x = velocity_displacement(t, qd, seg)
    np.testing.assert_allclose(x[3:], (t[3:] - t[3])[:, None] * qd[0])


def test_dahl_velocity_source_ignores_position_rounding(spec, sim):
    """A Dahl distance of 1e-4 rad is the q resolution of some logs: the velocity-driven state does
    not change when q is rounded to 1e-4 rad, the position-driven one does."""
    rec, qdd, _ = sim
    n = 1500
    t, q, qd, a = rec.t[:n], rec.q[:n], rec.qd[:n], qdd[:n]
    qr = np.round(q, 4)
    for source, changes in (("velocity", False), ("position", True)):
        cfg = ModelConfig(coulomb="dahl", dahl_rad=1e-4, dahl_source=source)
        fine = design_matrix(spec, cfg, q, qd, a, t=t)
        coarse = design_matrix(spec, cfg, qr, qd, a, t=t)
        col = [k for k, nm in enumerate(base_for(spec, False).names) if nm.startswith("fc")]
        diff = np.max(np.abs(fine[:, col] - coarse[:, col]))
        assert (diff > 0.1) == changes, (source, diff)
    # on finely sampled, consistent q and qd both sources give nearly the same state
    cfg_v = ModelConfig(coulomb="dahl", dahl_rad=1e-3, dahl_source="velocity")
    cfg_p = ModelConfig(coulomb="dahl", dahl_rad=1e-3, dahl_source="position")
    np.testing.assert_allclose(design_matrix(spec, cfg_v, q, qd, a, t=t),
                               design_matrix(spec, cfg_p, q, qd, a, t=t), atol=0.05)
    # without timestamps the positions drive the state (documented fallback)
    np.testing.assert_allclose(design_matrix(spec, cfg_v, q, qd, a), design_matrix(spec, cfg_p, q, qd, a))
    with pytest.raises(ConfigError, match="dahl_source"):
        ModelConfig(dahl_source="torque")


def test_load_dependent_and_sqrt_viscous_friction_are_recovered(spec, sim):
    """Torques with an extra load-dependent Coulomb term 0.02·|τ_L|·tanh(q̇/ε) and 0.5·sign(q̇)√|q̇|
    are fitted by the 'load' and 'sqrtvisc' extras, whose coefficients are recovered."""
    from urident.ident.design import column_names, nominal_link_torque
    from urident.model import regressor_blocks

    rec, qdd, tau = sim
    blocks = regressor_blocks(spec, rec.q, rec.qd, qdd, 0.01)
    load = np.abs(nominal_link_torque(spec, blocks)) * np.tanh(rec.qd / 0.01)
    tau_x = tau + 0.02 * load + 0.5 * np.sign(rec.qd) * np.sqrt(np.abs(rec.qd))
    data = Prepared(rec.t, rec.q, rec.qd, qdd, tau_x, spec.drive_gains)
    cfg = ModelConfig(extras=("load", "sqrtvisc"))
    names = column_names(spec, cfg)
    assert names[-12:] == [f"fcl{j}" for j in range(1, 7)] + [f"fvs{j}" for j in range(1, 7)]
    assert nonnegative_mask(spec, cfg)[-12:].all()
    model = identify(spec, data, "ols", cfg)
    np.testing.assert_allclose(model.values[-12:-6], 0.02, atol=2e-3)
    np.testing.assert_allclose(model.values[-6:], 0.5, atol=0.05)
    assert max(model.train_rms) < 1e-6


def test_select_dahl_rad_by_blocked_cv(spec):
    """Data generated with a Dahl friction state of δ = 3e-3 rad: CV inside the data picks it."""
    from urident.ident.crossval import select_dahl_rad
    from urident.ident.design import design_blocks

    rec, qdd, _ = synthetic_recording(spec, duration_s=8.0, rate_hz=125.0, seed=11)
    true = ModelConfig(coulomb="dahl", dahl_rad=3e-3, dahl_source="velocity")
    b = base_for(spec, False)
    w = design_blocks(spec, true, rec.q, rec.qd, qdd, t=rec.t)
    tau = w @ (b.combination @ spec.nominal_params)
    tau += np.random.default_rng(2).normal(0, 0.05, tau.shape)
    data = Prepared(rec.t, rec.q, rec.qd, qdd, tau, spec.drive_gains)
    best, scores = select_dahl_rad(spec, data, true, (3e-4, 1e-3, 3e-3, 1e-2), folds=4)
    assert best.dahl_rad == 3e-3
    assert [s.model.dahl_rad for s in scores] == [3e-4, 1e-3, 3e-3, 1e-2]


def test_cli_presets_and_overrides(spec, tmp_path, capsys):
    from urident.cli.main import main

    rec, _, _ = synthetic_recording(spec, duration_s=8.0, rate_hz=125.0, current_noise_a=0.03, seed=7)
    _write_log(rec, tmp_path / "id.csv")
    out = tmp_path / "p.yaml"
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--preset", "ur10e-2020"]) == 0
    report = capsys.readouterr().out
    assert "dahl_rad selected by 5-fold blocked CV" in report and "preset ur10e-2020" in report
    m = load_params(out)
    assert m.weighting == "joint" and m.model.reduced and m.model.coulomb == "dahl"
    assert m.model.dahl_source == "velocity" and set(m.model.extras) == {"load", "sqrtvisc", "stribeck"}
    from urident.ident.presets import DAHL_GRID

    assert m.model.dahl_rad in DAHL_GRID
    # explicit options override the fixed set (fixed distance: no CV)
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--model", "ur10e-2020", "--weighting", "none", "--dahl-rad", "1e-3", "--full",
                 "--friction-extra", "load", "--overwrite"]) == 0
    assert "selected by" not in capsys.readouterr().out
    m = load_params(out)
    assert (m.weighting, m.model.dahl_rad, m.model.reduced, m.model.extras) == ("none", 1e-3, False, ("load",))
    # the paper preset is the default configuration
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--preset", "paper", "--overwrite"]) == 0
    m = load_params(out)
    assert m.model == ModelConfig() and m.weighting == "none"
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--dahl-rad", "auto", "--overwrite"]) == 2
    assert "needs a Dahl state" in capsys.readouterr().err
    # --model best is real-robot is auto, which chooses its friction itself: the fixed set is named
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--model", "best", "--weighting", "none", "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "--weighting conflicts with --preset best (= auto)" in err and "--preset ur10e-2020" in err


def test_reports_name_the_friction_model_they_used():
    from urident.ident.design import ModelConfig

    assert ModelConfig().friction_summary() == "tanh friction, eps = 0.01 rad/s"
    text = ModelConfig(coulomb="dahl", dahl_source="velocity", extras=("load",)).friction_summary()
    assert text.startswith("Dahl friction") and "velocity" in text and text.endswith("+ load")
    assert ModelConfig(coulomb="hold").friction_summary().startswith("hold friction")
