"""Per-joint friction terms chosen by blocked CV (``--preset auto``, urident.ident.friction_select)."""

from __future__ import annotations

import numpy as np
import pytest

from urident.errors import ConfigError
from urident.ident import ModelConfig, Prepared, identify, load_params, save_params
from urident.ident.crossval import cross_validate
from urident.ident.design import base_for, column_kinds, column_names, design_blocks, design_chunks
from urident.ident.friction_select import select_friction
from urident.ident.synthetic import synthetic_recording
from urident.model import load_robot


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


def gaz(qd, phi1, phi2, phi3):
    """Gaz et al.'s sigmoid friction with offset (exact, not the linearised columns)."""
    s = lambda x: 1.0 / (1.0 + np.exp(-x))  # noqa: E731
    return phi1 * s(phi2 * (qd + phi3)) - phi1 * s(phi2 * phi3)


@pytest.fixture(scope="module")
def gaz_data(spec):
    """The paper's model plus, on joint 5 only, an asymmetric sigmoid friction (outside the
    family's columns) and a load-dependent Coulomb term on joint 2; current noise on every joint."""
    rec, qdd, _ = synthetic_recording(spec, duration_s=10.0, rate_hz=125.0, seed=21)
    truth = ModelConfig(joint_extras=((), ("load",), (), (), (), ()))
    b = base_for(spec, False)
    blocks = design_blocks(spec, truth, rec.q, rec.qd, qdd, t=rec.t)
    tau = blocks @ np.r_[b.combination @ spec.nominal_params, 0.05]
    tau[:, 4] += gaz(rec.qd[:, 4], 3.0, 20.0, 0.03)
    tau += np.random.default_rng(4).normal(0, 0.1, tau.shape)
    return Prepared(rec.t, rec.q, rec.qd, qdd, tau, spec.drive_gains)


def test_joint_extras_columns_and_params_roundtrip(spec, tmp_path, gaz_data):
    m = ModelConfig(reduced=True, coulomb="dahl", dahl_rad=2e-4, dahl_source="velocity",
                    joint_coulomb=("tanh", "dahl@2e-4", "dahl@5e-5", "tanh", "tanh", "dahl@0.0002"),
                    joint_extras=((), ("load",), (), (), ("sigmoid@0.05", "sigoffset@0.050"), ("dahl@1e-3",)))
    assert m.joint_extras[4] == ("sigmoid@0.05", "sigoffset@0.05")   # canonical spelling
    assert m.joint_coulomb[1] == "dahl@0.0002"
    names = column_names(spec, m)
    nb = base_for(spec, True).n_base
    assert names[nb:] == ["fcl2", "fg5@0.05", "fgo5@0.05", "fh6@0.001"]
    assert column_kinds(spec, m)[nb:] == ["load_friction", "sigmoid", "sigmoid_offset", "dahl"]
    # each column sits on its own joint's rows only
    blocks = design_blocks(spec, m, gaz_data.q[:300], gaz_data.qd[:300], gaz_data.qdd[:300], t=gaz_data.t[:300])
    rows = np.any(blocks[:, :, nb:] != 0, axis=0)
    assert [int(np.flatnonzero(rows[:, c])[0]) for c in range(4)] == [1, 4, 4, 5] and rows.sum() == 4
    # chunked (history states of every distance carried over) equals the whole-array regressor
    whole = design_blocks(spec, m, gaz_data.q, gaz_data.qd, gaz_data.qdd, t=gaz_data.t)
    parts = np.concatenate([b for _, _, b in design_chunks(spec, m, gaz_data.q, gaz_data.qd, gaz_data.qdd,
                                                            t=gaz_data.t, chunk=97)])
    np.testing.assert_allclose(parts, whole, atol=1e-12)
    fitted = identify(spec, gaz_data, "ols", m, "joint")
    save_params(fitted, tmp_path / "p.yaml")
    back = load_params(tmp_path / "p.yaml")
    assert back.model == m and back.names == fitted.names and back.kinds == fitted.kinds


@pytest.mark.parametrize("bad_coulomb", [("tanh",) * 5, ("dahl",) * 6, ("hold",) * 6, ("dahl@0",) * 6])
def test_joint_coulomb_rejects_bad_states(bad_coulomb):
    with pytest.raises(ConfigError):
        ModelConfig(joint_coulomb=bad_coulomb)


@pytest.mark.parametrize("bad", [((),) * 5, (("nope",),) + ((),) * 5, (("load@2",),) + ((),) * 5,
                                 (("sigmoid@-1",),) + ((),) * 5, (("load", "load"),) + ((),) * 5])
def test_joint_extras_rejects_bad_terms(bad):
    with pytest.raises(ConfigError):
        ModelConfig(joint_extras=bad)


def test_selection_finds_the_joint_with_asymmetric_friction_and_its_cv_is_exact(spec, gaz_data):
    sel = select_friction(spec, gaz_data, ModelConfig(reduced=True), folds=4, dahl_grid=(2e-4,))
    assert sel.model.joint_coulomb == ("tanh",) * 6     # the data have no presliding memory
    chosen = [set(t.split("@")[0] for t in terms) for terms in sel.model.joint_extras]
    assert chosen[4] & {"sigoffset", "asym", "offset"}     # the asymmetry is carried on joint 5
    assert "load" in chosen[1]
    assert sum(len(c) for k, c in enumerate(chosen) if k not in (1, 4)) <= 1   # little on clean joints
    # what the report quotes is the blocked CV of urident.ident.crossval on the chosen model
    cv = cross_validate(spec, gaz_data, sel.model, "joint", "ols", folds=4)
    np.testing.assert_allclose([j.rms for j in sel.joints], cv.rms_nm, rtol=1e-6)
    assert sel.joints[4].rms < 0.8 * sel.joints[4].steps[0].rms_before
    text = sel.text()
    assert "J5: tanh;" in text and "tried per joint" in text and "sigmoid+offset eps=0.05" in text


def _shifted_to_share(t, q, qd, share):
    """q, q̇ with joint 5's velocity shifted up until its backward travel is ``share`` of its travel."""
    from urident.ident.friction_select import direction_shares

    lo, hi = 0.0, 0.02 - qd[:, 4].min()
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        v = qd[:, 4] + mid
        back = np.clip(-v, 0, None).sum() / np.abs(v).sum()
        lo, hi = (mid, hi) if back > share else (lo, mid)
    q, qd = q.copy(), qd.copy()
    qd[:, 4] += hi
    q[:, 4] += hi * t
    assert direction_shares(Prepared(t, q, qd, qd, qd, np.ones(6)))[4] == pytest.approx(share, abs=2e-3)
    return q, qd


@pytest.mark.parametrize("backward", [None, 0.05, 0.0])
def test_a_term_that_makes_the_directions_differ_needs_both_directions(spec, backward):
    """Joint 5's friction has an even part (1.5·tanh²(q̇/0.2), the sigmoid-with-offset's column).
    Moving both ways, the sigmoid with offset is chosen. Moving mostly forwards (its velocity
    shifted up until 5 % or none of its travel is backwards), the same columns fit the forward
    samples as well, but what they predict backwards rests on a few reversals or on no sample at
    all: no term with a part even in q̇ is offered, and the report says why."""
    from urident.ident.friction_select import MIN_DIRECTION_SHARE

    rec, qdd, _ = synthetic_recording(spec, duration_s=10.0, rate_hz=125.0, seed=21)
    q, qd = (rec.q, rec.qd) if backward is None else _shifted_to_share(rec.t, rec.q, rec.qd, backward)
    tau = design_blocks(spec, ModelConfig(), q, qd, qdd, t=rec.t) @ (base_for(spec, False).combination
                                                                     @ spec.nominal_params)
    tau[:, 4] += 1.5 * np.tanh(qd[:, 4] / 0.2) ** 2
    tau += np.random.default_rng(4).normal(0, 0.1, tau.shape)
    sel = select_friction(spec, Prepared(rec.t, q, qd, qdd, tau, spec.drive_gains), ModelConfig(reduced=True),
                          folds=4, dahl_grid=(2e-4,))
    j5 = {t.split("@")[0] for t in sel.model.joint_extras[4]}
    if backward is None:
        assert "sigoffset" in j5
        assert min(sel.joints[4].steps[0].by_direction) > 0
        assert sel.directional_joints == tuple(range(6))
        assert "offset, |z| and sigmoid offset offered on every joint" in sel.text()
    else:
        assert MIN_DIRECTION_SHARE > backward
        assert not j5 & {"offset", "asym", "sigoffset"} and j5      # an odd term carries the shape
        assert 4 not in sel.directional_joints and sel.to_dict()["directional_joints"] == [1, 2, 3, 4, 6]
        assert sel.to_dict()["direction_share"][4] == pytest.approx(backward, abs=2e-3)
        assert "offset, |z| and sigmoid offset not offered on J5 (moved < 10 % of its travel one way" in sel.text()


def test_a_directional_term_is_scored_on_each_direction(spec, gaz_data):
    """Below the share rule, a directional term must still lower the held-out error of each
    direction's samples: the report's steps carry both decreases, every one of them positive."""
    sel = select_friction(spec, gaz_data, ModelConfig(reduced=True), folds=4, dahl_grid=(2e-4,))
    steps = [s for c in sel.joints for s in c.steps if s.by_direction is not None]
    assert steps and all(min(s.by_direction) > 0 for s in steps)


def thermal_run(spec, effect: bool, rise_c=(8.0, 10.0, 12.0, 6.0, 5.0, 4.0)):
    """A 10 s run whose joint temperatures drift up by ``rise_c`` (4-12 °C); with ``effect``, joint
    3's friction follows them through the simulated controller's thermal_drift effect (viscous
    −2 %/°C, Coulomb −1 %/°C relative to the first sample, no hidden warm-up)."""
    from dataclasses import replace

    from urident.simcontroller.effects import load_effects, parse_effects_text

    rec, qdd, _ = synthetic_recording(spec, duration_s=10.0, rate_hz=125.0, seed=5)
    n = len(rec)
    temps = 30.0 + np.array(rise_c) * np.linspace(0.0, 1.0, n)[:, None]
    current = rec.current
    if effect:
        es = load_effects(parse_effects_text(
            "effects:\n  - {name: thermal_drift, joints: [3], viscous_change_per_c: -0.02, "
            "coulomb_change_per_c: -0.01, warmup_c: 0}\n"), spec=spec)
        current = current + es.offline_extra_torque(rec.t, rec.q, rec.qd, qdd, np.zeros((n, 6)), temps) / spec.drive_gains
    return replace(rec, current=current, temperature=temps)


def temperature_terms(model):
    return [[t for t in terms if t.startswith(("tempvisc", "tempcoul"))] for terms in model.joint_extras]


def test_temperature_terms_chosen_where_friction_follows_the_temperature(spec, tmp_path):
    from dataclasses import replace

    from urident.ident import PreprocessConfig, predict_recordings, prepare

    data = prepare([thermal_run(spec, True)], spec, PreprocessConfig())
    assert data.temperature.shape == data.q.shape
    sel = select_friction(spec, data, ModelConfig(reduced=True), dahl_grid=(2e-4,))
    chosen = temperature_terms(sel.model)
    assert chosen[2] and not any(chosen[j] for j in (0, 1, 3, 4, 5))
    assert chosen[2][0].endswith(f"@{np.round(data.temperature[:, 2].mean(), 1):g}")   # T_ref: the mean
    assert "joint temperature: offered" in sel.text()
    plain = select_friction(spec, prepare([thermal_run(spec, False)], spec, PreprocessConfig()),
                            ModelConfig(reduced=True), dahl_grid=(2e-4,))
    assert not any(temperature_terms(plain.model))
    # the model predicts from a log's temperatures, and says so when a log has none
    fitted = identify(spec, data, "ols", sel.model, "joint")
    save_params(fitted, tmp_path / "p.yaml")
    back = load_params(tmp_path / "p.yaml")
    assert back.model == sel.model
    rec = thermal_run(spec, True)
    assert predict_recordings(back, rec, spec).validation().rms_nm[2] < 0.3
    with pytest.raises(ConfigError, match="no \\(finite\\) joint temperature"):
        predict_recordings(back, replace(rec, temperature=None), spec)


def test_temperature_terms_offered_only_where_the_temperature_moved(spec):
    """A joint whose temperature moved less than MIN_TEMPERATURE_SPAN_C gets no temperature term
    (what it would fit is any slow drift, extrapolated once the temperature leaves that span)."""
    from urident.ident import PreprocessConfig, prepare
    from urident.ident.friction_select import MIN_TEMPERATURE_SPAN_C

    assert MIN_TEMPERATURE_SPAN_C == 1.0
    data = prepare([thermal_run(spec, True, (0.5, 0.5, 12.0, 0.5, 0.5, 0.5))], spec, PreprocessConfig())
    sel = select_friction(spec, data, ModelConfig(reduced=True), dahl_grid=(2e-4,))
    assert sel.temperature_joints == (2,)
    chosen = temperature_terms(sel.model)
    assert chosen[2] and not any(chosen[j] for j in (0, 1, 3, 4, 5))
    assert "joint temperature: offered on J3 (moved >= 1 °C" in sel.text()
    assert sel.to_dict()["temperature_joints"] == [3]
    # the same effect on joint 3, its temperature moving 0.5 °C: nothing offered anywhere
    still = prepare([thermal_run(spec, True, (0.5,) * 6)], spec, PreprocessConfig())
    sel = select_friction(spec, still, ModelConfig(reduced=True), dahl_grid=(2e-4,))
    assert sel.temperature_joints == () and not any(temperature_terms(sel.model))
    assert "not offered: no joint's temperature moved 1 °C" in sel.text()
    assert sel.to_dict()["temperature_span_c"][2] == pytest.approx(0.5, abs=0.01)


def test_fold_test_takes_a_gain_on_every_fold_whatever_its_spread():
    """The term rule's fold test: mean > MIN_T standard errors, or a gain on every fold."""
    from urident.ident.friction_select import MIN_T, fold_test

    spread = np.array([4.5, 0.6, 0.2, 0.4, 0.02])      # one fold holds most of the gain
    t, every, ok = fold_test(spread)
    assert t < MIN_T and every and ok
    t, every, ok = fold_test(np.r_[spread[:4], -0.02])  # and one fold loses
    assert t < MIN_T and not every and not ok
    t, every, ok = fold_test(np.array([1.0, 1.1, 0.9, 1.0, -0.05]))
    assert t > MIN_T and not every and ok
    assert not fold_test(np.array([0.1]))[2]             # one fold is no evidence


def test_temperature_not_offered_without_it_and_never_filled(spec, gaz_data):
    from dataclasses import replace

    from urident.ident import PreprocessConfig, prepare

    rec, _, _ = synthetic_recording(spec, duration_s=2.0, rate_hz=125.0, seed=3)
    warm = replace(rec, temperature=np.full((len(rec), 6), 35.0))
    assert prepare([warm, warm], spec, PreprocessConfig()).temperature.shape == (2 * len(rec), 6)
    assert prepare([warm, rec], spec, PreprocessConfig()).temperature is None   # one log lacks it
    bad = np.full((len(rec), 6), 35.0)
    bad[5, 2] = np.nan
    assert prepare([replace(rec, temperature=bad)], spec, PreprocessConfig()).temperature is None
    sel = select_friction(spec, gaz_data.select(slice(0, 600)), ModelConfig(reduced=True), folds=3,
                          dahl_grid=())
    assert "joint temperature: not offered: the logs carry no joint temperature" in sel.text()
    assert sel.t_ref is None and not any("temperature" in f for f in sel.family)
    with pytest.raises(ConfigError, match="reference temperature"):
        ModelConfig(joint_extras=(("tempvisc",),) + ((),) * 5)
    with pytest.raises(ConfigError, match="reference temperature"):
        ModelConfig(extras=("tempcoul",))


def test_cli_preset_auto(spec, tmp_path, capsys):
    from urident.cli.main import main
    from urident.logs import LogWriter

    rec, _, _ = synthetic_recording(spec, duration_s=6.0, rate_hz=125.0, current_noise_a=0.03, seed=7)
    with LogWriter(tmp_path / "id.csv", fields=["timestamp", "actual_q", "actual_qd", "actual_current"],
                   metadata={"robot": rec.robot, "rate_hz": rec.rate_hz}) as w:
        for k in range(len(rec)):
            w.append_sample(float(rec.t[k]), q=rec.q[k], qd=rec.qd[k], current=rec.current[k])
    out = tmp_path / "p.yaml"
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out),
                 "--preset", "auto"]) == 0
    report = capsys.readouterr().out
    assert "preset auto" in report and "chosen per joint by 5-fold blocked CV" in report
    assert all(f"  J{j}:" in report for j in range(1, 7))
    m = load_params(out)
    assert m.weighting == "joint" and m.model.reduced and len(m.model.joint_extras) == 6
    assert main(["validate", str(tmp_path / "id.csv"), "--params", str(out)]) == 0
    capsys.readouterr()
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out), "--overwrite",
                 "--preset", "auto", "--friction-extra", "load"]) == 2
    assert "--friction-extra conflicts with --preset auto" in capsys.readouterr().err


def test_two_terms_that_pay_only_together_are_taken_as_a_pair(monkeypatch):
    """One term at a time, forward selection misses two terms that pay only together: each alone
    helps some folds and hurts another. The case of ``benchmarks/friction_wrist.py``: the UR5's
    identification trajectory simulated at 125 Hz with the realistic effects and Gaz et al.'s
    sigmoid friction with offset on the wrist, the first 10 s identified. After the Coulomb states
    are chosen, a joint whose single terms all fail tries pairs; a pair passes both fold tests and
    each of its terms pays beside the other. The states are chosen without pairs."""
    from dataclasses import fields, replace
    from pathlib import Path

    from scipy.special import expit

    from urident.excitation.files import load_trajectory
    from urident.ident import PreprocessConfig, prepare
    from urident.ident import friction_select as fs
    from urident.model.parameters import COULOMB
    from urident.simcontroller.offline import simulate

    spec = load_robot("ur5")
    traj = load_trajectory(Path(__file__).resolve().parents[1] / "experiments" / "ur5_ident.yaml")
    rec = simulate(spec, traj, rate_hz=125.0, effects="realistic", seed=2).to_recording()
    phi1, phi3 = 0.8 * spec.nominal_params[COULOMB], np.array([0.0, 0.0, 0.0, 0.04, -0.02, 0.03])
    tau = np.where(phi3 != 0, phi1 * (expit(25.0 * (rec.qd + phi3)) - expit(25.0 * phi3)), 0.0)
    rec = replace(rec, current=rec.current + tau / spec.drive_gains)
    n = len(rec.t) // 2
    first = replace(rec, **{f.name: getattr(rec, f.name)[:n] for f in fields(rec)
                            if isinstance(getattr(rec, f.name), np.ndarray) and len(getattr(rec, f.name)) == len(rec.t)})
    data = prepare([first], spec, PreprocessConfig())
    sel = fs.select_friction(spec, data)
    pairs = [(j, s) for j, c in enumerate(sel.joints) for s in c.steps if s.pair]
    assert pairs
    text = sel.text()
    for j, s in pairs:
        assert len(s.labels) == 2 and set(s.labels) <= set(sel.family)
        assert s.every_fold and s.t_stat > fs.MIN_T and s.gain_pct >= 200 * fs.MIN_GAIN
        assert f"{s.term} ({s.rms_before:.3f} -> {s.rms_after:.3f}" in text and "together" in text
        assert set(s.labels) <= set(sel.to_dict()["joints"][j]["terms"])
    monkeypatch.setattr(fs, "_best_pair", lambda *a, **k: None)
    alone = fs.select_friction(spec, data)
    assert alone.model.joint_coulomb == sel.model.joint_coulomb
    for j, _ in pairs:
        assert sel.joints[j].rms < alone.joints[j].rms
    assert sel.mean_rms_nm < alone.mean_rms_nm
