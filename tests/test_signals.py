"""UR's torque signals as UR defines them (docs/signals.md): the simulated controller serves
actual_current_as_torque gravity-compensated (read here with ur_rtde's own client, not urident's
recorder) and target_gravity from 5.26; `urident run` records both where the version has them;
identification never takes the compensated torque as a full one."""

from __future__ import annotations

import csv
import subprocess
import sys
import time

import numpy as np
import pytest

from urident.cli.main import main
from urident.ident.torque import measured_torque, restored_gravity, torque_signal
from urident.logs import load_log
from urident.model import load_robot

# a pose with gravity load on joints 2-3 (upper arm and forearm away from the vertical)
LOADED_POSE = [0.05, -0.9, 0.8, -1.6, 0.05, 0.0]


def _ur_rtde_rows(host: str, names: list[str], seconds: float, path) -> dict[str, np.ndarray]:
    """Record ``names`` with ur_rtde's own RTDEReceiveInterface.startFileRecording."""
    import rtde_receive

    r = rtde_receive.RTDEReceiveInterface(host, 500.0, names)
    try:
        r.startFileRecording(str(path), names)
        time.sleep(seconds)
        r.stopFileRecording()
    finally:
        r.disconnect()
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], np.array(rows[1:], dtype=float)
    return {name: body[:, [head.index(f"{name}_{j}") for j in range(6)]]
            for name in names if name != "timestamp"}


def test_ur_rtde_reads_a_gravity_compensated_torque_at_rest(tmp_path):
    pytest.importorskip("rtde_receive")
    from urident.simcontroller.process import SimControllerProcess

    gains = load_robot("ur5e").drive_gains
    host = "127.0.0.135"
    with SimControllerProcess(host=host, robot="ur5e", version="5.23.0", initial_q=LOADED_POSE):
        got = _ur_rtde_rows(host, ["timestamp", "actual_current", "actual_current_as_torque"], 0.3,
                            tmp_path / "rest.csv")
    full = np.abs(np.mean(got["actual_current"] * gains, axis=0))
    torque = np.abs(np.mean(got["actual_current_as_torque"], axis=0))
    assert len(got["actual_current"]) > 50
    assert np.all(full[1:3] > 5.0)                       # the arm holds gravity on joints 2-3 ...
    assert np.all(torque[1:3] < 0.05 * full[1:3])        # ... which the torque field leaves out


def test_run_records_target_gravity_from_5_26_and_identifies_from_currents(tmp_path, capsys):
    pytest.importorskip("rtde_control")
    from test_session_family import small_trajectory
    from test_ur_rtde_recording import RECORD_RUN, check_ur_rtde_run_recording
    from test_session_sim import RELAXED, run_cli

    from urident.simcontroller.process import SimControllerProcess

    spec = load_robot("ur5e")
    config = tmp_path / "relaxed.yaml"
    config.write_text(RELAXED)
    out = tmp_path / "run.csv"
    recorded = tmp_path / "ur_rtde_run.csv"   # ur_rtde's own recorder beside `urident run`
    with SimControllerProcess(host="127.0.0.136", robot="ur5e", version="5.26.0",
                              initial_q=[0.05, -1.45, 0.1, -1.6, 0.05, 0.0]):
        recorder = subprocess.Popen([sys.executable, "-c", RECORD_RUN, "127.0.0.136", str(recorded)],
                                    stdin=subprocess.PIPE, text=True)
        try:
            r = run_cli("127.0.0.136", "ur5e", small_trajectory(tmp_path / "t.yaml", "ur5e"), out,
                        config, "--yes")
        finally:
            recorder.communicate("stop\n", timeout=60)
    assert r.returncode == 0, r.stderr
    print(check_ur_rtde_run_recording(recorded, "ur5e", tmp_path, capsys))
    log = load_log(out)
    assert log.tau is not None and log.metadata["torque_kind"] == "compensated"
    np.testing.assert_allclose(log.target_gravity, np.tile(-spec.gravity, (len(log), 1)))
    full = log.current * spec.drive_gains
    # the compensated torque is the full one less the controller's gravity model (here the nominal)
    np.testing.assert_allclose(log.tau + restored_gravity(log, spec), full, atol=2e-3)  # q quantized
    rest = np.max(np.abs(log.qd), axis=1) == 0           # before the motion
    assert rest.sum() > 50 and np.all(np.abs(log.tau[rest, 1:3].mean(axis=0))   # noise averaged
                                      < 0.05 * np.abs(full[rest, 1:3]).mean(axis=0))
    assert torque_signal(log) == "current"
    np.testing.assert_allclose(measured_torque(log, spec.drive_gains, "compensated", spec), full,
                               atol=2e-3)

    outs = {}
    for name, extra in (("default", []), ("compensated", ["--signal", "compensated"])):
        assert main(["identify", str(out), "--robot", "ur5e", "--out", str(tmp_path / f"{name}.yaml"),
                     *extra]) == 0
        outs[name] = capsys.readouterr().out
    assert "torques of run.csv: motor current x drive gains (its joint torques are " \
           "gravity-compensated" in outs["default"]
    assert "masses and first moments (gravity terms) are the model's, not identified" \
        in outs["compensated"]
    assert "signal: motor current x drive gains" in (tmp_path / "default.yaml").read_text()
    # a compensated torque is never taken for a full one
    assert main(["identify", str(out), "--robot", "ur5e", "--signal", "torque",
                 "--out", str(tmp_path / "x.yaml")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(err) == 1 and "--signal torque: its joint torques are gravity-compensated" in err[0]


# ------------------------------------------------------------------ bags: the effort's meaning
def _bags(tmp_path):
    from test_logs_rosbag import SAMPLE, messages_of, write_bag

    from urident.logs.rosbag import _nominal_gravity

    spec = load_robot("ur5")
    rec = load_log(SAMPLE)
    full = rec.current * spec.drive_gains
    efforts = {"current": rec.current, "torque": full,
               # the driver's main branch since PR #1551: compensated torque, nothing says so
               "compensated": full - _nominal_gravity(spec, rec.q)}
    return rec, {kind: write_bag(tmp_path / kind, "mcap", messages_of(rec, effort=e))
                 for kind, e in efforts.items()}


def test_a_bags_effort_is_found_at_standstill_and_a_contradiction_refused(tmp_path, capsys):
    pytest.importorskip("rosbags")
    rec, bags = _bags(tmp_path)
    for kind, bag in bags.items():
        got = load_log(bag, robot="ur5")
        assert got.metadata["effort"] == kind
        assert any(f"effort read as {kind}" in n for n in got.metadata["notes"])
        assert got.metadata.get("torque_kind") == {"current": None, "torque": "full",
                                                   "compensated": "compensated"}[kind]
    for kind, wrong in (("compensated", "current"), ("torque", "current"), ("current", "torque")):
        assert main(["convert", str(bags[kind]), "--robot", "ur5", "--effort", wrong,
                     "--bag", str(tmp_path / "never")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(bags[kind]) in err[0], err
        assert f"--effort {wrong} contradicts the effort (" in err[0]
        assert "joint 2: mean effort" in err[0] and f"pass --effort {kind}" in err[0]
    # the compensated bag carries no current: it is fitted only when asked, without gravity terms
    assert main(["identify", str(bags["compensated"]), "--robot", "ur5",
                 "--out", str(tmp_path / "d.yaml")]) == 2
    assert "pass --signal compensated" in capsys.readouterr().err
    assert main(["identify", str(bags["compensated"]), "--robot", "ur5", "--signal", "compensated",
                 "--out", str(tmp_path / "c.yaml")]) == 0
    assert "first moments (gravity terms) are the model's, not identified" in capsys.readouterr().out


def test_a_bag_that_cannot_tell_asks_for_effort(tmp_path, capsys):
    pytest.importorskip("rosbags")
    from test_logs_rosbag import SAMPLE, messages_of, write_bag

    rec = load_log(SAMPLE)
    moving = np.flatnonzero(np.max(np.abs(rec.qd), axis=1) > 0.01)
    part = rec.select(slice(moving[0], moving[-1] + 1))     # no standstill left
    bag = write_bag(tmp_path / "moving", "mcap", messages_of(part))
    with pytest.raises(Exception, match="cannot tell what JointState effort holds.*pass --effort"):
        load_log(bag, robot="ur5")
    got = load_log(bag, robot="ur5", effort="current")
    assert any("effort taken as current (--effort), not fully checked" in n for n in got.metadata["notes"])


def test_convert_writes_each_effort_kind(tmp_path, capsys):
    pytest.importorskip("rosbags")
    from test_logs_rosbag import SAMPLE

    for kind in ("current", "torque", "compensated"):
        out = tmp_path / f"conv_{kind}"
        assert main(["convert", str(SAMPLE), "--bag", str(out), "--bag-effort", kind]) == 0
        assert load_log(out, robot="ur5").metadata["effort"] == kind
    capsys.readouterr()


def test_the_declared_payloads_gravity_is_compensated_too():
    from urident.logs import Recording
    from urident.simcontroller.controller import make_torque_model
    from urident.simcontroller.effects import load_effects, parse_effects_text
    from urident.simcontroller.plant import Plant

    spec = load_robot("ur5e")
    load = "{name: payload_error, mass_kg: 2.0, offset_m: [0.01, -0.02, 0.05]}"
    effects = load_effects(parse_effects_text(f"effects:\n  - {load}\n"), spec=spec)
    plant = Plant(spec, make_torque_model(spec), 500.0, np.random.default_rng(0), effects,
                  initial_q=LOADED_POSE, current_noise_a=0.0)
    plant.step()
    carried = plant.compensated_torque.copy()          # the load's gravity, not declared
    assert np.max(np.abs(carried[1:3])) > 2.0 * 9.81 * 0.3
    plant.declare_payload(2.0, [0.01, -0.02, 0.05])
    plant.step()
    assert np.max(np.abs(plant.compensated_torque)) < 1e-9   # declared: zero at rest
    # and identification's restored gravity is the controller's: model + declared payload
    rec = Recording(t=[0.0], q=[plant.q], qd=[np.zeros(6)], current=[plant.measured_current],
                    tau=[plant.compensated_torque],
                    metadata={"torque_kind": "compensated", "extra": {"declared_payload": {
                        "mass_kg": 2.0, "cog_m": [0.01, -0.02, 0.05], "inertia_kg_m2": None}}})
    np.testing.assert_allclose(rec.tau + restored_gravity(rec, spec),
                               [plant.measured_current * spec.drive_gains], atol=1e-9)
