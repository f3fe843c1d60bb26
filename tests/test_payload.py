"""Payload identification on an identified arm (issue 17): ``urident payload``, the payload file,
predicting with a payload, and the bad inputs that must be one line and exit 2.

Data: offline simulations (``urident simulate``) of the UR5 pair in ``experiments/``, the arm
identified without a load, the loaded run carrying a ``payload_error`` of known mass and centre
of mass."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from urident.cli.main import main
from urident.model.payload import Payload, flange_map
from urident.ident.payload_file import load_payload, save_payload
from urident.model import load_robot
from urident.model.parameters import body_params

ROOT = Path(__file__).resolve().parent.parent
MASS, COM = 2.0, [0.01, -0.02, 0.06]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("payload")
    effects = d / "effects_load.yaml"
    effects.write_text(yaml.safe_dump({"effects": [{"name": "payload_error", "mass_kg": MASS,
                                                    "offset_m": COM}]}))
    traj = yaml.safe_load((ROOT / "experiments" / "ur5_valid.yaml").read_text())
    for key in ("a_rad_s", "b_rad_s"):   # the wrist joints 4-6 held still
        for j in (3, 4, 5):
            traj["trajectory"][key][j] = [0.0] * len(traj["trajectory"][key][j])
    for j in (3, 4, 5):
        traj["trajectory"]["q_start_rad"][j] = traj["trajectory"]["q0_rad"][j]
    still = d / "still_traj.yaml"
    still.write_text(yaml.safe_dump(traj))
    for args in (["--trajectory", str(ROOT / "experiments/ur5_ident.yaml"), "--out", str(d / "arm.csv"), "--seed", "1"],
                 ["--trajectory", str(ROOT / "experiments/ur5_valid.yaml"), "--out", str(d / "load.csv"),
                  "--effects", str(effects), "--seed", "2"],
                 ["--trajectory", str(ROOT / "experiments/ur5_ident.yaml"), "--out", str(d / "load_ident.csv"),
                  "--effects", str(effects), "--seed", "3"],
                 ["--trajectory", str(still), "--out", str(d / "still.csv"), "--effects", str(effects)]):
        assert main(["simulate", *args]) == 0
    assert main(["identify", str(d / "arm.csv"), "--robot", "ur5", "--out", str(d / "arm_params.yaml")]) == 0
    return d


def test_flange_map_matches_the_tool_frame():
    spec = load_robot("ur10e")
    inertia = np.array([[0.02, 0.001, -0.002], [0.001, 0.03, 0.0005], [-0.002, 0.0005, 0.01]])
    p = Payload("ur10e", 3.0, [0.02, -0.01, 0.08], inertia)
    r, t = spec.tool_rotation, spec.tool_xyz
    expected = body_params(3.0, t + r @ p.com_m, r @ inertia @ r.T)
    np.testing.assert_allclose(p.body_params(spec), expected, atol=1e-12)
    np.testing.assert_allclose(flange_map(spec) @ p.flange_vector, expected, atol=1e-12)


def test_payload_identifies_mass_and_centre_of_mass(runs, capsys):
    out, js = runs / "p.yaml", runs / "p.json"
    capsys.readouterr()
    assert main(["payload", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                 "--out", str(out), "--json-out", str(js)]) == 0
    text = capsys.readouterr().out
    assert "set_target_payload(" in text and "script manual" in text and "identifiable:" in text
    data = json.loads(js.read_text())
    for key in ("mass_kg", "com_m", "inertia_kg_m2", "sigma", "identifiable"):
        assert key in data
    assert abs(data["mass_kg"] - MASS) < 0.02 * MASS
    assert np.max(np.abs(np.array(data["com_m"]) - COM)) < 0.003
    assert {"m", "mcx", "mcy", "mcz"} <= set(data["identifiable"])
    assert set(data["sigma"]) >= {"mass_kg", "com_m", "inertia_kg_m2"}
    assert data["fit"]["e_n_with_payload"] < 0.5 * data["fit"]["e_n_arm_alone"]
    p = load_payload(out, load_robot("ur5"))
    assert abs(p.mass_kg - data["mass_kg"]) < 1e-12
    assert np.all(np.linalg.eigvalsh(p.inertia_kg_m2) >= -1e-9)


def test_payload_refuses_an_existing_output(runs, capsys):
    out = runs / "exists.yaml"
    out.write_text("x")
    assert main(["payload", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                 "--out", str(out)]) == 2


def _one_line_exit2(capsys, argv, needle):
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("urident: error:") and "\n" not in err and "Traceback" not in err
    assert needle in err, err


def test_no_wrist_motion_is_bad_input(runs, capsys):
    _one_line_exit2(capsys, ["payload", str(runs / "still.csv"), "--params", str(runs / "arm_params.yaml"),
                             "--out", str(runs / "x.yaml")], "wrist")


def test_params_without_base_parameters_is_bad_input(runs, capsys):
    bad = runs / "nobase.yaml"
    data = yaml.safe_load((runs / "arm_params.yaml").read_text())
    del data["base_parameters"]
    bad.write_text(yaml.safe_dump(data))
    _one_line_exit2(capsys, ["payload", str(runs / "load.csv"), "--params", str(bad),
                             "--out", str(runs / "x.yaml")], "base_parameters")


def test_bad_payload_files(tmp_path):
    from urident.model.payload import PayloadError

    p = tmp_path / "p.yaml"
    save_payload(Payload("ur10e", 1.0, [0, 0, 0.05], np.eye(3) * 1e-3), p)
    assert load_payload(p, load_robot("ur10e")).mass_kg == 1.0
    with pytest.raises(PayloadError, match="robot"):
        load_payload(p, load_robot("ur5"))
    data = yaml.safe_load(p.read_text())
    for key, value, needle in (("mass_kg", 0.0, "mass_kg"), ("mass_kg", -1.0, "mass_kg"),
                               ("com_m", [0, 0], "com_m"), ("surprise", 1, "surprise"),
                               ("inertia_kg_m2", [[1, 0, 0], [0, -1, 0], [0, 0, 1]], "inertia")):
        bad = dict(data, **{key: value})
        p.write_text(yaml.safe_dump(bad))
        with pytest.raises(PayloadError, match=needle):
            load_payload(p)


def _validate(runs, capsys, *extra):
    js = runs / f"val{len(list(runs.glob('val*.json')))}.json"
    assert main(["validate", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                 "--json-out", str(js), *extra]) == 0
    return json.loads(js.read_text())


def test_validate_view_and_gap_with_a_payload(runs, capsys):
    from urident.ident import load_params, predict_recordings
    from urident.model.payload import Payload
    from urident.logs import load_log

    spec = load_robot("ur5")
    true = runs / "true_payload.yaml"
    save_payload(Payload("ur5", MASS, COM, np.zeros((3, 3))), true)
    alone = _validate(runs, capsys)
    loaded = _validate(runs, capsys, "--payload", str(true))
    assert loaded["payload"] == str(true)
    assert loaded["e_n"] < 0.2 * alone["e_n"]
    # the library path adds exactly the payload's torque
    params = load_params(runs / "arm_params.yaml")
    rec = load_log(runs / "load.csv")
    p0 = predict_recordings(params, rec, spec)
    p1 = predict_recordings(params, rec, spec, payload=load_payload(true, spec))
    from urident.ident.payload import payload_torque

    np.testing.assert_allclose(p1.tau_predicted - p0.tau_predicted,
                               payload_torque(spec, load_payload(true), p0.data.q, p0.data.qd, p0.data.qdd),
                               atol=1e-9)
    rrd = runs / "view.rrd"
    capsys.readouterr()
    assert main(["view", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                 "--payload", str(true), "--save", str(rrd)]) == 0
    e_view = float(capsys.readouterr().out.split("e_N = ")[1].split(",")[0])
    assert abs(e_view - loaded["e_n"]) < 1e-4
    # a payload file for another robot is refused in one line
    other = runs / "ur10e_payload.yaml"
    save_payload(Payload("ur10e", MASS, COM, np.zeros((3, 3))), other)
    _one_line_exit2(capsys, ["validate", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                             "--payload", str(other)], "ur10e")
    zero = runs / "zero_payload.yaml"
    zero.write_text(true.read_text().replace(f"mass_kg: {MASS}", "mass_kg: 0.0"))
    _one_line_exit2(capsys, ["view", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                             "--payload", str(zero), "--save", str(runs / "v2.rrd")], "mass_kg")


def test_identify_the_arm_from_loaded_runs_with_a_known_payload(runs, capsys):
    true = runs / "true_payload2.yaml"
    save_payload(Payload("ur5", MASS, COM, np.zeros((3, 3))), true)
    out = runs / "arm_from_loaded.yaml"
    assert main(["identify", str(runs / "load.csv"), "--robot", "ur5", "--out", str(out),
                 "--payload", str(true)]) == 0
    naive = runs / "arm_naive.yaml"
    assert main(["identify", str(runs / "load.csv"), "--robot", "ur5", "--out", str(naive)]) == 0
    # on the unloaded identification run, the arm identified with the payload removed predicts
    # as well as the one identified there; the one that ignored the payload does not
    e = {}
    for name in ("arm_params", "arm_from_loaded", "arm_naive"):
        js = runs / f"{name}_on_arm.json"
        assert main(["validate", str(runs / "arm.csv"), "--params", str(runs / f"{name}.yaml"),
                     "--json-out", str(js)]) == 0
        e[name] = json.loads(js.read_text())["e_n"]
    assert e["arm_from_loaded"] < 2 * e["arm_params"] + 0.01
    assert e["arm_naive"] > 3 * e["arm_from_loaded"]


def test_gap_with_the_known_payload_finds_nothing_left(runs):
    true = runs / "true_payload3.yaml"
    save_payload(Payload("ur5", MASS, COM, np.zeros((3, 3))), true)
    found = {}
    for name, extra in (("without", []), ("with", ["--payload", str(true)])):
        js = runs / f"gap_{name}.json"
        assert main(["gap", "--robot", "ur5", "--ident", str(runs / "load_ident.csv"), "--valid",
                     str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                     "--json-out", str(js), *extra]) == 0
        found[name] = [f["effect"] for f in json.loads(js.read_text())["findings"]]
    assert "payload_error" in found["without"]
    assert found["with"] == []


def test_drive_gains_from_a_known_load(tmp_path, capsys):
    factors = [1.05, 0.97, 1.08, 1.02, 0.95, 1.1]
    tk = {"name": "torque_constant_error", "gain_factor": factors}
    load = {"name": "payload_error", "mass_kg": 4.0, "offset_m": [0.03, 0.0, 0.05]}
    for name, effects, seed in (("without", [tk], "4"), ("with", [tk, load], "5")):
        (tmp_path / f"eff_{name}.yaml").write_text(yaml.safe_dump({"effects": effects}))
        assert main(["simulate", "--trajectory", str(ROOT / "experiments/ur5_ident.yaml"), "--out",
                     str(tmp_path / f"{name}.csv"), "--effects", str(tmp_path / f"eff_{name}.yaml"),
                     "--seed", seed]) == 0
    gains, js = tmp_path / "gains.yaml", tmp_path / "gains.json"
    assert main(["drive-gains", "--robot", "ur5", "--without", str(tmp_path / "without.csv"), "--with",
                 str(tmp_path / "with.csv"), "--payload-mass", "4", "--payload-com", "0.03,0,0.05",
                 "--out", str(gains), "--json-out", str(js)]) == 0
    data = json.loads(js.read_text())
    true = np.array(load_robot("ur5").drive_gains) * factors
    est, sigma = np.array(data["drive_gains"]), np.array(data["sigma"])
    ok = np.array(data["calibrated"])
    assert ok[1:5].all()    # the load's gravity torque reaches joints 2-5 strongly
    assert np.all(np.abs(est[ok] / true[ok] - 1) < 0.01)
    assert np.all(np.abs(est - true) < 4 * sigma + 0.01 * true)
    import urident as ur   # the API computes what the command wrote

    api = ur.calibrate_drive_gains([tmp_path / "without.csv"], [tmp_path / "with.csv"], "ur5",
                                   Payload("ur5", 4.0, [0.03, 0.0, 0.05], np.zeros((3, 3))))
    assert json.loads(api.to_json()) == data
    # the gains file works wherever --drive-gains does
    capsys.readouterr()
    assert main(["identify", str(tmp_path / "without.csv"), "--robot", "ur5", "--out", str(tmp_path / "p.yaml"),
                 "--drive-gains", str(gains)]) == 0
    from urident.ident import load_params

    np.testing.assert_allclose(load_params(tmp_path / "p.yaml").drive_gains, est)
    bad = tmp_path / "bad.yaml"
    bad.write_text(gains.read_text().replace("format: urident-drive-gains", "format: other"))
    _one_line_exit2(capsys, ["identify", str(tmp_path / "without.csv"), "--robot", "ur5", "--out",
                             str(tmp_path / "q.yaml"), "--drive-gains", str(bad)], "--drive-gains")


def test_payload_with_a_tare_run_of_the_same_trajectory(runs, capsys):
    """``--unloaded``: the arm model's own errors on that motion are fit on both runs and removed."""
    js = runs / "tare.json"
    capsys.readouterr()
    assert main(["payload", str(runs / "load_ident.csv"), "--params", str(runs / "arm_params.yaml"),
                 "--unloaded", str(runs / "arm.csv"), "--out", str(runs / "tare.yaml"), "--json-out", str(js)]) == 0
    assert "tare: 1 unloaded log(s)" in capsys.readouterr().out
    data = json.loads(js.read_text())
    assert abs(data["mass_kg"] - MASS) < 0.02 * MASS
    assert np.max(np.abs(np.array(data["com_m"]) - COM)) < 0.003
    assert data["fit"]["unloaded_logs"] == [str(runs / "arm.csv")]
    import urident as ur   # the API gives the document the command wrote, by construction

    api = ur.identify_payload([runs / "load_ident.csv"], runs / "arm_params.yaml", unloaded=[runs / "arm.csv"])
    assert json.loads(api.to_json()) == data
    assert api.payload.mass_kg == pytest.approx(data["mass_kg"])
    _one_line_exit2(capsys, ["payload", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                             "--unloaded", str(runs / "still.csv"), "--out", str(runs / "x.yaml")],
                    f"--unloaded {runs / 'still.csv'}: the wrist joints")


def test_a_tare_from_rows_of_another_log_must_be_the_same_motion(runs, capsys):
    """``--unloaded-rows``: the tare's rows apart from the loaded logs' ``--rows``; refused unless the
    two selections are the same motion (joints within 0.05 rad)."""
    args = ["payload", str(runs / "load_ident.csv"), "--params", str(runs / "arm_params.yaml"),
            "--rows", "301-1000", "--unloaded", str(runs / "arm.csv"), "--out", str(runs / "part.yaml")]
    capsys.readouterr()
    assert main([*args, "--unloaded-rows", "301-1000"]) == 0
    assert "tare: 1 unloaded log(s) of" in capsys.readouterr().out
    _one_line_exit2(capsys, [*args, "--unloaded-rows", "341-1040", "--overwrite"],
                    f"--unloaded {runs / 'arm.csv'} rows 341-1040: not the same motion as the loaded log")
    _one_line_exit2(capsys, [*args, "--unloaded-rows", "301-1300", "--overwrite"], "the loaded log's")
    _one_line_exit2(capsys, ["payload", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                             "--unloaded", str(runs / "arm.csv"), "--out", str(runs / "x.yaml")],
                    "tolerance 0.05 rad")
    _one_line_exit2(capsys, ["payload", str(runs / "load.csv"), "--params", str(runs / "arm_params.yaml"),
                             "--unloaded-rows", "1-100", "--out", str(runs / "x.yaml")], "--unloaded-rows needs")


def _pieces(t, q, tau, segment=None):
    from urident.ident.preprocess import Prepared

    z = np.zeros_like(q)
    return Prepared(t, q, z, z, tau, np.ones(6), segment=segment)


def test_tare_is_laid_over_the_loaded_run_at_the_same_point_of_the_motion():
    """``tare_at``: the tare's residual is read where the tare was at the loaded sample's joint
    positions, its time offset found (here 1.25 periods late); a tare of another motion covers
    nothing; two tares are averaged and their sharing between loaded runs is counted."""
    from urident.ident.payload import tare_at

    dt = 0.002
    t = np.arange(2000) * dt
    motion = lambda s: np.column_stack([0.3 * np.sin(2.0 * s + j) for j in range(6)])  # noqa: E731
    loaded = _pieces(t, motion(t), np.zeros((len(t), 6)))
    late = t + 1.25 * dt                                  # the tare's recording started later
    tare = _pieces(t, motion(late), np.zeros((len(t), 6)))
    residual = np.column_stack([np.cos(3.0 * late + j) for j in range(6)])  # a function of the motion
    mean, count, shared = tare_at(loaded, tare, residual)
    inside = count > 0
    assert inside.mean() > 0.99 and np.all(count[inside] == 1) and np.all(shared[inside] == 1)
    truth = np.column_stack([np.cos(3.0 * t + j) for j in range(6)])
    assert np.max(np.abs(mean[inside] - truth[inside])) < 1e-4     # without the offset: ~7e-3
    other = _pieces(t, motion(t) + 0.2, np.zeros((len(t), 6)))
    assert not np.any(tare_at(loaded, other, residual)[1])
    two = _pieces(np.r_[t, t], np.vstack([motion(late), motion(late)]), np.zeros((2 * len(t), 6)),
                  np.r_[np.zeros(len(t), int), np.ones(len(t), int)])
    mean2, count2, _ = tare_at(loaded, two, np.vstack([residual, residual + 1.0]))
    assert np.max(count2) == 2 and np.allclose(mean2[count2 == 2], (mean + 0.5)[count2 == 2], atol=1e-4)
    both = _pieces(np.r_[t, t], np.vstack([motion(t), motion(t)]), np.zeros((2 * len(t), 6)),
                   np.r_[np.zeros(len(t), int), np.ones(len(t), int)])
    assert np.max(tare_at(both, tare, residual)[2]) == 2         # one tare under two loaded runs


def test_a_shared_tare_widens_sigma(runs):
    """Two loaded runs over one tare share its noise: σ is scaled by √((1 + 2)/(1 + 1)) (one
    loaded run per tare: 1), so twice the loaded data with the same tare does not halve the
    variance."""
    from urident.ident import load_params, predict_recordings
    from urident.ident.payload import estimate_payload, since_first_row
    from urident.logs import load_log

    arm = load_params(runs / "arm_params.yaml")
    spec = load_robot("ur5")
    tare_runs = [load_log(runs / "arm.csv")]
    tare = since_first_row(predict_recordings(arm, tare_runs, spec), tare_runs)
    one = [load_log(runs / "load_ident.csv")]
    est1 = estimate_payload(arm, spec, since_first_row(predict_recordings(arm, one, spec), one), unloaded=tare)
    assert est1.ols.info["tare_sigma_scale"] == pytest.approx(1.0)
    assert est1.ols.info["tared_samples"] == est1.n_samples
    effects = runs / "effects_load.yaml"
    assert main(["simulate", "--trajectory", str(ROOT / "experiments/ur5_ident.yaml"), "--out",
                 str(runs / "load_ident4.csv"), "--effects", str(effects), "--seed", "4", "--overwrite"]) == 0
    two = [*one, load_log(runs / "load_ident4.csv")]   # its own noise
    est2 = estimate_payload(arm, spec, since_first_row(predict_recordings(arm, two, spec), two), unloaded=tare)
    assert est2.ols.info["tare_sigma_scale"] == pytest.approx(np.sqrt(1.5))
    assert est2.ols.sigma["mass_kg"] > est1.ols.sigma["mass_kg"] / np.sqrt(2)
    assert abs(est2.ols.mass_kg - MASS) < 0.02 * MASS


def test_every_loaded_log_needs_its_tare(runs, capsys):
    """The tare is subtracted sample by sample, so a loaded log whose motion no ``--unloaded`` log
    runs is refused, naming it (one line, exit 2)."""
    _one_line_exit2(capsys, ["payload", str(runs / "load_ident.csv"), str(runs / "load.csv"), "--params",
                             str(runs / "arm_params.yaml"), "--unloaded", str(runs / "arm.csv"),
                             "--out", str(runs / "x.yaml")], f"{runs / 'load.csv'}: no tare runs its motion")


def test_the_inertia_is_reported_only_at_two_sigma_of_its_smallest_principal_axis():
    """The inertia entries' tolerance is 15 % of the smallest principal inertia about the centre of
    mass over 2 (an inertia reported is within 15 % on every axis at 2σ), not of the mean."""
    from urident.ident.payload import INERTIA_SIGMAS, TOLERANCES, _tolerances

    m, c = 2.0, np.array([0.02, -0.01, 0.07])
    ic = np.diag([0.004, 0.01, 0.013])
    j = ic + m * (c @ c * np.eye(3) - np.outer(c, c))      # about the flange origin
    phi = np.r_[m, m * c, j[0, 0], j[1, 1], j[2, 2], j[1, 2], j[0, 2], j[0, 1]]
    tol = _tolerances(phi)
    assert INERTIA_SIGMAS == 2.0
    assert tol[4:10] == pytest.approx(np.full(6, TOLERANCES["inertia_rel"] * 0.004 / 2))
    assert tol[0] == pytest.approx(0.05 * m) and tol[1:4] == pytest.approx(np.full(3, 0.005 * m))
    point = phi.copy()
    point[4:10] = np.r_[np.diag(m * (c @ c * np.eye(3) - np.outer(c, c))), 0, 0, 0]
    point[7:10] = [-m * c[1] * c[2], -m * c[0] * c[2], -m * c[0] * c[1]]
    assert _tolerances(point)[4] == pytest.approx(TOLERANCES["inertia_abs"])   # a point mass: the floor
