"""Offline simulation: a log as the simulated controller would record it, much faster than real
time.

:func:`simulate` runs the arm through the same :class:`~urident.simcontroller.plant.Plant` servo
tracking the simulated controller uses (servoJ to the trajectory's position at every controller
period, starting at rest at the trajectory's start), then computes the rest for the whole run at
once: model torques with the batched :func:`urident.model.joint_torques`, the effects' whole-run
forms, joint temperatures (the Plant's thermal model as a linear filter), sensor noise and
quantization drawn from the Plant's own generator. With the same seed, robot, rate, servo
settings and effects it gives the numbers the Plant stepped with the effects' hooks gives (to
floating-point rounding): ``tests/test_simulate_offline.py`` checks this.

The log (``out``) has the columns and sidecar of a live ``urident run`` log, plus, under the
sidecar's ``extra``, the ground truth: ``simulated: true``, ``seed``, ``effects_source``,
``effects_file`` (the effects file's text), ``effects`` (every entry with all parameters
explicit), ``params`` (the 78-vector the plant used) and ``simulation`` (servo and sensor
settings). Tools that diagnose or identify from logs (``urident gap``, ``urident identify``)
must never read these keys: they are for tests and blind benchmarks only.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from urident.errors import ConfigError, SafetyError
from urident.logs import LOG_FIELDS, LogWriter, Recording
from urident.model.parameters import check_standard
from urident.model.regressor import DEFAULT_FRICTION_EPS, joint_torques
from urident.simcontroller.effects import EffectSet, EffectsConfig, load_effects
from urident.simcontroller.plant import Plant, servo_bandwidth
from urident.simcontroller.robot_state import RUNTIME_PLAYING, ROBOT_MODE_RUNNING, SAFETY_BIT_NORMAL

DEFAULT_LOOKAHEAD_S = 0.1
DEFAULT_GAIN = 300.0
TRUTH_KEYS = ("simulated", "seed", "effects_source", "effects_file", "effects", "params",
              "simulation")


@dataclass(frozen=True, eq=False)
class SimulatedRecording(Recording):
    """A :class:`~urident.logs.Recording` of a simulated run plus the ground truth the log does
    not hold: ``tau_true`` (N, 6) the joint torque that drove the currents [N·m],
    ``extra_torque`` (N, 6) the effects' share of it, ``current_true`` (N, 6) the drive current
    before noise and sensor effects [A], ``link_q`` (N, 6) the link-side position (differs from
    ``target_q`` only under ``joint_elasticity``) [rad], and ``effects`` (the EffectSet)."""

    tau_true: np.ndarray | None = None
    extra_torque: np.ndarray | None = None
    current_true: np.ndarray | None = None
    link_q: np.ndarray | None = None
    effects: EffectSet | None = None

    _TRUTH = ("tau_true", "extra_torque", "current_true", "link_q")

    def __post_init__(self) -> None:
        super().__post_init__()
        n = len(self)
        for name in self._TRUTH:
            value = getattr(self, name)
            if value is not None:
                arr = np.array(value, dtype=np.float64)
                if arr.shape != (n, 6):
                    raise ValueError(f"SimulatedRecording.{name} must have shape ({n}, 6)")
                arr.flags.writeable = False
                object.__setattr__(self, name, arr)

    def select(self, index) -> "SimulatedRecording":
        """A new SimulatedRecording with samples ``index`` (the truth sliced alike)."""
        changes = {"t": self.t[index]}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if (f.name != "t" and isinstance(value, np.ndarray) and value.ndim >= 1
                    and value.shape[0] == len(self)):
                changes[f.name] = value[index]
        return dataclasses.replace(self, **changes)

    def to_recording(self) -> Recording:
        """The plain Recording (what the log holds), without the ground truth."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(Recording)}
        return Recording(**fields)


class _ZeroTorque:
    """Torque model of the motion pass: the motion does not depend on torques."""

    def torque(self, q, qd, qdd):
        return np.zeros(6)


def _unwrap_trajectory(trajectory) -> tuple[Any, str | None]:
    inner = getattr(trajectory, "trajectory", None)
    if inner is not None and hasattr(inner, "evaluate"):
        path = getattr(trajectory, "path", None)
        return inner, (str(path) if path is not None else None)
    if not (hasattr(trajectory, "evaluate") and hasattr(trajectory, "duration")):
        raise TypeError("trajectory must have evaluate(t) and duration (or be a TrajectoryFile)")
    return trajectory, None


def _effect_set(effects, spec, params, friction_eps, rng) -> EffectSet:
    if isinstance(effects, EffectSet):
        return effects.bind(spec, params, friction_eps)
    if effects is None or isinstance(effects, (str, Path, EffectsConfig)):
        return load_effects(effects, spec=spec, rng=rng, params=params, friction_eps=friction_eps)
    raise TypeError(f"effects must be a path, preset name, EffectsConfig or EffectSet, not {effects!r}")


def simulate(spec, trajectory, rate_hz: float | None = None, effects=None, seed: int = 0,
             params=None, out: str | Path | None = None, *,
             friction_eps: float = DEFAULT_FRICTION_EPS,
             servo_lookahead_s: float = DEFAULT_LOOKAHEAD_S, servo_gain: float = DEFAULT_GAIN,
             current_noise_a: float = 0.02, position_quantum_rad: float = 1e-5,
             trajectory_file: str | Path | None = None, overwrite: bool = False,
             ) -> SimulatedRecording:
    """Simulate ``trajectory`` (``.evaluate(t) -> (q, qd, qdd)`` and ``.duration``, or a
    TrajectoryFile) on robot ``spec`` at ``rate_hz`` (default the robot's controller rate).

    Samples ``t = 0, 1/rate, …, round(duration·rate)/rate`` (``round(duration·rate) + 1``
    samples). ``effects``: None, an effects file, a preset name, an EffectsConfig or an EffectSet
    (rebound to ``spec``/``params``; its hook state is untouched). ``params``: the plant's true
    78-vector (default the robot file's). ``seed`` draws the sensor noise exactly as the
    simulated controller seeded with it. ``out``: write the log there (``.csv`` + sidecar).
    Raises SafetyError when the motion leaves the joint limits.
    """
    traj, traj_path = _unwrap_trajectory(trajectory)
    trajectory_file = trajectory_file if trajectory_file is not None else traj_path
    rate = float(spec.controller_rate_hz if rate_hz is None else rate_hz)
    if not (np.isfinite(rate) and 0 < rate <= 10000):
        raise ConfigError(f"--rate {rate_hz}: must be a rate in Hz between 0 and 10000")
    p = spec.nominal_params.copy() if params is None else check_standard(params).copy()
    plant_seed, effects_seed = np.random.SeedSequence(int(seed)).spawn(2)
    effect_set = _effect_set(effects, spec, p, friction_eps, np.random.default_rng(effects_seed))

    duration = float(traj.duration)
    n = int(round(duration * rate)) + 1
    motion = _servo_motion(spec, traj, rate, n, np.random.default_rng(plant_seed),
                           servo_lookahead_s, servo_gain, current_noise_a, position_quantum_rad)
    t, q, qd, qdd = motion["t"], motion["q"], motion["qd"], motion["qdd"]

    tau_model = joint_torques(spec, p, q, qd, qdd, friction_eps)
    thermal = motion["thermal"]
    hook_temps, logged_temps = _temperatures(tau_model, thermal)
    extra = np.zeros_like(tau_model)
    if len(effect_set):
        extra = effect_set.offline_extra_torque(t, q, qd, qdd, tau_model, hook_temps)
        hook_temps, logged_temps = _temperatures(tau_model + extra, thermal)
        if "thermal_drift" in effect_set.names:  # extra torque depends on the temperatures
            for _ in range(8):
                extra_new = effect_set.offline_extra_torque(t, q, qd, qdd, tau_model, hook_temps)
                change = float(np.max(np.abs(extra_new - extra)))
                extra = extra_new
                hook_temps, logged_temps = _temperatures(tau_model + extra, thermal)
                if change < 1e-12:
                    break
    tau = tau_model + extra
    gains = np.asarray(spec.drive_gains, dtype=float)
    current_true = tau / gains
    measured = current_true + motion["noise"]
    if len(effect_set):
        measured = effect_set.offline_measure_current(t, measured, q, qd, hook_temps)
        link_q = q - effect_set.offline_deflection(t, q, qd, qdd, tau_model)
    else:
        link_q = q

    extra_meta = {
        "simulated": True,
        "seed": int(seed),
        "effects_source": effect_set.config.source,
        "effects_file": effect_set.config.text,
        "effects": effect_set.as_dict()["effects"],
        "params": [float(v) for v in p],
        "simulation": {"servo_lookahead_s": float(servo_lookahead_s), "servo_gain": float(servo_gain),
                       "current_noise_a": float(current_noise_a),
                       "position_quantum_rad": float(position_quantum_rad),
                       "friction_eps": float(friction_eps)},
    }
    metadata = {
        "robot": spec.name,
        "controller_version": ".".join(str(v) for v in spec.controller_version),
        "rate_hz": rate,
        "trajectory_file": None if trajectory_file is None else str(trajectory_file),
        "gear_ratios": [float(v) for v in spec.gear_ratios],
        "torque_constants": [float(v) for v in spec.torque_constants],
        "extra": extra_meta,
    }
    ones = np.ones(n, dtype=np.int64)
    arrays = dict(
        t=t, q=motion["measured_q"], qd=qd, current=measured, target_q=q, target_qd=qd,
        target_qdd=qdd, target_current=tau_model / gains, target_moment=tau_model,
        temperature=logged_temps, robot_mode=ROBOT_MODE_RUNNING * ones,
        safety_status_bits=SAFETY_BIT_NORMAL * ones, runtime_state=RUNTIME_PLAYING * ones,
    )
    source = None
    if out is not None:
        source, metadata = _write_log(Path(out), arrays, metadata, overwrite)
    else:
        metadata.update(format="urident-log", status="completed", n_samples=n)
    return SimulatedRecording(
        **arrays, source=source, robot=spec.name, rate_hz=rate, metadata=metadata,
        tau_true=tau, extra_torque=extra, current_true=current_true, link_q=link_q,
        effects=effect_set)


def _servo_motion(spec, traj, rate, n, rng, lookahead, gain, noise_a, quantum,
                  force_stepping: bool = False) -> dict:
    """The motion of a Plant servoing (servoJ) to the trajectory at every period, its measured
    positions, its noise draws and its thermal constants.

    A Plant (zero torque model, no effects) is built at the start; its measured current is then
    pure noise. While no velocity or acceleration limit clips the motion, the Plant's servo step
    is a linear recursion, solved here for the whole run at once (:func:`_linear_servo`);
    otherwise, or with ``force_stepping``, the Plant itself is stepped (identical numbers up to
    rounding, checked by the tests)."""
    dt = 1.0 / rate
    q_ref, _, _ = traj.evaluate(np.arange(n) * dt)
    q_ref = np.asarray(q_ref, dtype=float)
    if q_ref.shape != (n, 6) or not np.all(np.isfinite(q_ref)):
        raise ConfigError("the trajectory gives no finite (N, 6) positions")
    q0 = q_ref[0]
    if np.any(q0 < spec.q_min) or np.any(q0 > spec.q_max):
        raise SafetyError("the trajectory starts outside the joint limits")
    plant = Plant(spec, _ZeroTorque(), rate, rng, effects=None, initial_q=q0,
                  current_noise_a=noise_a, position_quantum_rad=quantum)
    c = plant.dt / plant.thermal_time_constant_s
    ambient = plant.ambient_temperature_c
    # the plant has already relaxed its initial temperature once (zero torque): undo that
    initial = (plant.temperatures - ambient * c) / (1.0 - c)
    out = {"thermal": (initial, ambient, plant.heating_c_per_nm, c)}
    motion = None if force_stepping else _linear_servo(plant, q_ref, servo_bandwidth(lookahead, gain))
    if motion is not None:
        q, qd, qdd = motion
        t = np.concatenate([[plant.t], plant.t + np.cumsum(np.full(n - 1, plant.dt))])
        draws = rng.normal(0.0, plant.current_noise_a, (n - 1, 6))  # the Plant's next draws
        noise = np.vstack([plant.measured_current[None, :], draws])
        measured_q = np.round(q / quantum) * quantum if quantum > 0 else q.copy()
        measured_q[0] = plant.measured_q
        out.update(t=t, q=q, qd=qd, qdd=qdd, measured_q=measured_q, noise=noise)
        return out
    arrays = {k: np.empty((n, 6)) for k in ("q", "qd", "qdd", "measured_q", "noise")}
    t = np.empty(n)
    for k in range(n):
        if k:
            plant.servo(q_ref[k], lookahead, gain)
            plant.step()
            if plant.fault_reason:
                raise SafetyError(f"the simulated arm stopped at t={plant.t:.3f} s: {plant.fault_reason}")
        t[k] = plant.t
        arrays["q"][k], arrays["qd"][k], arrays["qdd"][k] = plant.q, plant.qd, plant.qdd
        arrays["measured_q"][k] = plant.measured_q
        arrays["noise"][k] = plant.measured_current
    out.update(arrays, t=t)
    return out


def _linear_servo(plant: Plant, q_ref: np.ndarray, w: float):
    """Plant's servo step ``e1 = (e0 + (q̇0 + ω e0) dt) e^(−ω dt)``, ``q̇1 = (q̇0 − ω (q̇0 + ω e0)
    dt) e^(−ω dt)`` (``e = q − r``) for the whole run from rest at ``q_ref[0]``, as a linear filter
    of the targets; None when the Plant would clip a velocity or acceleration or leave the
    joint limits (it then has to be stepped)."""
    dt = plant.dt
    decay = np.exp(-w * dt)
    a = decay * np.array([[1.0 + w * dt, dt], [-w * w * dt, 1.0 - w * dt]])
    b = np.array([[1.0 - decay * (1.0 + w * dt)], [decay * w * w * dt]])
    # x_k = A x_(k-1) + B r_k: with state s_k = x_(k-1), output x_k = A s_k + B r_k
    num, den = signal.ss2tf(a, b, a, b)
    r = q_ref[1:]
    x0 = q_ref[0]
    # start at rest on the target: x = (q0, 0) is the steady state of input q0
    zi_q = signal.lfilter_zi(num[0], den)
    zi_qd = signal.lfilter_zi(num[1], den)
    q = np.empty_like(q_ref)
    qd = np.empty_like(q_ref)
    q[0], qd[0] = x0, 0.0
    q[1:] = signal.lfilter(num[0], den, r, axis=0, zi=zi_q[:, None] * x0[None, :])[0]
    qd[1:] = signal.lfilter(num[1], den, r, axis=0, zi=zi_qd[:, None] * x0[None, :])[0]
    qdd = np.zeros_like(q_ref)
    qdd[1:] = np.diff(qd, axis=0) / dt  # mean acceleration over each period, as the Plant reports
    acc = qdd[1:]
    if (np.any(np.abs(acc) > plant.qdd_max) or np.any(np.abs(qd[1:]) > plant.qd_max)
            or np.any(q < plant.q_min) or np.any(q > plant.q_max)):
        return None
    return q, qd, qdd


def _temperatures(tau: np.ndarray, thermal) -> tuple[np.ndarray, np.ndarray]:
    """The Plant's joint temperatures for torques ``tau``: (what the hooks see at each sample,
    what the controller reports after it)."""
    initial, ambient, heating, c = thermal
    x = c * (ambient + heating * np.abs(tau))
    zi = ((1.0 - c) * initial)[None, :]
    logged = signal.lfilter([1.0], [1.0, -(1.0 - c)], x, axis=0, zi=zi)[0]
    hook = np.vstack([initial[None, :], logged[:-1]])
    return hook, logged


def _write_log(path: Path, arrays: dict, metadata: dict, overwrite: bool):
    if path.suffix == "":
        path = path.with_suffix(".csv")
    if path.suffix != ".csv":
        raise ConfigError(f"{path}: a log path must end in .csv")
    if not path.parent.is_dir():
        raise ConfigError(f"{path}: directory {path.parent} does not exist")
    columns = []
    for field in LOG_FIELDS:
        value = np.asarray(arrays[field.attr], dtype=float)
        columns.append(value.reshape(len(value), -1))
    table = np.hstack(columns)
    with LogWriter(path, LOG_FIELDS, metadata, overwrite=overwrite) as writer:
        for row in table:
            writer.append(row)
    from urident.logs import read_sidecar

    return path, read_sidecar(writer.sidecar)
