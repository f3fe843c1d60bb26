"""Payload excitation (issue 17, item 3): ``urident excite --for-payload`` and a tool's capsule in
the collision model (excite, the trajectory file, check-trajectory and the run's preflight)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from urident.cli.main import main
from urident.errors import ConfigError, SafetyError
from urident.excitation import check_trajectory, load_trajectory
from urident.excitation.collision import CoalDistances, capsule_model
from urident.ident.payload import payload_condition
from urident.model import load_robot
from urident.model.robot import ToolCapsule

ROOT = Path(__file__).resolve().parent.parent
IDENT = ROOT / "experiments" / "ur10e_ident.yaml"
TOOL = ToolCapsule(0.05, 0.15)


def _cond(loaded) -> float:
    t = np.arange(0.0, loaded.trajectory.duration, 0.01)
    return payload_condition(loaded.spec, *loaded.trajectory.evaluate(t))


def _with_tool(path: Path, out: Path, radius: float, length: float) -> Path:
    doc = yaml.safe_load(path.read_text())
    doc["tool_capsule"] = {"radius_m": radius, "length_m": length}
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def test_tool_capsule_distances_numpy_equal_coal(rng):
    spec = load_robot("ur10e").with_tool(TOOL)
    capsules = capsule_model(spec, 0.05)
    tool_pairs = [n for n in capsules.pair_names if "tool_0" in n]
    assert "tool_0/floor" in tool_pairs and "base_0/tool_0" in tool_pairs
    assert not any("wrist_3" in n for n in tool_pairs)   # the link it is bolted to
    q = rng.uniform(-np.pi, np.pi, (200, 6))
    d = capsules.distances(spec, q)
    np.testing.assert_allclose(d, CoalDistances(spec, capsules).distances(q), atol=1e-9)
    k = [capsules.pair_names.index(n) for n in tool_pairs]
    assert (d[:, k] < 0).any()           # a tool can hit the arm or the floor somewhere


def test_for_payload_conditions_the_payload_columns_and_passes_the_check(tmp_path, capsys):
    out = tmp_path / "payload_traj.yaml"
    assert main(["excite", "--robot", "ur10e", "--for-payload", "--tool-capsule", "0.05,0.15",
                 "--out", str(out), "--starts", "1", "--iterations", "100", "--quiet"]) == 0
    assert "payload columns cond" in capsys.readouterr().out
    loaded = load_trajectory(out)
    assert loaded.tool == TOOL and loaded.optimization["for_payload"] is True
    arm = load_trajectory(IDENT)
    assert _cond(loaded) < _cond(arm)
    assert loaded.criteria["payload_cond"] == pytest.approx(_cond(loaded), rel=0.05)
    # wrist-dominated: the arm joints within their share of the limits, the wrist moving more
    t = np.arange(0.0, loaded.trajectory.duration, 0.002)
    _, qd, _ = loaded.trajectory.evaluate(t)
    share = np.abs(qd).max(axis=0) / loaded.limits.qd_max
    assert np.all(share[:3] <= loaded.optimization["arm_joint_fraction"] + 1e-9)
    assert share[3:].max() > 2 * share[:3].max()
    assert main(["check-trajectory", str(out)]) == 0
    assert "tool capsule on the flange" in capsys.readouterr().out


def test_a_trajectory_that_hits_its_tool_is_refused_by_check_and_run_preflight(tmp_path, capsys):
    from urident.session.runner import plan_motion

    spec = load_robot("ur10e")
    assert check_trajectory(spec, load_trajectory(IDENT).trajectory).ok   # safe without the tool
    bad = _with_tool(IDENT, tmp_path / "ident_with_tool.yaml", 0.1, 0.5)
    assert main(["check-trajectory", str(bad)]) == SafetyError.exit_code
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "unsafe trajectory" in err and "tool_0" in err
    with pytest.raises(SafetyError, match="tool_0"):   # urident run's preflight keeps the file's tool
        plan_motion(spec, bad, spec.controller_rate_hz, 1, 0.5)


def test_excite_takes_the_tool_from_a_payload_file(tmp_path, capsys):
    payload = tmp_path / "tool.yaml"
    payload.write_text(yaml.safe_dump({"format": "urident-payload", "version": 1, "robot": "ur5",
                                       "mass_kg": 1.0, "com_m": [0, 0, 0.05],
                                       "capsule": {"radius_m": 0.04, "length_m": 0.1}}))
    out = tmp_path / "t.yaml"
    assert main(["excite", "--robot", "ur5", "--for-payload", "--payload", str(payload), "--out", str(out),
                 "--harmonics", "2", "--duration", "6", "--iterations", "3", "--starts", "1", "--quiet"]) == 0
    assert f"capsule of {payload}" in capsys.readouterr().out
    assert load_trajectory(out).tool == ToolCapsule(0.04, 0.1)


@pytest.mark.parametrize("value, message", [
    ("0.05", "must be RADIUS,LENGTH"), ("a,b", "must be RADIUS,LENGTH"), ("0.05,0.1,0.2", "must be RADIUS,LENGTH"),
    ("-0.05,0.1", "radius must be positive"), ("0,0.1", "radius must be positive"),
    ("0.05,-0.1", "length must not be negative"), ("nan,0.1", "radius must be positive"),
])
def test_bad_tool_capsule_flag(tmp_path, capsys, value, message):
    code = main(["excite", "--robot", "ur5", "--out", str(tmp_path / "x.yaml"), f"--tool-capsule={value}"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "--tool-capsule" in err and message in err and "Traceback" not in err
    assert not (tmp_path / "x.yaml").exists()


def test_for_payload_without_a_tool_size_and_bad_tool_in_a_file(tmp_path, capsys):
    payload = tmp_path / "tool.yaml"
    payload.write_text(yaml.safe_dump({"format": "urident-payload", "version": 1, "robot": "ur5",
                                       "mass_kg": 1.0, "com_m": [0, 0, 0.05]}))
    for extra in ([], ["--payload", str(payload)]):
        code = main(["excite", "--robot", "ur5", "--for-payload", "--out", str(tmp_path / "x.yaml"), *extra])
        err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
        assert code == ConfigError.exit_code and len(err) == 1 and "--tool-capsule" in err[0]
    bad = _with_tool(IDENT, tmp_path / "neg.yaml", -0.1, 0.5)
    with pytest.raises(ConfigError, match=r"neg.yaml: tool_capsule.radius_m"):
        load_trajectory(bad)


def test_shipped_payload_trajectory_is_safe_with_its_tool_and_within_the_tracking_monitor():
    from urident.session.config import MonitorConfig, ServoConfig

    loaded = load_trajectory(ROOT / "experiments" / "ur10e_payload.yaml")
    assert loaded.tool is not None and loaded.optimization["for_payload"] is True
    report = check_trajectory(loaded.spec, loaded.trajectory, limits=loaded.limits, collision_backend="numpy")
    assert report.ok and any("tool_0" in n for n in report.pair_names)
    _, qd, _ = loaded.trajectory.evaluate(np.linspace(0.0, loaded.trajectory.duration, 20001))
    assert np.abs(qd).max() * ServoConfig().lookahead_time_s < 0.95 * MonitorConfig().max_tracking_error_rad
    assert _cond(loaded) < 0.75 * _cond(load_trajectory(IDENT))


def _low_torque_ident(tmp_path: Path) -> Path:
    """ur10e_ident.yaml with the torque limits at 0.6 of the robot's: safe on the empty flange and with
    1 kg, not with a 10 kg tool (the shoulder and elbow carry its gravity)."""
    doc = yaml.safe_load(IDENT.read_text())
    for key in ("q_min_rad", "q_max_rad", "qd_max_rad_s", "qdd_max_rad_s2", "tau_max_nm"):
        doc["limits"].pop(key)
    doc["limits"]["torque_fraction"] = 0.6
    out = tmp_path / "ident_low_torque.yaml"
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


TEN_KG = dict(mass_kg=10.0, com_m=[0.0, 0.05, 0.1], inertia_kg_m2=np.diag([0.08, 0.06, 0.05]))


def test_a_payload_enters_the_torque_check_and_the_file_records_it(tmp_path, capsys):
    from urident.excitation import trajectory_document, write_trajectory
    from urident.model.payload import Payload
    from urident.session.runner import plan_motion

    path = _low_torque_ident(tmp_path)
    loaded = load_trajectory(path)
    assert loaded.payload is None                      # a file without a payload: the empty flange
    tool = Payload("ur10e", **TEN_KG)
    empty = check_trajectory(loaded.spec, loaded.trajectory, limits=loaded.limits, collision_backend="numpy")
    heavy = check_trajectory(loaded.spec, loaded.trajectory, limits=loaded.limits, collision_backend="numpy",
                             payload=tool)
    assert empty.ok and not heavy.ok and heavy.payload_kg == 10.0
    assert {v.constraint for v in heavy.violations} == {"torque"}
    assert np.all(heavy.margins["torque"] < empty.margins["torque"] + 1e-9)   # the worse of both, per joint
    assert main(["check-trajectory", str(path)]) == 0
    capsys.readouterr()
    assert main(["check-trajectory", str(path), "--payload-mass", "10", "--payload-com", "0,0.05,0.1"]) == 3
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "torque limit" in err

    recorded = tmp_path / "recorded.yaml"          # the payload round-trips through the file
    write_trajectory(recorded, trajectory_document("ur10e", loaded.trajectory, loaded.limits, payload=tool))
    back = load_trajectory(recorded).payload
    assert back.mass_kg == tool.mass_kg
    np.testing.assert_array_equal(back.com_m, tool.com_m)
    np.testing.assert_array_equal(back.inertia_kg_m2, tool.inertia_kg_m2)
    assert main(["check-trajectory", str(recorded)]) == 3          # the recorded load is checked
    assert "torque limit" in capsys.readouterr().err
    assert main(["check-trajectory", str(recorded), "--payload-mass", "1"]) == 0   # a given one replaces it
    spec = load_robot("ur10e")
    with pytest.raises(SafetyError, match="torque limit"):          # urident run's preflight
        plan_motion(spec, recorded, spec.controller_rate_hz, 1, 0.5)
    with pytest.raises(SafetyError, match="torque limit"):
        plan_motion(spec, path, spec.controller_rate_hz, 1, 0.5, payload=tool)
    assert plan_motion(spec, path, spec.controller_rate_hz, 1, 0.5).payload is None


def test_a_payload_above_the_rated_one_is_refused(tmp_path, capsys):
    from urident.excitation import trajectory_document, write_trajectory
    from urident.model.payload import Payload

    loaded = load_trajectory(IDENT)
    for argv in (["check-trajectory", str(IDENT), "--payload-mass", "12.6"],
                 ["excite", "--robot", "ur10e", "--out", str(tmp_path / "x.yaml"), "--payload-mass", "13"],
                 ["check-trajectory", str(IDENT), "--payload-mass", "2", "--payload", "p.yaml"],
                 ["check-trajectory", str(IDENT), "--payload-com", "0,0,0.1"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "x.yaml").exists()
    heavy = tmp_path / "heavy.yaml"
    write_trajectory(heavy, trajectory_document("ur10e", loaded.trajectory, loaded.limits,
                                                payload=Payload("ur10e", 13.0, [0, 0, 0.1], np.zeros((3, 3)))))
    with pytest.raises(ConfigError, match=r"heavy.yaml: payload.mass_kg: payload 13 kg exceeds the rated "
                                          r"payload of UR10e \(12.5 kg"):
        load_trajectory(heavy)


def test_excite_with_a_payload_mass_records_it_and_caps_a_fast_wrist(tmp_path, capsys):
    from urident.session.config import MonitorConfig, ServoConfig

    out = tmp_path / "t.yaml"
    assert main(["excite", "--robot", "ur3e", "--for-payload", "--tool-capsule", "0.04,0.1", "--payload-mass", "3",
                 "--payload-com", "0,0,0.08", "--out", str(out), "--harmonics", "2", "--duration", "6",
                 "--iterations", "3", "--starts", "1", "--quiet"]) == 0
    assert "payload 3 kg (--payload-mass)" in capsys.readouterr().out
    loaded = load_trajectory(out)
    assert loaded.payload.mass_kg == 3.0 and list(loaded.payload.com_m) == [0.0, 0.0, 0.08]
    # a UR3e wrist's 0.7 × 6.28 rad/s would lag 0.44 rad behind servoJ's 0.1 s lookahead: capped
    _, qd, _ = loaded.trajectory.evaluate(np.linspace(0.0, loaded.trajectory.duration, 6001))
    assert loaded.limits.qd_max[3:].min() * ServoConfig().lookahead_time_s > MonitorConfig().max_tracking_error_rad
    assert np.abs(qd).max() * ServoConfig().lookahead_time_s <= 0.9 * MonitorConfig().max_tracking_error_rad + 1e-4
    assert main(["check-trajectory", str(out)]) == 0
    assert "payload in the torque check" in capsys.readouterr().out
