"""Offline simulation: log format, agreement with the stepped Plant, CLI."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import yaml

import urident.excitation
from urident.cli.main import main
from urident.errors import SafetyError
from urident.logs import load_log, read_sidecar
from urident.model import load_robot
from urident.model.pinocchio_model import TorqueModel
from urident.simcontroller.effects import load_effects, parse_effects_text
from urident.simcontroller.offline import SimulatedRecording, _servo_motion, simulate
from urident.simcontroller.plant import Plant

HOME = np.array([0.3, -1.2, 1.4, -1.8, -1.5, 0.4])


class FourierTrajectory:
    """q = q0 + Σ_k a_k (1 − cos(k ω t)): starts at rest at q0."""

    def __init__(self, amplitudes, period_s=4.0, duration=2.0, q0=HOME):
        self.a = np.asarray(amplitudes, dtype=float)   # (K, 6)
        self.w = 2 * np.pi / period_s
        self.duration = float(duration)
        self.q0 = np.asarray(q0, dtype=float)

    def evaluate(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))[:, None]
        q, qd, qdd = np.tile(self.q0, (len(t), 1)), np.zeros((len(t), 6)), np.zeros((len(t), 6))
        for k, a in enumerate(self.a, start=1):
            wk = k * self.w
            q += a * (1 - np.cos(wk * t))
            qd += a * wk * np.sin(wk * t)
            qdd += a * wk * wk * np.cos(wk * t)
        return q, qd, qdd


SLOW = FourierTrajectory([[0.3, 0.2, -0.3, 0.3, 0.4, 0.5], [0.05, -0.05, 0.05, 0.1, -0.1, 0.1]])
FAST = FourierTrajectory([[1.0, 0.6, -0.9, 1.2, 1.2, 1.5]], period_s=1.0)  # clips acceleration


@dataclass
class FakeTrajectoryFile:
    robot: str
    trajectory: object


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


def step_plant(spec, trajectory, rate, effects_text, seed, lookahead=0.1, gain=300.0):
    """What the simulated controller does: a Plant with the torque model and the effects' hooks,
    servoJ to the trajectory's position every period (seeded like the controller)."""
    plant_seed, effects_seed = np.random.SeedSequence(seed).spawn(2)
    effects = None
    if effects_text is not None:
        effects = load_effects(parse_effects_text(effects_text), spec=spec,
                               rng=np.random.default_rng(effects_seed))
    n = int(round(trajectory.duration * rate)) + 1
    q_ref, _, _ = trajectory.evaluate(np.arange(n) / rate)
    plant = Plant(spec, TorqueModel(spec), rate, np.random.default_rng(plant_seed),
                  effects=effects, initial_q=q_ref[0])
    rows = []
    for k in range(n):
        if k:
            plant.servo(q_ref[k], lookahead, gain)
            plant.step()
        rows.append((plant.t, plant.measured_q, plant.qd, plant.measured_current, plant.q,
                     plant.qdd, plant.target_current, plant.tau_model, plant.temperatures.copy()))
    cols = list(zip(*rows))
    return dict(t=np.array(cols[0]), q=np.array(cols[1]), qd=np.array(cols[2]),
                current=np.array(cols[3]), target_q=np.array(cols[4]), target_qdd=np.array(cols[5]),
                target_current=np.array(cols[6]), target_moment=np.array(cols[7]),
                temperature=np.array(cols[8]))


EVERYTHING = """
effects:
  - {name: stribeck, joints: [1, 2, 3], static_friction_ratio: 1.4}
  - {name: load_friction, coefficient: 0.02}
  - {name: thermal_drift, warmup_c: 15, warmup_time_constant_s: 3}
  - {name: position_ripple, amplitude_nm: 0.3, harmonic: 11}
  - {name: payload_error, mass_kg: 1.0, offset_m: [0, 0.02, 0.05]}
  - {name: joint_elasticity, joints: [1, 2, 3], stiffness_nm_per_rad: 8000}
  - {name: current_delay, delay_s: 0.01}
  - {name: torque_constant_error, joints: [2], gain_factor: 1.08}
  - {name: current_offset, offset_a: 0.04}
"""


@pytest.mark.parametrize("trajectory", [SLOW, FAST], ids=["linear-servo", "clipped-servo"])
@pytest.mark.parametrize("effects_text", [None, EVERYTHING], ids=["no-effects", "all-effects"])
def test_offline_equals_the_stepped_plant(spec, trajectory, effects_text):
    rate = 125.0
    ref = step_plant(spec, trajectory, rate, effects_text, seed=7)
    sim = simulate(spec, trajectory, rate, parse_effects_text(effects_text) if effects_text else None,
                   seed=7)
    np.testing.assert_array_equal(sim.t, ref["t"])
    for name in ("q", "qd", "target_q", "target_qdd"):
        np.testing.assert_allclose(getattr(sim, name), ref[name], atol=1e-9, err_msg=name)
    for name in ("current", "target_current", "target_moment", "temperature"):
        np.testing.assert_allclose(getattr(sim, name), ref[name], rtol=1e-8, atol=1e-8, err_msg=name)


def test_linear_servo_equals_stepping(spec):
    rng = lambda: np.random.default_rng(3)  # noqa: E731
    fast = _servo_motion(spec, SLOW, 500.0, 1001, rng(), 0.1, 300.0, 0.02, 1e-5)
    slow = _servo_motion(spec, SLOW, 500.0, 1001, rng(), 0.1, 300.0, 0.02, 1e-5,
                         force_stepping=True)
    for key in ("t", "noise", "measured_q"):
        np.testing.assert_array_equal(fast[key], slow[key])
    for key in ("q", "qd", "qdd"):
        np.testing.assert_allclose(fast[key], slow[key], atol=1e-9)


def test_no_effects_currents_are_model_torque_over_gain(spec):
    sim = simulate(spec, SLOW, 500.0, None, seed=1)
    assert len(sim) == round(SLOW.duration * 500) + 1
    np.testing.assert_allclose(np.diff(sim.t), 1 / 500, rtol=1e-9)
    residual = sim.current - sim.target_moment / spec.drive_gains
    assert abs(residual.mean()) < 0.005
    assert 0.015 < residual.std() < 0.025             # the plant's 0.02 A noise, nothing else
    np.testing.assert_array_equal(sim.extra_torque, 0.0)
    np.testing.assert_array_equal(sim.link_q, sim.target_q)
    assert np.max(np.abs(sim.q - sim.target_q)) <= 0.5e-5 + 1e-12     # quantization only
    assert np.all(sim.robot_mode == 7) and np.all(sim.runtime_state == 2)
    # the arm tracks the trajectory with the servo's lag, from rest at its start
    q_ref = SLOW.evaluate(sim.t)[0]
    assert np.array_equal(sim.target_q[0], q_ref[0]) and np.all(sim.qd[0] == 0)
    assert np.max(np.abs(sim.target_q - q_ref)) < 0.1


def test_effects_change_currents_and_seed_determines_noise(spec):
    base = simulate(spec, SLOW, 125.0, None, seed=1)
    again = simulate(spec, SLOW, 125.0, None, seed=1)
    other = simulate(spec, SLOW, 125.0, None, seed=2)
    np.testing.assert_array_equal(base.current, again.current)
    assert not np.array_equal(base.current, other.current)
    realistic = simulate(spec, SLOW, 125.0, "realistic", seed=1)
    assert set(realistic.effects.names) >= {"stribeck", "current_delay"}
    assert np.max(np.abs(realistic.current - base.current)) > 0.05
    elastic = simulate(spec, SLOW, 125.0, parse_effects_text(
        "effects: [{name: joint_elasticity, joints: [2], stiffness_nm_per_rad: 5000}]"), seed=1)
    lag = elastic.target_q[:, 1] - elastic.link_q[:, 1]
    assert np.max(np.abs(lag)) > 1e-3 and np.all(elastic.link_q[:, [0, 2, 3, 4, 5]]
                                                    == elastic.target_q[:, [0, 2, 3, 4, 5]])


def test_leaving_the_joint_limits_is_a_safety_error(spec):
    wild = FourierTrajectory([[0, 0, 0, 0, 0, 7.0]], period_s=8.0, duration=4.0)
    with pytest.raises(SafetyError, match="joint position limit"):
        simulate(spec, wild, 125.0)
    outside = FourierTrajectory([[0] * 6], q0=[0, 0, 0, 0, 0, 7.0])
    with pytest.raises(SafetyError, match="starts outside"):
        simulate(spec, outside, 125.0)


def test_written_log_reads_back(spec, tmp_path):
    out = tmp_path / "sim.csv"
    sim = simulate(spec, SLOW, 500.0, "realistic", seed=5, out=out, trajectory_file="traj.yaml")
    assert isinstance(sim, SimulatedRecording) and sim.source == out
    log = load_log(out)
    assert len(log) == round(SLOW.duration * 500) + 1 == len(sim)
    assert log.robot == "ur5" and log.rate_hz == 500.0 and log.status == "completed"
    np.testing.assert_allclose(log.t, sim.t, atol=1e-6)
    for name in ("q", "qd", "current", "target_q", "target_qd", "target_qdd", "target_current",
                 "target_moment", "temperature"):
        np.testing.assert_allclose(getattr(log, name), getattr(sim, name), rtol=1e-8, atol=1e-12)
    side = read_sidecar(out.with_suffix(".yaml"))
    extra = side["extra"]
    assert extra["simulated"] is True and extra["seed"] == 5
    assert extra["effects_source"] == "realistic"
    assert "stribeck" in extra["effects_file"]
    assert yaml.safe_load(extra["effects_file"]) == yaml.safe_load(
        sim.effects.config.path.read_text())
    assert {e["name"] for e in extra["effects"]} == set(sim.effects.names)
    assert side["gear_ratios"] == list(spec.gear_ratios)
    assert side["trajectory_file"] == "traj.yaml"
    plain = sim.to_recording()
    assert type(plain).__name__ == "Recording" and len(plain.select(slice(0, 10))) == 10
    assert sim.select(slice(0, 10)).tau_true.shape == (10, 6)


def test_cli_simulate(spec, tmp_path, monkeypatch, capsys):
    traj_file = tmp_path / "traj.yaml"
    traj_file.write_text("fake trajectory\n")
    monkeypatch.setattr(urident.excitation, "load_trajectory",
                        lambda path: FakeTrajectoryFile("ur5", SLOW), raising=False)
    out = tmp_path / "run1.csv"
    code = main(["simulate", "--robot", "ur5", "--trajectory", str(traj_file), "--out", str(out),
                 "--effects", "realistic", "--seed", "3", "--rate", "250"])
    assert code == 0
    assert "wrote" in capsys.readouterr().out
    log = load_log(out)
    assert len(log) == round(SLOW.duration * 250) + 1
    side = read_sidecar(out.with_suffix(".yaml"))
    assert side["trajectory_sha256"] and side["extra"]["seed"] == 3

    # no effects: currents are the model torque over the drive gain, within the noise
    out2 = tmp_path / "run2.csv"
    assert main(["simulate", "--trajectory", str(traj_file), "--out", str(out2)]) == 0
    log2 = load_log(out2)
    assert len(log2) == round(SLOW.duration * spec.controller_rate_hz) + 1
    assert np.max(np.abs(log2.current - log2.target_moment / spec.drive_gains)) < 0.1

    for argv, message in [
        (["--effects", "realistik", "--overwrite"], "no such effects file or preset"),
        (["--robot", "ur10e", "--overwrite"], "trajectory is for robot 'ur5'"),
        ([], "exists; pass --overwrite to replace it"),
    ]:
        code = main(["simulate", "--trajectory", str(traj_file), "--out", str(out), *argv])
        err = capsys.readouterr().err
        assert code == 2 and message in err and err.count("\n") == 1


def test_cli_simulate_real_trajectory_file(tmp_path, capsys):
    from urident.excitation import FourierTrajectory as ExcitationFourier
    from urident.excitation import Limits, load_trajectory, trajectory_document, write_trajectory

    spec = load_robot("ur5e")
    a = np.zeros((6, 2))
    b = np.zeros((6, 2))
    a[:, 0] = [0.3, 0.2, -0.2, 0.3, 0.3, 0.4]
    b[:, 1] = [0.1, -0.1, 0.1, 0.1, -0.1, 0.1]
    traj = ExcitationFourier(a, b, 2 * np.pi / 2.0, HOME, 2.0)
    path = tmp_path / "traj.yaml"
    write_trajectory(path, trajectory_document("ur5e", traj, Limits.from_robot(spec)))
    out = tmp_path / "run.csv"
    assert main(["simulate", "--trajectory", str(path), "--out", str(out), "--effects",
                 "realistic", "--seed", "4"]) == 0, capsys.readouterr().err
    log = load_log(out)
    assert log.robot == "ur5e" and len(log) == round(2.0 * spec.controller_rate_hz) + 1
    start = load_trajectory(path).trajectory.evaluate(np.array([0.0]))[0][0]
    np.testing.assert_allclose(log.target_q[0], start, atol=1e-12)
    np.testing.assert_allclose(log.qd[0], 0.0, atol=1e-12)


def test_cli_lists_the_catalogue(capsys):
    assert main(["simulate", "--list-effects"]) == 0
    text = capsys.readouterr().out
    for name in ("stribeck", "joint_elasticity", "presets: none, realistic"):
        assert name in text
