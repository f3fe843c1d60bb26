"""Torque-carrying logs: `urident run` records actual_current_as_torque where the controller's
version publishes it (PolyScope 5.23 / 10.11 on) and target_gravity (5.26 / 10.12 on); a full
torque (a bag's) is the default signal, UR's gravity-compensated one never is (docs/signals.md)."""

from __future__ import annotations

import numpy as np
import pytest

from urident.cli.main import main
from urident.ident.torque import describe_signal, measured_torque, torque_signal
from urident.logs import load_log
from urident.model import load_robot
from urident.session.rtde_io import GRAVITY_FIELD, TORQUE_FIELD, log_field_names

from test_logs_rosbag import SAMPLE, _params, messages_of, write_bag


@pytest.mark.parametrize("version, torque, gravity", [
    ((3, 15, 8), False, False), ((5, 11, 0), False, False), ((5, 22, 9), False, False),
    ((5, 23, 0), True, False), ((5, 25, 1), True, False), ((5, 26, 0), True, True),
    ((10, 10, 0), False, False), ((10, 11, 0), True, False), ((10, 12, 0), True, True),
    ((11, 0, 0), True, True)])
def test_the_torque_and_gravity_fields_are_recorded_where_the_version_publishes_them(
        version, torque, gravity):
    names = log_field_names(version)
    assert (TORQUE_FIELD in names) is torque
    assert (GRAVITY_FIELD in names) is gravity
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
    assert "torques of b: motor current x drive gains" in out["current"][0]
    assert "torques of b: the recorded full joint torques" in out["torque"][0]
    # the bag's effort read as current is 1.01 x gains x the CSV's current: its own fit
    assert not np.allclose(out["torque"][1], out["csv"][1], rtol=1e-6)
    assert main(["identify", str(SAMPLE), "--robot", "ur5", "--signal", "torque",
                 "--out", str(tmp_path / "x.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--signal torque: the log carries no joint torque" in err
