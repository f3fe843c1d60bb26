"""Dense safety check of a trajectory before anything moves: every constraint at every controller
tick, with the tightest margin per constraint and joint (or collision pair).

Constraints: position (inside the margined limits), velocity, acceleration, nominal joint torque
(the robot file's nominal parameters, |τ| ≤ torque_fraction·τ_max; with a payload, both the empty
flange and the payload's torque added: τ is affine in the payload's mass at a fixed centre of mass
and inertia shape, so the check holds for every lighter load of that shape), collision (capsule distances
from Pinocchio/coal against each pair's required distance, see :mod:`urident.excitation.collision`)
and rest (zero velocity and acceleration at the start and the end, so moveJ → servoJ is smooth).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from urident.errors import SafetyError
from urident.excitation.collision import CoalDistances, capsule_model
from urident.excitation.constraints import Limits, kinematic_margins
from urident.excitation.fourier import sample_times
from urident.model.parameters import tool_body_vector
from urident.model.regressor import regressor_blocks
from urident.model.robot import RobotSpec

REST_TOLERANCE = 1e-6   # [rad/s] and [rad/s²] at t = 0 and t = duration
JOINT_CONSTRAINTS = ("position", "velocity", "acceleration", "torque", "rest")
UNITS = {"position": "rad", "velocity": "rad/s", "acceleration": "rad/s^2", "torque": "N m",
         "rest": "rad/s or rad/s^2", "collision": "m"}


class Trajectory(Protocol):
    duration: float

    @property
    def q_start(self) -> np.ndarray: ...

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class Violation:
    """One violated constraint at its worst sample. ``where`` is a joint or collision pair name."""

    constraint: str
    where: str
    index: int          # joint index 0..5 or collision pair index
    time_s: float
    margin: float       # negative [SI unit of the constraint]
    limit: float
    value: float

    def message(self) -> str:
        unit = UNITS[self.constraint]
        if self.constraint == "collision":
            return (f"collision pair {self.where} at t = {self.time_s:.3f} s: distance {self.value:.4f} m "
                    f"< required {self.limit:.4f} m (margin {self.margin:.4f} m)")
        what = {"position": "q", "velocity": "|q̇|", "acceleration": "|q̈|", "torque": "|τ|",
                "rest": "max(|q̇|, |q̈|) at the ends"}[self.constraint]
        return (f"{self.constraint} limit on joint {self.index + 1} ({self.where}) at t = {self.time_s:.3f} s: "
                f"{what} = {self.value:.4g} vs limit {self.limit:.4g} {unit} (margin {self.margin:.4g} {unit})")


@dataclass(frozen=True)
class CheckReport:
    """Result of :func:`check_trajectory`. ``margins[c]`` (6,) is limit − value at the tightest
    sample of constraint c per joint (negative: violated), ``times[c]`` when it happens."""

    robot: str
    rate_hz: float
    n_samples: int
    duration: float
    limits: Limits
    joint_names: tuple[str, ...]
    margins: dict[str, np.ndarray]
    times: dict[str, np.ndarray]
    pair_names: tuple[str, ...]
    pair_distance: np.ndarray     # (P,) smallest distance of each collision pair [m]
    pair_required: np.ndarray     # (P,) required distance (−inf: pair not checked)
    pair_time: np.ndarray         # (P,)
    violations: tuple[Violation, ...] = field(default=())
    payload_kg: float = 0.0       # the payload mass the torque check included [kg]

    @property
    def ok(self) -> bool:
        return not self.violations

    @property
    def checked_pairs(self) -> np.ndarray:
        return np.isfinite(self.pair_required)

    @property
    def min_distance_m(self) -> float:
        """Smallest capsule distance over the checked pairs (floor included) [m]."""
        return float(np.min(self.pair_distance[self.checked_pairs]))

    @property
    def min_distance_pair(self) -> str:
        k = np.flatnonzero(self.checked_pairs)[np.argmin(self.pair_distance[self.checked_pairs])]
        return self.pair_names[k]

    @property
    def collision_margin_m(self) -> float:
        """Smallest distance − required distance over the checked pairs [m]."""
        checked = self.checked_pairs
        return float(np.min(self.pair_distance[checked] - self.pair_required[checked]))

    def raise_if_unsafe(self, source: str) -> None:
        """Raise a one-line :class:`SafetyError` naming ``source`` and the worst violation."""
        if self.ok:
            return
        first = self.violations[0]
        more = f" (and {len(self.violations) - 1} more violations)" if len(self.violations) > 1 else ""
        raise SafetyError(f"{source}: unsafe trajectory: {first.message()}{more}", path=source,
                          violations=tuple(self.violations))

    def to_dict(self) -> dict[str, Any]:
        """The summary ``urident check-trajectory --json`` prints (with the file's details)."""
        return self.as_dict()

    def to_json(self, indent: int | None = 2) -> str:
        import json

        return json.dumps(self.as_dict(), indent=indent)

    def as_dict(self) -> dict[str, Any]:
        """JSON-friendly summary."""
        return {
            "robot": self.robot,
            "ok": self.ok,
            "rate_hz": self.rate_hz,
            "n_samples": self.n_samples,
            "duration_s": self.duration,
            "payload_kg": self.payload_kg,
            "joints": list(self.joint_names),
            "margins": {c: self.margins[c].tolist() for c in JOINT_CONSTRAINTS},
            "margin_times_s": {c: self.times[c].tolist() for c in JOINT_CONSTRAINTS},
            "min_distance_m": self.min_distance_m,
            "min_distance_pair": self.min_distance_pair,
            "collision_margin_m": self.collision_margin_m,
            "pairs": [{"pair": n, "min_distance_m": float(d),
                       "required_m": float(r) if np.isfinite(r) else None, "time_s": float(t)}
                      for n, d, r, t in zip(self.pair_names, self.pair_distance, self.pair_required,
                                            self.pair_time)],
            "violations": [{"constraint": v.constraint, "where": v.where, "time_s": v.time_s,
                            "margin": v.margin, "limit": v.limit, "value": v.value,
                            "message": v.message()} for v in self.violations],
        }


def check_times(duration: float, rate_hz: float) -> np.ndarray:
    """The controller ticks, plus the end time when it is not a tick."""
    t = sample_times(duration, rate_hz)
    if duration - t[-1] > 1e-9:
        t = np.append(t, duration)
    return t


def check_trajectory(spec: RobotSpec, trajectory: Trajectory, rate_hz: float | None = None,
                     limits: Limits | None = None, collision_backend: str = "coal",
                     payload=None) -> CheckReport:
    """Check ``trajectory`` on the grid ``k / rate_hz`` (default: the robot's controller rate).
    Pure: returns a report; call :meth:`CheckReport.raise_if_unsafe` to turn it into an error.
    ``collision_backend`` 'coal' (Pinocchio, the reference) or 'numpy' (same numbers, faster).
    ``payload``: a tool on the flange (:class:`urident.model.payload.Payload`); the torque check
    then holds with and without it (module doc)."""
    rate = float(spec.controller_rate_hz if rate_hz is None else rate_hz)
    limits = Limits.from_robot(spec) if limits is None else limits
    t = check_times(trajectory.duration, rate)
    q, qd, qdd = (np.asarray(x, dtype=float) for x in trajectory.evaluate(t))
    if not all(np.all(np.isfinite(x)) for x in (q, qd, qdd)):
        raise SafetyError(f"trajectory for {spec.name} evaluates to non-finite values")
    km = kinematic_margins(t, q, qd, qdd, limits)
    blocks = regressor_blocks(spec, q, qd, qdd)
    tau = blocks @ spec.nominal_params
    if payload is not None:
        loaded = tau + blocks @ tool_body_vector(payload.body_params(spec))
        tau = np.where(np.abs(loaded) > np.abs(tau), loaded, tau)   # the worse of empty and loaded
    tau_margin = limits.tau_max - np.abs(tau)
    k_tau = np.argmin(tau_margin, axis=0)
    ends = np.stack([np.abs(qd[0]), np.abs(qd[-1]), np.abs(qdd[0]), np.abs(qdd[-1])])
    rest_value = ends.max(axis=0)
    rest_time = np.where(np.argmax(ends, axis=0) % 2 == 0, t[0], t[-1])
    joints = np.arange(6)
    margins = {"position": km.position, "velocity": km.velocity, "acceleration": km.acceleration,
               "torque": tau_margin[k_tau, joints], "rest": REST_TOLERANCE - rest_value}
    times = {"position": km.position_time, "velocity": km.velocity_time,
             "acceleration": km.acceleration_time, "torque": t[k_tau], "rest": rest_time}

    capsules = capsule_model(spec, limits.clearance_m, limits.floor_height_m)
    if collision_backend == "coal":
        dist = CoalDistances(spec, capsules).distances(q)
    elif collision_backend == "numpy":
        dist = capsules.distances(spec, q)
    else:
        raise ValueError(f"unknown collision backend {collision_backend!r}")
    k_pair = np.argmin(dist - np.where(np.isfinite(capsules.required), capsules.required, 0.0), axis=0)
    pair_distance = dist[k_pair, np.arange(dist.shape[1])]

    violations = []
    names = spec.joint_names
    for c in JOINT_CONSTRAINTS:
        for j in joints:
            m = float(margins[c][j])
            if m < 0 or not np.isfinite(m):
                k = int(np.argmin(np.abs(t - times[c][j])))
                value, limit = _value_and_limit(c, j, k, q, qd, qdd, tau, rest_value, limits)
                violations.append(Violation(c, names[j], int(j), float(times[c][j]), m, limit, value))
    for p, name in enumerate(capsules.pair_names):
        if np.isfinite(capsules.required[p]) and pair_distance[p] < capsules.required[p]:
            violations.append(Violation("collision", name, p, float(t[k_pair[p]]),
                                        float(pair_distance[p] - capsules.required[p]),
                                        float(capsules.required[p]), float(pair_distance[p])))
    violations.sort(key=lambda v: v.time_s)
    return CheckReport(spec.name, rate, len(t), float(trajectory.duration), limits, names, margins, times,
                       capsules.pair_names, pair_distance, capsules.required.copy(), t[k_pair],
                       tuple(violations), 0.0 if payload is None else float(payload.mass_kg))


def _value_and_limit(constraint: str, j: int, k: int, q, qd, qdd, tau, rest_value,
                     limits: Limits) -> tuple[float, float]:
    if constraint == "position":
        value = float(q[k, j])
        return value, float(limits.q_min[j] if value - limits.q_min[j] < limits.q_max[j] - value
                            else limits.q_max[j])
    if constraint == "velocity":
        return float(abs(qd[k, j])), float(limits.qd_max[j])
    if constraint == "acceleration":
        return float(abs(qdd[k, j])), float(limits.qdd_max[j])
    if constraint == "torque":
        return float(abs(tau[k, j])), float(limits.tau_max[j])
    return float(rest_value[j]), REST_TOLERANCE
