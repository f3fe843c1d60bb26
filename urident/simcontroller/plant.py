"""The simulated arm: joint-level motion generation and tracking, torques, currents, temperatures.

One :meth:`Plant.step` advances the arm by one controller period ``dt``. The motion mode decides the
joint trajectory:

* ``hold``  - stand still.
* ``move``  - moveJ: synchronised trapezoidal profile; the leading joint (largest distance) moves at
  the requested speed and acceleration, the others are scaled so all joints arrive together.
* ``servo`` - servoJ: the joints follow the latest target through a critically damped second-order
  filter ``q̈ = ω²(r − q) − 2ω q̇`` (stepped exactly for a constant target), with
  ``ω = min(4 / lookahead_time, gain / 10)`` rad/s, so a ramp is tracked with a lag of
  ``2/ω`` (half the lookahead time at the default gain 300 / lookahead 0.1 → 67 ms); q̇ and q̈ are
  clipped to the robot's limits.
* ``speed`` - speedJ: joint velocities ramp to the target at the given acceleration.
* ``stop``  - decelerate every joint to rest at the given deceleration, then ``hold``.

The arm is assumed to track the generated trajectory exactly (target = actual); the measurements
differ from the truth: ``actual_q`` is quantized (``position_quantum_rad``), ``actual_current`` has
Gaussian noise (``current_noise_a``) from a seeded generator.

Torque: ``τ = TorqueModel.torque(q, q̇, q̈) + effects.extra_torque(t, q, q̇, q̈, τ_model, T)``; current
``i = τ / drive_gains``; measured current ``effects.measure_current(t, i + noise, q, q̇, T)``.
The compensated torque (RTDE actual_current_as_torque, UR's definition: docs/signals.md) is the
measured current times the drive gains minus the controller's gravity torque: the arm model's
``TorqueModel.torque(q, 0, 0)`` plus the declared payload's; zero at rest without external load. Both
hooks are optional methods of the ``effects`` object (see :class:`PlantEffects`). Joint temperatures
relax towards ``ambient + heating_c_per_nm·|τ|`` with time constant ``thermal_time_constant_s``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

N_JOINTS = 6
HOME_Q = np.array([0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0])


@runtime_checkable
class TorqueModelLike(Protocol):
    def torque(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray: ...


class PlantEffects(Protocol):
    """What an unmodelled-effects object may provide (each method is optional).

    ``extra_torque(t, q, qd, qdd, tau_model, temperatures) -> (6,)``: joint torque [N·m] added to
    the model torque (e.g. friction not in the model, cogging, payload).
    ``measure_current(t, current, q, qd, temperatures) -> (6,)``: the reported current [A] given the
    true current plus sensor noise (e.g. offsets, scale errors, delay, quantization).
    """


def servo_bandwidth(lookahead_time: float, gain: float) -> float:
    """Natural frequency ω [rad/s] of the servoJ tracking filter."""
    return float(min(4.0 / max(lookahead_time, 1e-3), max(gain, 1.0) / 10.0))


@dataclass
class MoveProfile:
    """Synchronised trapezoidal joint move from ``start`` to ``goal``."""

    start: np.ndarray
    goal: np.ndarray
    speed: float
    acceleration: float

    def __post_init__(self) -> None:
        self.delta = self.goal - self.start
        self.distance = float(np.max(np.abs(self.delta)))
        v, a, d = self.speed, self.acceleration, self.distance
        if d <= 0.0:
            self.t_acc = self.t_flat = 0.0
            self.v_peak = 0.0
        elif d <= v * v / a:                                   # triangular profile
            self.t_acc = float(np.sqrt(d / a))
            self.t_flat = 0.0
            self.v_peak = a * self.t_acc
        else:
            self.t_acc = v / a
            self.t_flat = d / v - v / a
            self.v_peak = v
        self.duration = 2.0 * self.t_acc + self.t_flat

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.distance <= 0.0 or t >= self.duration:
            return self.goal.copy(), np.zeros(N_JOINTS), np.zeros(N_JOINTS)
        a, ta, tf, vp = self.acceleration, self.t_acc, self.t_flat, self.v_peak
        if t < ta:
            s, sd, sdd = 0.5 * a * t * t, a * t, a
        elif t < ta + tf:
            s, sd, sdd = 0.5 * a * ta * ta + vp * (t - ta), vp, 0.0
        else:
            tr = self.duration - t
            s, sd, sdd = self.distance - 0.5 * a * tr * tr, a * tr, -a
        scale = self.delta / self.distance
        return self.start + scale * s, scale * sd, scale * sdd


class Plant:
    """Joint-space simulation of the arm at the controller rate (see the module docstring)."""

    def __init__(self, spec, torque_model: TorqueModelLike, rate_hz: float,
                 rng: np.random.Generator, effects=None, initial_q=None,
                 current_noise_a: float = 0.02, position_quantum_rad: float = 1e-5,
                 ambient_temperature_c: float = 25.0, heating_c_per_nm: float = 0.15,
                 thermal_time_constant_s: float = 900.0):
        self.spec = spec
        self.torque_model = torque_model
        self.dt = 1.0 / float(rate_hz)
        self.rng = rng
        self.effects = effects
        self.current_noise_a = float(current_noise_a)
        self.position_quantum_rad = float(position_quantum_rad)
        self.ambient_temperature_c = float(ambient_temperature_c)
        self.heating_c_per_nm = float(heating_c_per_nm)
        self.thermal_time_constant_s = float(thermal_time_constant_s)
        self.drive_gains = np.asarray(spec.drive_gains, dtype=float)
        self.q_min = np.asarray(spec.q_min, dtype=float)
        self.q_max = np.asarray(spec.q_max, dtype=float)
        self.qd_max = np.asarray(spec.qd_max, dtype=float)
        self.qdd_max = np.asarray(spec.qdd_max, dtype=float)
        self._extra_torque = getattr(effects, "extra_torque", None)
        self._measure_current = getattr(effects, "measure_current", None)

        q0 = HOME_Q if initial_q is None else np.asarray(initial_q, dtype=float)
        self.q = np.clip(q0.astype(float).copy(), self.q_min, self.q_max)
        self.qd = np.zeros(N_JOINTS)
        self.qdd = np.zeros(N_JOINTS)
        self.t = 0.0
        self.mode = "hold"
        self._profile: MoveProfile | None = None
        self._profile_t0 = 0.0
        self._servo_target = self.q.copy()
        self._servo_omega = servo_bandwidth(0.1, 300.0)
        self._speed_target = np.zeros(N_JOINTS)
        self._acceleration = 1.0
        self.fault_reason: str | None = None       # set when a joint limit is hit

        self.temperatures = np.full(N_JOINTS, self.ambient_temperature_c + 5.0)
        self.tau_model = np.zeros(N_JOINTS)
        self.target_moment = np.zeros(N_JOINTS)      # the model torque with the declared payload
        self.declared_payload: np.ndarray | None = None   # ten parameters about K_6 (set_target_payload)
        self.tau = np.zeros(N_JOINTS)
        self.current = np.zeros(N_JOINTS)            # true motor current [A]
        self.target_current = np.zeros(N_JOINTS)     # model current (feed-forward) [A]
        self.measured_current = np.zeros(N_JOINTS)
        self.compensated_torque = np.zeros(N_JOINTS)  # actual_current_as_torque [N·m]
        self.measured_q = self.q.copy()
        self._update_torques()

    # ----------------------------------------------------------------- commands
    def move_joints(self, goal, speed: float, acceleration: float) -> float:
        """Start a moveJ; returns its duration [s]."""
        goal = np.clip(np.asarray(goal, dtype=float), self.q_min, self.q_max)
        speed = float(np.clip(speed, 1e-6, np.min(self.qd_max)))
        acceleration = float(np.clip(acceleration, 1e-6, np.min(self.qdd_max)))
        self._profile = MoveProfile(self.q.copy(), goal, speed, acceleration)
        self._profile_t0 = self.t
        self.mode = "move"
        return self._profile.duration

    def servo(self, target, lookahead_time: float, gain: float) -> None:
        """Update the servoJ target (and its filter bandwidth); switches to servo mode."""
        self._servo_target = np.asarray(target, dtype=float).copy()
        self._servo_omega = servo_bandwidth(lookahead_time, gain)
        self.mode = "servo"

    def speed_joints(self, qd_target, acceleration: float) -> None:
        self._speed_target = np.clip(np.asarray(qd_target, dtype=float), -self.qd_max, self.qd_max)
        self._acceleration = max(float(acceleration), 1e-6)
        self.mode = "speed"

    def stop(self, deceleration: float | None = None) -> None:
        """Decelerate to rest (``None``: as fast as the joints allow)."""
        if self.mode == "hold":
            return
        self._speed_target = np.zeros(N_JOINTS)
        self._acceleration = float(np.min(self.qdd_max)) if deceleration is None else max(deceleration, 1e-6)
        self.mode = "stop"

    @property
    def is_moving(self) -> bool:
        """True until a move or stop has come to rest (servo and speed modes always move)."""
        return self.mode != "hold"

    # ----------------------------------------------------------------- stepping
    def step(self) -> None:
        """Advance by one controller period."""
        dt = self.dt
        self.t += dt
        q0, qd0 = self.q, self.qd
        if self.mode == "move":
            profile = self._profile
            q, qd, qdd = profile.sample(self.t - self._profile_t0)
            if self.t - self._profile_t0 >= profile.duration:
                self.mode = "hold"
        elif self.mode == "servo":
            q, qd, qdd = self._servo_step(q0, qd0, dt)
        elif self.mode in ("speed", "stop"):
            dv = np.clip(self._speed_target - qd0, -self._acceleration * dt, self._acceleration * dt)
            qd = qd0 + dv
            q = q0 + 0.5 * (qd0 + qd) * dt
            qdd = dv / dt
            if self.mode == "stop" and not np.any(qd):
                self.mode = "hold"
        else:
            q, qd, qdd = q0, np.zeros(N_JOINTS), np.zeros(N_JOINTS)
        if np.any(q < self.q_min) or np.any(q > self.q_max):
            q = np.clip(q, self.q_min, self.q_max)
            qd = np.zeros(N_JOINTS)
            qdd = np.zeros(N_JOINTS)
            self.mode = "hold"
            self.fault_reason = "joint position limit reached"
        self.q, self.qd, self.qdd = q, qd, qdd
        self._update_torques()

    def _servo_step(self, q0: np.ndarray, qd0: np.ndarray, dt: float):
        w = self._servo_omega
        e0 = q0 - self._servo_target
        decay = np.exp(-w * dt)
        c = qd0 + w * e0
        e1 = (e0 + c * dt) * decay
        qd1 = (qd0 - w * c * dt) * decay
        acc = (qd1 - qd0) / dt
        limited = np.abs(acc) > self.qdd_max
        if np.any(limited) or np.any(np.abs(qd1) > self.qd_max):
            acc = np.clip(acc, -self.qdd_max, self.qdd_max)
            qd1 = np.clip(qd0 + acc * dt, -self.qd_max, self.qd_max)
            acc = (qd1 - qd0) / dt
            q1 = q0 + 0.5 * (qd0 + qd1) * dt
            return q1, qd1, acc
        # The reported q̈ is the mean acceleration over the period, (q̇1 − q̇0)/dt, not the filter's
        # acceleration at its end: the target steps every period, so the end value is biased by
        # about ω²·dt·q̇/2, and the torque (the current) belongs to the motion over the period.
        return self._servo_target + e1, qd1, acc

    def declare_payload(self, mass_kg: float, cog_m, inertia6=None) -> None:
        """A payload declared to the controller (``set_target_payload`` / ``setPayload``): mass,
        centre of mass in the flange frame, [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about it. It changes
        the target moment and target current only; the physics is the effects' business."""
        from urident.model.parameters import TOOL_BODY
        from urident.simcontroller.effects.dynamics import inertia_matrix, payload_params

        i6 = [0.0] * 6 if inertia6 is None else list(inertia6)
        if mass_kg <= 0:
            self.declared_payload = None
            return
        p78 = payload_params(self.spec, float(mass_kg), np.asarray(cog_m, float),
                             inertia_matrix(i6[:3], i6[3:]))
        self.declared_payload = p78[TOOL_BODY]

    def _declared_torque(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray]:
        """The declared payload's torque at (q, q̇, q̈) and its gravity torque at q."""
        from urident.model import regressor_blocks
        from urident.model.parameters import TOOL_BODY

        zero = np.zeros_like(q)
        blocks = regressor_blocks(self.spec, np.stack([q, q]), np.stack([qd, zero]),
                                  np.stack([qdd, zero]))
        torque = blocks[:, :, TOOL_BODY] @ self.declared_payload
        return torque[0], torque[1]

    def _update_torques(self) -> None:
        t, q, qd, qdd = self.t, self.q, self.qd, self.qdd
        tau_model = np.asarray(self.torque_model.torque(q, qd, qdd), dtype=float)
        tau = tau_model
        if self._extra_torque is not None:
            tau = tau_model + np.asarray(
                self._extra_torque(t, q, qd, qdd, tau_model, self.temperatures), dtype=float)
        self.tau_model, self.tau = tau_model, tau
        self.target_moment = tau_model
        zero = np.zeros(N_JOINTS)
        gravity = np.asarray(self.torque_model.torque(q, zero, zero), dtype=float)
        if self.declared_payload is not None:   # the controller's model carries what it was told
            declared, declared_gravity = self._declared_torque(q, qd, qdd)
            self.target_moment = tau_model + declared
            gravity = gravity + declared_gravity
        self.target_current = self.target_moment / self.drive_gains
        self.current = tau / self.drive_gains
        measured = self.current + self.rng.normal(0.0, self.current_noise_a, N_JOINTS)
        if self._measure_current is not None:
            measured = np.asarray(self._measure_current(t, measured, q, qd, self.temperatures), dtype=float)
        self.measured_current = measured
        self.compensated_torque = measured * self.drive_gains - gravity
        quantum = self.position_quantum_rad
        self.measured_q = np.round(q / quantum) * quantum if quantum > 0 else q.copy()
        equilibrium = self.ambient_temperature_c + self.heating_c_per_nm * np.abs(tau)
        self.temperatures = self.temperatures + (equilibrium - self.temperatures) * (
            self.dt / self.thermal_time_constant_s)
