"""Pure parts of the session layer: monitors, pre-motion checks, configuration."""

import numpy as np
import pytest

from urident.errors import ConfigError, SafetyError
from urident.model import load_robot
from urident.session.config import MonitorConfig, load_experiment_config
from urident.session.monitors import RunMonitor, safety_problem
from urident.session.preflight import check_controller, check_robot_state, plan_approach
from urident.session.rtde_io import parse_polyscope_version, rate_for_version

Q = np.zeros(6)


def monitor(**kw):
    return RunMonitor(MonitorConfig(**kw), period_s=0.002)


def test_monitor_passes_a_normal_sample():
    assert monitor().check(Q, Q + 0.01, 1.0, 0b1, 2, 0.0005) is None


@pytest.mark.parametrize("bit, word", [(2, "protective stop"), (7, "emergency stop"), (4, "safeguard")])
def test_monitor_stops_on_safety_bits(bit, word):
    reason = monitor().check(Q, Q, 1.0, 1 << bit, 2, None)
    assert word in reason


def test_monitor_stops_when_program_stops():
    assert "runtime_state=1" in monitor().check(Q, Q, 1.0, 0, 1, None)


def test_monitor_tracking_error_names_the_joint():
    q = Q.copy()
    q[3] = 0.3
    reason = monitor(max_tracking_error_rad=0.25).check(Q, q, 1.0, 0, 2, None)
    assert "joint 4" in reason and "0.300" in reason


def test_monitor_frozen_timestamp_is_stale_data():
    """Packages keep coming (the noisy currents change) but the controller clock stands still."""
    m = monitor(max_stale_periods=5)
    rng = np.random.default_rng(0)
    assert m.check(Q, Q, 1.0, 0, 2, None, rng.normal(size=6)) is None
    reasons = [m.check(Q, Q, 1.0, 0, 2, None, rng.normal(size=6)) for _ in range(5)]
    assert reasons[:4] == [None] * 4 and "stale data: controller timestamp frozen" in reasons[4]


def test_monitor_missing_packages_are_late_samples_not_frozen_time():
    """The same package seen again (nothing new arrived) is a latency spike, named as such."""
    m = monitor(max_stale_periods=100)
    current = np.arange(6.0)
    assert m.check(Q, Q, 1.0, 0, 2, None, current) is None
    reasons = [m.check(Q, Q, 1.0, 0, 2, None, current.copy()) for _ in range(100)]
    assert reasons[:99] == [None] * 99
    assert reasons[99] == "controller samples late: no sample for 0.20 s"
    # Samples resume: the count starts again.
    assert m.check(Q, Q, 1.2, 0, 2, None, current + 1) is None
    assert m.check(Q, Q, 1.2, 0, 2, None, current + 1) is None


def test_monitor_late_cycles_consecutive_and_fraction():
    m = monitor(max_consecutive_late=3, max_late_fraction=1.0)
    reasons = [m.check(Q, Q, 0.002 * k, 0, 2, 0.01) for k in range(3)]
    assert reasons[:2] == [None, None] and "3 late control cycles in a row" in reasons[2]
    m = monitor(max_consecutive_late=10**6, max_late_fraction=0.05)
    out = None
    for k in range(600):  # every 10th cycle late: 10 % > 5 % budget once warmed up (1 s)
        out = m.check(Q, Q, 0.002 * k, 0, 2, 0.01 if k % 10 == 0 else 0.0001)
        if out:
            break
    assert out is not None and "budget 5%" in out and k >= 499


def test_safety_problem_none_for_normal():
    assert safety_problem(0b1) is None


def test_controller_generation_rate_and_model():
    ur5, ur5e = load_robot("ur5"), load_robot("ur5e")
    check_controller(ur5, (3, 15, 8), 125.0, "UR5")
    check_controller(ur5e, (5, 11, 0), 500.0, "UR5")  # e-Series dashboards say the family name
    with pytest.raises(SafetyError, match="e-Series controller, but robot 'ur5' is a CB3"):
        check_controller(ur5, (5, 11, 0), 500.0, None)
    with pytest.raises(SafetyError, match="CB3 controller, but robot 'ur5e'"):
        check_controller(ur5e, (3, 15, 8), 125.0, None)
    with pytest.raises(SafetyError, match="reports robot model 'UR10'"):
        check_controller(ur5e, (5, 11, 0), 500.0, "UR10")
    assert rate_for_version(3) == 125.0 and rate_for_version(5) == 500.0
    assert parse_polyscope_version("URSoftware 5.11.1.108318 (Mar 22 2021)")[:3] == (5, 11, 1)
    with pytest.raises(SafetyError):
        parse_polyscope_version("garbage")


def test_robot_state_checks():
    check_robot_state(7, 1, 1)
    with pytest.raises(SafetyError, match="power off"):
        check_robot_state(3, 1, 1)
    with pytest.raises(SafetyError, match="protective stop"):
        check_robot_state(7, 3, 1 << 2)


def test_approach_distance_and_clearance():
    spec = load_robot("ur5e")
    start = np.array([0.0, -1.57, 0.0, -1.57, 0.0, 0.0])
    plan = plan_approach(spec, start + 0.1, start, 2.0)
    assert plan.max_joint_distance_rad == pytest.approx(0.1)
    with pytest.raises(SafetyError, match="starts 2.50 rad away on joint 3"):
        plan_approach(spec, start + np.array([0, 0, 2.5, 0, 0, 0]), start, 2.0)
    with pytest.raises(SafetyError, match="violates the collision clearance by 0.010 m"):
        plan_approach(spec, start + 0.1, start, 2.0, margin_fn=lambda q: np.full(len(q), -0.01))
    assert plan_approach(spec, start + 0.1, start, 2.0,
                         margin_fn=lambda q: np.full(len(q), 0.2)).min_margin_m == pytest.approx(0.2)


def test_experiment_config_errors(tmp_path):
    assert load_experiment_config(None).servo.gain == 300.0
    shipped = load_experiment_config("experiments/session.yaml")
    assert shipped.monitors.max_stale_periods == 25
    bad = tmp_path / "c.yaml"
    bad.write_text("servo:\n  gian: 300\n")
    with pytest.raises(ConfigError, match=r"c.yaml: servo.gian: unknown key"):
        load_experiment_config(bad)
    bad.write_text("servo:\n  gain: 5000\n")
    with pytest.raises(ConfigError, match=r"servo.gain: must be in \[100, 2000\]"):
        load_experiment_config(bad)
    bad.write_text("servo: [1, 2\n")
    with pytest.raises(ConfigError, match=r"c.yaml:\d+: malformed YAML"):
        load_experiment_config(bad)
    bad.write_text("monitors:\n  max_stale_periods: 2.5\n")
    with pytest.raises(ConfigError, match="whole number"):
        load_experiment_config(bad)


class _SignalledLink:
    """Our RobotLink's interface, with a signal arriving while the controller is being read."""

    def __init__(self, signum):
        self.signum = signum
        self.closed = False

    def connect_receive(self):
        import os
        import time

        os.kill(os.getpid(), self.signum)
        time.sleep(1.0)  # the handler raises here
        raise AssertionError("the signal did not interrupt the session")

    def close(self):
        self.closed = True
        return []


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_signal_before_motion_is_one_line_exit_130(name, tmp_path):
    import signal

    from urident.errors import Interrupted
    from urident.session import RunRequest, run_session

    signum = getattr(signal, name)
    before = signal.getsignal(signum)
    link = _SignalledLink(signum)
    request = RunRequest(robot="ur5e", host="127.0.0.1", trajectory=tmp_path / "t.yaml",
                         out=tmp_path / "x.csv")
    with pytest.raises(Interrupted) as info:
        run_session(request, say=lambda _l: None, link=link)
    assert str(info.value) == f"terminated by {name} before any motion: nothing was moved"
    assert info.value.exit_code == 130 and link.closed
    assert signal.getsignal(signum) is before


def test_a_declared_payload_heavier_than_the_checked_one_is_refused():
    from urident.errors import SafetyError
    from urident.session.preflight import check_declared_payload

    check_declared_payload(None, 0.0, "t.yaml")          # a controller that publishes no payload
    check_declared_payload(2.0, 2.0005, "t.yaml")        # lighter (or the same) is covered by the check
    check_declared_payload(2.0005, 2.0, "t.yaml")        # within the 1 g rounding allowance
    with pytest.raises(SafetyError, match=r"declares a payload of 2.5 kg, heavier than the 2 kg t.yaml"):
        check_declared_payload(2.5, 2.0, "t.yaml")
