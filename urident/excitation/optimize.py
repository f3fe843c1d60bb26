"""Optimised excitation trajectories (paper eq. 26): minimise cond(Λ) (or maximise log det Λ) of the
base regressor over the Fourier coefficients, subject to joint, velocity, acceleration, torque and
collision constraints.

Method
* The free coefficients (6 × 2(L−1), rest at both ends built in, see :mod:`fourier`) are the
  variables. Starts are random coefficients scaled per joint down to the position, velocity and
  acceleration limits (each joint's motion is linear in its own coefficients, so this is exact,
  :func:`joint_scale_factors`) and then towards q0 until collision-free.
* The criterion uses the base regressor on a coarse grid (``criterion_samples``); the kinematic
  limits (on a fine grid), collisions (vectorised numpy capsule distances, with a small extra
  buffer) and nominal torques enter as smooth quadratic penalties.
* Gradients are forward differences, all perturbations evaluated in one batched regressor call;
  L-BFGS-B runs from the best few of many seeded random feasible starts.
* The result is projected onto the limits at the controller rate, and shrunk towards q0 if the dense
  collision check needs it, so it passes :func:`check_trajectory`.

Payload excitation (``for_payload``): the criterion is the condition number of the ten payload
columns (:func:`urident.ident.payload.payload_regressor`, reference-scaled by
:func:`~urident.ident.payload.payload_reference_scales`), the arm's parameters taken as known; the
arm joints 1-3 move within ``arm_joint_fraction`` of their velocity and acceleration limits, so the
motion is the wrist's (the orientation of gravity in the flange frame and the flange's rotation
are all the payload needs, while large arm motion only adds the arm model's error to the residual).
A mounted tool (``spec.tool``) is part of the collision model either way.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import scipy.optimize

from urident.excitation.collision import CapsuleModel, capsule_model
from urident.excitation.constraints import Limits, Margins, joint_scale_factors
from urident.excitation.criteria import (CRITERIA, CriterionValues, evaluate_criteria, gram_criteria,
                                         reference_scales)
from urident.excitation.fourier import FourierBasis, FourierTrajectory, base_frequency, sample_times
from urident.model.base import BaseParameters, base_parameters
from urident.model.parameters import tool_body_vector
from urident.model.regressor import regressor_blocks
from urident.model.robot import RobotSpec

PAPER_Q0 = (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)  # paper section IV-C: q2,0 = −π/2, others 0
_PENALTY_WEIGHT = 1.0e3
_KINEMATIC_WEIGHT = 1.0e4
_FD_STEP = 1e-6
#: ``for_payload``: joints 1-3 keep within this fraction of their velocity and acceleration limits.
ARM_JOINT_FRACTION = 0.2


@dataclass(frozen=True)
class ExcitationSettings:
    harmonics: int = 5
    duration_s: float = 20.0
    periods: int = 1                      # whole base periods in the duration: ω = 2π·periods/T
    q0: tuple[float, ...] = PAPER_Q0
    criterion: str = "cond"               # 'cond' (min cond Λ) or 'logdet' (max log det Λ)
    reduced: bool = False                 # the paper's reduced (33) or the full (52) base parameters
    seed: int = 0
    candidates: int = 24                  # random feasible points scored before optimising
    starts: int = 2                       # L-BFGS-B runs from the best candidates
    iterations: int = 100                 # L-BFGS-B iterations per start
    criterion_samples: int = 100
    collision_samples: int = 400
    limit_samples: int = 800
    collision_buffer_m: float = 0.01      # extra distance while optimising on the coarse grid
    margins: Margins = field(default_factory=Margins)
    for_payload: bool = False             # criterion: cond of the payload columns (module doc)
    arm_joint_fraction: float = ARM_JOINT_FRACTION   # for_payload: joints 1-3's share of their limits
    max_velocity_rad_s: float | None = None  # the optimiser's |q̇| bound on every joint besides the margins'

    def __post_init__(self) -> None:
        if self.criterion not in CRITERIA:
            raise ValueError(f"criterion must be one of {', '.join(CRITERIA)}, not {self.criterion!r}")
        if self.harmonics < 2:
            raise ValueError("harmonics must be at least 2 (rest at both ends removes two per joint)")
        if not self.duration_s > 0 or self.periods < 1:
            raise ValueError("duration_s must be positive and periods at least 1")
        if len(self.q0) != 6:
            raise ValueError("q0 must have 6 entries")
        if min(self.candidates, self.starts, self.criterion_samples, self.collision_samples,
               self.limit_samples) < 1 or self.iterations < 0:
            raise ValueError("sample counts, candidates and starts must be positive")
        if self.max_velocity_rad_s is not None and not self.max_velocity_rad_s > 0:
            raise ValueError(f"max_velocity_rad_s must be positive, not {self.max_velocity_rad_s}")
        if not 0 < self.arm_joint_fraction <= 1:
            raise ValueError(f"arm_joint_fraction must be in (0, 1], not {self.arm_joint_fraction}")

    @property
    def omega(self) -> float:
        return base_frequency(self.duration_s, self.periods)


@dataclass(frozen=True)
class ExcitationResult:
    trajectory: FourierTrajectory
    criteria: CriterionValues           # at the controller rate
    coarse_criteria: CriterionValues    # on the optimiser's criterion grid
    min_distance_m: float               # numpy capsule distance at the controller rate
    wall_s: float
    evaluations: int
    settings: ExcitationSettings
    limits: Limits
    history: tuple[float, ...]          # best objective after each start
    payload_cond: float | None = None   # for_payload: cond of the payload columns at the controller rate


class ExcitationProblem:
    """The objective on fixed grids, batched over coefficient sets ``X`` (B, 6, 2(L−1))."""

    def __init__(self, spec: RobotSpec, settings: ExcitationSettings,
                 base: BaseParameters | None = None, payload=None):
        s = settings
        self.spec, self.settings = spec, s
        self.file_limits = Limits.from_robot(spec, s.margins)   # what the trajectory file states
        self.limits = self.file_limits
        if s.for_payload:  # the optimiser's own, tighter bounds on the arm joints (module doc)
            f = np.where(np.arange(6) < 3, s.arm_joint_fraction, 1.0)
            self.limits = replace(self.file_limits, qd_max=self.file_limits.qd_max * f,
                                  qdd_max=self.file_limits.qdd_max * f)
        if s.max_velocity_rad_s is not None:
            self.limits = replace(self.limits, qd_max=np.minimum(self.limits.qd_max, s.max_velocity_rad_s))
        self.q0 = np.array(s.q0, dtype=float)
        if np.any(self.q0 <= self.limits.q_min) or np.any(self.q0 >= self.limits.q_max):
            raise ValueError("q0 is not strictly inside the position limits (with margin)")
        self.base = base_parameters(spec, reduced=s.reduced) if base is None else base
        self.capsules: CapsuleModel = capsule_model(spec, s.margins.clearance_m, s.margins.floor_height_m)
        checked = np.isfinite(self.capsules.required)
        self.checked = checked
        self.required = self.capsules.required[checked] + s.collision_buffer_m
        margins0 = self.capsules.margins(spec, self.q0[None])[0]
        if np.any(margins0[checked] < 0):
            k = np.flatnonzero(checked)[np.argmin(margins0[checked])]
            pair = self.capsules.pair_names[k]
            tool = (f" (the tool capsule: radius {spec.tool.radius_m:g} m, length {spec.tool.length_m:g} m)"
                    if spec.tool is not None and "tool" in pair else "")
            raise ValueError(f"the offset configuration q0 itself violates the collision clearance: pair "
                             f"{pair}{tool} by {-margins0[k]:.3g} m")
        T, w, L = s.duration_s, s.omega, s.harmonics
        grid = lambda n: np.arange(n) * (T / n)  # noqa: E731  (periodic: t = T equals t = 0)
        self.basis_criterion = FourierBasis.build(grid(s.criterion_samples), w, L)
        self.basis_collision = FourierBasis.build(grid(s.collision_samples), w, L)
        self.basis_limits = FourierBasis.build(grid(s.limit_samples), w, L)
        self.n_free = 2 * (L - 1)
        self.p_nominal = spec.nominal_params
        # a tool's load: the torque penalty holds with and without it, as the dense check does
        self.p_payload = None if payload is None else tool_body_vector(payload.body_params(spec))
        if s.for_payload:
            from urident.ident.payload import payload_reference_scales, payload_regressor

            self.columns = lambda blocks: payload_regressor(spec, blocks)
            self.scales = payload_reference_scales(spec)
        else:
            self.columns = lambda blocks: blocks[..., self.base.independent]
            self.scales = reference_scales(spec, self.base)
        self.n_columns = len(self.scales)
        self.evaluations = 0

    # -- building blocks ---------------------------------------------------------------------
    def project(self, x: np.ndarray, basis: FourierBasis | None = None) -> np.ndarray:
        """Scale each joint's coefficients down to its kinematic limits on ``basis``'s grid."""
        basis = self.basis_limits if basis is None else basis
        dq, qd, qdd = basis.evaluate(x)
        return x * joint_scale_factors(dq, qd, qdd, self.q0, self.limits)[..., None]

    def objective(self, x: np.ndarray, rows: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(criterion, collision penalty, torque penalty), each (B,), of projected coefficients.
        ``rows``: only these collision-grid samples can contribute to the collision penalty."""
        b = x.shape[0]
        self.evaluations += b
        dq, qd, qdd = self.basis_criterion.evaluate(x)
        blocks = regressor_blocks(self.spec, (dq + self.q0).reshape(-1, 6), qd.reshape(-1, 6),
                                  qdd.reshape(-1, 6))
        tau = (blocks @ self.p_nominal).reshape(b, -1, 6)
        theta = self.columns(blocks).reshape(b, -1, self.n_columns)
        # A contiguous transpose keeps the batched product on the fast BLAS path.
        gram = (np.ascontiguousarray(theta.transpose(0, 2, 1)) @ theta) / dq.shape[1]
        log_cond, logdet = gram_criteria(gram, self.scales)
        crit = log_cond if self.settings.criterion == "cond" else -logdet / self.n_columns
        excess = np.maximum(np.abs(tau) / self.limits.tau_max - 1.0, 0.0)
        if self.p_payload is not None:
            loaded = tau + (blocks @ self.p_payload).reshape(b, -1, 6)
            excess = np.maximum(excess, np.abs(loaded) / self.limits.tau_max - 1.0)
        torque_pen = np.sum(excess ** 2, axis=(1, 2)) / tau.shape[1]
        collision_pen = np.zeros(b)
        if rows is None or len(rows):
            short = self.collision_shortfall(x, rows)
            collision_pen = np.sum((short / 0.01) ** 2, axis=(1, 2)) / len(self.basis_collision.t)
        return crit, collision_pen, torque_pen

    def collision_shortfall(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """(B, n_rows, P) how far each checked pair is inside its required distance + buffer."""
        basis = self.basis_collision
        qb = basis.q if rows is None else basis.q[:, rows]
        dq = FourierBasis(basis.t, qb, qb, qb).evaluate(x)[0]
        d = self.capsules.distances(self.spec, (dq + self.q0).reshape(-1, 6))[:, self.checked]
        return np.maximum(self.required - d, 0.0).reshape(x.shape[0], -1, d.shape[1])

    def kinematic_penalty(self, x: np.ndarray) -> np.ndarray:
        """(B,) mean squared relative excess over the position, velocity and acceleration limits
        on the fine limit grid (smooth, unlike the projection, so L-BFGS-B sees no kinks)."""
        dq, qd, qdd = self.basis_limits.evaluate(x)
        excess = (np.maximum(dq / (self.limits.q_max - self.q0) - 1.0, 0.0) ** 2
                  + np.maximum(-dq / (self.q0 - self.limits.q_min) - 1.0, 0.0) ** 2
                  + np.maximum(np.abs(qd) / self.limits.qd_max - 1.0, 0.0) ** 2
                  + np.maximum(np.abs(qdd) / self.limits.qdd_max - 1.0, 0.0) ** 2)
        return np.sum(excess, axis=(1, 2)) / dq.shape[1]

    def value(self, x: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        crit, coll, torque = self.objective(x, rows)
        return crit + _PENALTY_WEIGHT * (coll + torque) + _KINEMATIC_WEIGHT * self.kinematic_penalty(x)

    def value_and_gradient(self, flat: np.ndarray) -> tuple[float, np.ndarray]:
        """Objective and its forward-difference gradient. The perturbations (one batch) only
        re-evaluate collision samples within 1 mm of their required distance: the others cannot
        enter the penalty for a step of 1e-6 rad/s."""
        x = flat.reshape(1, 6, self.n_free)
        f0 = float(self.value(x)[0])
        dq = self.basis_collision.evaluate(x)[0][0]
        d = self.capsules.distances(self.spec, dq + self.q0)[:, self.checked]
        rows = np.flatnonzero(np.any(d < self.required + 1e-3, axis=1))
        n = flat.size
        batch = np.repeat(flat.reshape(1, 6, self.n_free), n, axis=0)
        idx = np.arange(n)
        batch.reshape(n, -1)[idx, idx] += _FD_STEP
        values = self.value(batch, rows)
        return f0, (values - f0) / _FD_STEP

    def shrink_to_collision_free(self, x: np.ndarray, factor: float = 0.85, steps: int = 30) -> np.ndarray:
        """Scale each coefficient set (B, 6, K) towards q0 by factor**k, the smallest k that clears
        the collision grid (with buffer); q0 is collision-free, so small enough always works."""
        x = x.copy()
        pending = np.arange(x.shape[0])
        for _ in range(steps):
            if not len(pending):
                break
            bad = np.any(self.collision_shortfall(x[pending]) > 0, axis=(1, 2))
            pending = pending[bad]
            x[pending] *= factor
        return x

    def trajectory(self, x: np.ndarray) -> FourierTrajectory:
        return FourierTrajectory.from_free(x, self.settings.omega, self.q0, self.settings.duration_s)

    def random_coefficients(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` random coefficient sets (n, 6, 2(L−1)), projected onto the kinematic limits.
        Higher harmonics are drawn smaller (1/l), the usual spectrum of smooth excitation."""
        L = self.settings.harmonics
        weights = np.concatenate([1.0 / np.arange(2, L + 1)] * 2)
        x = rng.standard_normal((n, 6, self.n_free)) * weights * self.limits.qd_max[:, None]
        return self.project(x)


def optimize_excitation(spec: RobotSpec, settings: ExcitationSettings | None = None,
                        progress: Callable[[str], None] | None = None,
                        base: BaseParameters | None = None, payload=None) -> ExcitationResult:
    """Optimise an excitation trajectory for ``spec``; reproducible for a given ``settings.seed``.
    ``payload`` (:class:`urident.ident.payload.Payload`): the torque limits hold with it too."""
    settings = ExcitationSettings() if settings is None else settings
    say = progress or (lambda message: None)
    start_time = time.perf_counter()
    problem = ExcitationProblem(spec, settings, base, payload)
    rng = np.random.default_rng(settings.seed)

    candidates = problem.shrink_to_collision_free(problem.random_coefficients(rng, settings.candidates))
    crit, coll, torque = problem.objective(candidates)
    scores = crit + _PENALTY_WEIGHT * (coll + torque)
    order = np.argsort(scores)[: settings.starts]
    say(f"{settings.candidates} random feasible candidates: best criterion {_show(settings, crit[order[0]])}")

    results = []
    history = []
    for k, c in enumerate(order, start=1):
        iteration = [0]

        def callback(xk: np.ndarray, k=k) -> None:
            iteration[0] += 1
            if iteration[0] % 10 == 0:
                v = problem.value(xk.reshape(1, 6, -1))[0]
                say(f"start {k}/{len(order)}: iteration {iteration[0]}, objective {v:.4f}")

        # Restart L-BFGS-B from where it stopped (e.g. a failed line search at a kink of the
        # collision penalty) until the iteration budget is used or a restart makes no progress.
        x0, used, best = candidates[c].ravel(), 0, np.inf
        while used < settings.iterations:
            res = scipy.optimize.minimize(problem.value_and_gradient, x0, jac=True, method="L-BFGS-B",
                                          callback=callback,
                                          options={"maxiter": settings.iterations - used, "maxcor": 20})
            used += max(res.nit, 1)
            if not res.fun < best - 1e-6:
                break
            x0, best = res.x, res.fun
        res.x = x0
        x = problem.project(res.x.reshape(1, 6, -1))
        c_val, coll_val, tau_val = (float(v[0]) for v in problem.objective(x))
        results.append((c_val + _PENALTY_WEIGHT * (coll_val + tau_val), coll_val + tau_val, x[0]))
        history.append(min(r[0] for r in results))
        say(f"start {k}/{len(order)}: criterion {_show(settings, c_val)}, penalty {coll_val + tau_val:.3g} "
            f"({used} iterations, {time.perf_counter() - start_time:.1f} s)")

    # Best by objective (the penalty includes the buffer, so a tiny one is harmless); then make it
    # exactly feasible at the controller rate.
    results.sort(key=lambda r: r[0])
    trajectory, min_distance = _finalise(problem, spec, results[0][2])
    t = sample_times(settings.duration_s, spec.controller_rate_hz)
    dense = evaluate_criteria(spec, problem.base, *trajectory.evaluate(t))
    coarse = evaluate_criteria(spec, problem.base, *trajectory.evaluate(problem.basis_criterion.t))
    payload_cond = None
    if settings.for_payload:
        from urident.ident.payload import payload_condition

        payload_cond = payload_condition(spec, *trajectory.evaluate(t))
    wall = time.perf_counter() - start_time
    say(f"done in {wall:.1f} s: cond(Θ̄_B) = {dense.cond_theta:.4g} at {spec.controller_rate_hz:g} Hz, "
        + (f"payload columns cond {payload_cond:.4g}, " if payload_cond is not None else "")
        + f"min distance {min_distance:.4f} m")
    return ExcitationResult(trajectory, dense, coarse, min_distance, wall, problem.evaluations,
                            settings, problem.file_limits, tuple(history), payload_cond)


def _finalise(problem: ExcitationProblem, spec: RobotSpec, x: np.ndarray) -> tuple[FourierTrajectory, float]:
    """Project onto the limits at the controller rate; shrink towards q0 until the dense numpy
    collision check passes (q0 itself is collision-free, so this terminates)."""
    t = sample_times(problem.settings.duration_s, spec.controller_rate_hz)
    dense = FourierBasis.build(t, problem.settings.omega, problem.settings.harmonics)
    x = problem.project(x[None], dense)[0] * (1.0 - 1e-9)
    required = problem.capsules.required[problem.checked]
    for shrink in [1.0] + list(0.98 ** np.arange(1, 200)):
        trajectory = problem.trajectory(x * shrink)
        q = trajectory.evaluate(t)[0]
        d = problem.capsules.distances(spec, q)[:, problem.checked]
        if np.all(d >= required):
            return trajectory, float(d.min())
    raise RuntimeError("could not make the trajectory collision-free")  # pragma: no cover


def random_feasible_criteria(spec: RobotSpec, settings: ExcitationSettings, n: int, seed: int = 1,
                             base: BaseParameters | None = None, batch: int = 50) -> np.ndarray:
    """cond(Θ̄_B) (reference-scaled columns, on the criterion grid) of ``n`` random trajectories
    that satisfy the same constraints: random coefficients (the optimiser's start distribution),
    scaled down per joint to the kinematic limits, then together towards q0 in steps of 10 % until
    they clear the collision grid (without the optimiser's buffer); any that still collide or exceed
    the torque limit are rejected. This gives every random direction its largest feasible amplitude,
    the strongest random baseline."""
    settings = replace(settings, collision_buffer_m=0.0)
    problem = ExcitationProblem(spec, settings, base)
    rng = np.random.default_rng(seed)
    conds: list[float] = []
    while len(conds) < n:
        x = problem.shrink_to_collision_free(problem.random_coefficients(rng, batch), factor=0.9, steps=60)
        ok = ~np.any(problem.collision_shortfall(x) > 0, axis=(1, 2))
        if not ok.any():
            continue
        dq, qd, qdd = problem.basis_criterion.evaluate(x[ok])
        blocks = regressor_blocks(spec, (dq + problem.q0).reshape(-1, 6), qd.reshape(-1, 6), qdd.reshape(-1, 6))
        m = int(ok.sum())
        tau = (blocks @ problem.p_nominal).reshape(m, -1, 6)
        tau_ok = np.all(np.abs(tau) <= problem.limits.tau_max, axis=(1, 2))
        theta = blocks[..., problem.base.independent].reshape(m, -1, problem.base.n_base)
        sv = np.linalg.svd(theta / problem.scales, compute_uv=False)
        conds += list((sv[:, 0] / sv[:, -1])[tau_ok])
    return np.array(conds[:n])


def _show(settings: ExcitationSettings, value: float) -> str:
    if settings.criterion == "cond":
        return f"cond({'payload columns' if settings.for_payload else 'Θ̄_B'}) = {np.exp(value / 2):.4g}"
    return f"log det(Λ)/b = {-value:.4g}"
