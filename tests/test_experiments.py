"""experiments/ ships a checked identification/validation pair for every robot: each passes every
dense check (limits, nominal torques, self-collision, floor) at its controller's rate, and the
identification trajectory excites the base parameters far better than a random one would."""

from pathlib import Path

import numpy as np
import pytest

from urident.excitation import check_trajectory, load_trajectory
from urident.model import available_robots, load_robot

EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"


@pytest.mark.parametrize("kind", ["ident", "valid"])
@pytest.mark.parametrize("robot", available_robots())
def test_experiment_pair_passes_every_check_at_the_controller_rate(robot, kind):
    path = EXPERIMENTS / f"{robot}_{kind}.yaml"
    assert path.is_file(), f"{path.name} missing"
    loaded = load_trajectory(path)
    spec = load_robot(robot)
    assert loaded.robot == robot
    report = check_trajectory(spec, loaded.trajectory, spec.controller_rate_hz, loaded.limits,
                              collision_backend="numpy")
    assert report.ok, report
    assert report.rate_hz == spec.controller_rate_hz
    traj = loaded.trajectory
    assert np.allclose(traj.q_start, traj.q_end, atol=1e-9)
    # The optimiser's own record: reduced model, cond(Θ̄_B) at the controller rate well below
    # the random trajectories' medians measured by benchmarks/excitation.py (≥ 1,000).
    assert loaded.criteria["reduced"] and loaded.criteria["rate_hz"] == spec.controller_rate_hz
    assert loaded.criteria["cond_theta"] < 1000.0


def test_identification_and_validation_trajectories_differ():
    for robot in available_robots():
        a = load_trajectory(EXPERIMENTS / f"{robot}_ident.yaml").trajectory
        b = load_trajectory(EXPERIMENTS / f"{robot}_valid.yaml").trajectory
        assert not np.allclose(a.a, b.a), robot


@pytest.mark.parametrize("kind", ["ident", "valid"])
@pytest.mark.parametrize("robot", available_robots())
def test_servo_lag_stays_inside_the_tracking_monitor(robot, kind):
    """servoJ with the default lookahead lags the command by about q̇ · lookahead; the fastest
    joint must stay inside the session's default tracking-error limit, or a run aborts."""
    from urident.session.config import MonitorConfig, ServoConfig

    traj = load_trajectory(EXPERIMENTS / f"{robot}_{kind}.yaml").trajectory
    _, qd, _ = traj.evaluate(np.linspace(0.0, traj.duration, 20001))
    lag = np.abs(qd).max() * ServoConfig().lookahead_time_s
    assert lag < 0.95 * MonitorConfig().max_tracking_error_rad


@pytest.mark.parametrize("robot", available_robots())
def test_validation_start_is_within_the_demos_approach_of_the_identification_start(robot):
    """`urident demo --robot R` runs both trajectories back to back: the validation start must be
    within the demo's approach limit (approach.max_distance_rad = 3.2 in urident/cli/demo.py) of where
    identification ends (its start)."""
    ident = load_trajectory(EXPERIMENTS / f"{robot}_ident.yaml").trajectory
    valid = load_trajectory(EXPERIMENTS / f"{robot}_valid.yaml").trajectory
    assert np.abs(valid.q_start - ident.q_end).max() < 3.2


def test_the_sim_gap_validation_run_passes_every_check_and_tracks_within_the_session_limit(tmp_path):
    """experiments/ur5e_sim_gap.yaml (four base periods in 20 s, benchmarks/sim_gap.py): as safe as the
    pairs, and servoJ follows it within the session's tracking-error limit on the simulated controller."""
    from urident.cli.main import main
    from urident.logs import load_log
    from urident.session.config import MonitorConfig

    loaded = load_trajectory(EXPERIMENTS / "ur5e_sim_gap.yaml")
    spec = load_robot("ur5e")
    report = check_trajectory(spec, loaded.trajectory, spec.controller_rate_hz, loaded.limits,
                              collision_backend="numpy")
    assert report.ok, report
    log = tmp_path / "run.csv"
    assert main(["simulate", "--trajectory", str(EXPERIMENTS / "ur5e_sim_gap.yaml"), "--out", str(log)]) == 0
    rec = load_log(log)
    q_cmd = loaded.trajectory.evaluate(np.asarray(rec.t) - rec.t[0])[0]
    error = np.abs(q_cmd - np.asarray(rec.q)).max()
    assert 0 < error < MonitorConfig().max_tracking_error_rad
