"""Torque-carrying logs: `urident run` records actual_current_as_torque where the controller's
version publishes it (PolyScope 5.23 / 10.10 on), the simulated controller serves it there, and
identification takes the torques from it by default (--signal torque|current; the report says
which)."""

from __future__ import annotations

import numpy as np
import pytest

from urident.cli.main import main
from urident.ident.torque import describe_signal, measured_torque, torque_signal
from urident.logs import load_log
from urident.model import load_robot
from urident.session.rtde_io import TORQUE_FIELD, log_field_names

from test_logs_rosbag import SAMPLE, _params, messages_of, write_bag


@pytest.mark.parametrize("version, has", [((3, 15, 8), False), ((5, 11, 0), False),
                                          ((5, 22, 9), False), ((5, 23, 0), True),
                                          ((5, 24, 1), True), ((10, 9, 0), False),
                                          ((10, 10, 0), True), ((11, 0, 0), True)])
def test_the_torque_field_is_recorded_where_the_version_publishes_it(version, has):
    names = log_field_names(version)
    assert (TORQUE_FIELD in names) is has
    assert names[:4] == ["timestamp", "actual_q", "actual_qd", "actual_current"]


def test_default_signal_and_its_report(tmp_path, capsys):
    gains = load_robot("ur5").drive_gains
    csv = load_log(SAMPLE)
    assert torque_signal(csv) == "current" and "motor current x drive gains" in describe_signal(csv)
    torque = 1.01 * csv.current * gains  # torques that differ from current x gains on purpose
    bag = write_bag(tmp_path / "b", "mcap", messages_of(csv, effort=torque))
    rec = load_log(bag, robot="ur5", effort="torque")
    assert torque_signal(rec) == "torque"
    np.testing.assert_allclose(measured_torque(rec, gains), torque)
    np.testing.assert_allclose(measured_torque(rec, gains, "current"), torque, rtol=1e-12)
    zeros = write_bag(tmp_path / "z", "mcap", messages_of(csv, 100, effort=0 * torque))
    rz = load_log(zeros, robot="ur5", effort="torque")
    assert torque_signal(rz) == "current" and "all zero" in describe_signal(rz)

    out = {}
    for name, argv in (("csv", [str(SAMPLE)]), ("torque", [str(bag), "--effort", "torque"]),
                       ("current", [str(bag), "--signal", "current"])):
        assert main(["identify", *argv, "--robot", "ur5", "--out", str(tmp_path / f"{name}.yaml")]) == 0
        out[name] = (capsys.readouterr().out, _params(tmp_path / f"{name}.yaml"))
    assert "torques of sample_ident.csv: motor current x drive gains" in out["csv"][0]
    assert "torques of b: the recorded joint torques" in out["torque"][0]
    assert "torques of b: motor current x drive gains" in out["current"][0]
    # the bag's effort read as current is 1.01 x gains x the CSV's current: its own fit
    assert not np.allclose(out["torque"][1], out["csv"][1], rtol=1e-6)
    assert main(["identify", str(SAMPLE), "--robot", "ur5", "--signal", "torque",
                 "--out", str(tmp_path / "x.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--signal torque: the log carries no joint torque" in err


def test_simulated_controller_5_23_serves_torques_and_run_records_them(tmp_path, capsys):
    pytest.importorskip("rtde_control")
    from test_session_family import small_trajectory
    from test_session_sim import NEAR_START, RELAXED, run_cli

    from urident.simcontroller.process import SimControllerProcess

    host = "127.0.0.92"
    config = tmp_path / "relaxed.yaml"
    config.write_text(RELAXED)
    out = tmp_path / "run.csv"
    with SimControllerProcess(host=host, robot="ur5e", version="5.23.0", initial_q=NEAR_START):
        r = run_cli(host, "ur5e", small_trajectory(tmp_path / "t.yaml", "ur5e"), out, config, "--yes")
    assert r.returncode == 0, r.stderr
    log = load_log(out)
    assert TORQUE_FIELD + "_0" in log.metadata["columns"] and log.tau is not None
    # the simulated controller's torque is its measured current times the arm's drive gains
    np.testing.assert_allclose(log.tau, log.current * load_robot("ur5e").drive_gains, rtol=1e-6,
                               atol=1e-6)
    assert torque_signal(log) == "torque"
    assert main(["identify", str(out), "--out", str(tmp_path / "p.yaml"), "--robot", "ur5e"]) == 0
    assert "torques of run.csv: the recorded joint torques" in capsys.readouterr().out
