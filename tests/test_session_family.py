"""The UR family on the simulated controller: it answers as the arm (dashboard model and serial,
software version, rate), `urident run` drives a short servoJ run through the unmodified ur_rtde
client on a CB3 UR3 at 125 Hz and a UR20 at 500 Hz, and refuses a --robot of another model."""

from __future__ import annotations

import numpy as np
import pytest
from sim_helpers import dashboard

pytest.importorskip("rtde_control")

from test_session_sim import NEAR_START, RELAXED, START, one_line_error, run_cli  # noqa: E402

from urident.excitation import FourierTrajectory, Limits, trajectory_document, write_trajectory  # noqa: E402
from urident.excitation.fourier import base_frequency  # noqa: E402
from urident.logs import load_log  # noqa: E402
from urident.model import available_robots, load_robot  # noqa: E402
from urident.simcontroller.process import SimControllerProcess  # noqa: E402

DURATION_S = 2.0
# (robot, address, rate, dashboard model, version prefix, a robot of the same generation and
# rate that the controller must refuse)
ARMS = [("ur3", "127.0.0.81", 125.0, "UR3", "3.15.8", "ur5"),
        ("ur20", "127.0.0.82", 500.0, "UR20", "5.16.0", "ur30")]


def small_trajectory(path, robot):
    spec = load_robot(robot)
    free = np.random.default_rng(3).normal(scale=0.04, size=(6, 4))
    traj = FourierTrajectory.from_free(free, base_frequency(DURATION_S), np.array(START), DURATION_S)
    write_trajectory(path, trajectory_document(robot, traj, Limits.from_robot(spec)))
    return path


@pytest.mark.parametrize("robot, host, rate, model, version, other", ARMS)
def test_short_servoj_run_on_the_emulated_arm(tmp_path, robot, host, rate, model, version, other):
    trajectory = small_trajectory(tmp_path / f"{robot}_trajectory.yaml", robot)
    config = tmp_path / "relaxed.yaml"
    config.write_text(RELAXED)
    out = tmp_path / f"{robot}.csv"
    with SimControllerProcess(host=host, robot=robot, initial_q=NEAR_START):
        lines = dashboard(host, "get robot model", "get serial number", "PolyscopeVersion")
        refused = run_cli(host, other, small_trajectory(tmp_path / f"{other}_trajectory.yaml", other),
                          tmp_path / "refused.csv", config, "--yes")
        r = run_cli(host, robot, trajectory, out, config, "--yes")
    assert lines[1] == model
    assert lines[2].isdigit() and model[2:] in lines[2][4:]
    assert version in lines[3]
    assert refused.returncode == 3, refused.stdout + refused.stderr
    line = one_line_error(refused.stderr)
    assert f"reports robot model '{model}'" in line and f"--robot is '{other}'" in line
    assert not (tmp_path / "refused.csv").exists()
    assert r.returncode == 0, r.stderr
    log = load_log(out)
    assert log.status == "completed" and log.robot == robot and log.rate_hz == rate
    assert np.allclose(np.diff(log.t), 1.0 / rate, atol=1e-6)      # every controller sample
    assert log.metadata["extra"]["robot_model_reported"] == model
    first, last = log.metadata["extra"]["servo_timestamps_s"][:2]
    assert last - first >= DURATION_S - 2.0 / rate
    spec = load_robot(robot)
    servo = (log.t >= first) & (log.t <= last)
    assert np.abs(log.q[servo] - np.array(START)).max() > 0.01     # it moved
    assert np.all(np.abs(log.q) <= spec.q_max)


@pytest.mark.parametrize("robot", available_robots())
def test_dashboard_answers_as_each_arm(robot):
    from urident.simcontroller.controller import Controller, ControllerConfig, parse_version
    from urident.simcontroller.dashboard import DashboardSession

    spec = load_robot(robot)
    controller = Controller(ControllerConfig(spec=spec, version=parse_version(
        ".".join(map(str, spec.controller_version)))))
    session = DashboardSession(controller)
    assert session.handle("get robot model") == spec.dashboard_model
    assert spec.dashboard_model in (spec.model, spec.model[:-1])
    serial = session.handle("get serial number")
    assert serial.isdigit() and serial.startswith("2016" if spec.generation == "cb3" else "2023")
    assert controller.rate_hz == spec.controller_rate_hz
    assert session.handle("PolyscopeVersion").startswith(
        "URSoftware " + ".".join(map(str, spec.controller_version)))
