"""The excitation design problem (paper eq. 26) on fixed time grids: the criterion of the base
regressor's information matrix Λ (cond or log det), the constraints as smooth penalties, and its
exact gradient in the free Fourier coefficients (:mod:`urident.excitation.gradient`).

* The free coefficients (6 × 2(L−1), rest at both ends built in, see :mod:`fourier`) are the
  variables.
* The criterion uses the base regressor on a coarse grid (``criterion_samples``; the grids scale with
  the highest harmonic's cycles, :data:`SAMPLES_PER_CYCLE`); the kinematic
  limits (on a fine grid), collisions (vectorised numpy capsule distances, with a small extra
  buffer) and nominal torques enter as smooth quadratic penalties.
* :meth:`ExcitationProblem.project` scales each joint's coefficients onto the kinematic limits
  (each joint's motion is linear in its own coefficients, so this is exact).

Payload excitation (``for_payload``): the criterion is the condition number of the ten payload
columns (:func:`urident.ident.payload.payload_regressor`, reference-scaled by
:func:`~urident.ident.payload.payload_reference_scales`), the arm's parameters taken as known; the
arm joints 1-3 move within ``arm_joint_fraction`` of their velocity and acceleration limits, so the
motion is the wrist's (the orientation of gravity in the flange frame and the flange's rotation
are all the payload needs, while large arm motion only adds the arm model's error to the residual).
A mounted tool (``spec.tool``) is part of the collision model either way.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from urident.excitation.collision import CapsuleModel, capsule_model
from urident.excitation.constraints import Limits, Margins, joint_scale_factors
from urident.excitation.criteria import CRITERIA, gram_criteria, reference_scales
from urident.excitation.fourier import FourierBasis, FourierTrajectory, base_frequency
from urident.excitation.gradient import STATE_STEP, chain, criterion_weights
from urident.model.base import BaseParameters, base_parameters
from urident.model.parameters import N_PARAMS, tool_body_vector
from urident.model.regressor import regressor_blocks, weighted_state_derivatives
from urident.model.robot import RobotSpec

PAPER_Q0 = (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)  # paper section IV-C: q2,0 = −π/2, others 0
PENALTY_WEIGHT = 1.0e3
KINEMATIC_WEIGHT = 1.0e4
EIG_ABSTOL = 2.0 * np.finfo(float).tiny  # LAPACK's dsyevr: the most accurate eigenvalues
COLLISION_SCALE_M = 0.01  # a shortfall of this much costs the collision penalty's weight
#: Samples per cycle of the highest harmonic on each of the search's grids: Λ's entries are products
#: of regressor entries whose harmonics reach a few times the trajectory's, and a fixed count aliases
#: them once the user asks for more harmonics or periods (60 samples of four periods: cond 33.8 for
#: a design whose cond at the controller rate is 17.2).
SAMPLES_PER_CYCLE = {"criterion": 12, "polish": 20, "collision": 40, "limits": 80}
GRID_FIELDS = {"criterion": "criterion_samples", "polish": "polish_samples",
               "collision": "collision_samples", "limits": "limit_samples"}
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
    candidates: int = 64                  # random feasible points scored before optimising, and
    library: bool | None = None           # the arm's shipped designs of this order (excitation.library);
                                          # None: with seed 0 only (another seed asks for another trajectory)
    starts: int = 8                       # BFGS runs from the best candidates, screened ...
    screen_iterations: int = 60           # ... for this many iterations each, then
    finalists: int = 2                    # the best of them continued until converged
    iterations: int = 1000                # at most this many BFGS iterations per start in all
    tolerance: float = 2e-3               # converged: the objective fell less than this over
    window: int = 50                      # the last ``window`` iterations (2e-3: 0.1 % of cond Θ̄_B)
    hops: int = 2                         # then restarts from the best, perturbed (basin hopping), in
    hop_rounds: int = 12                  # at most this many rounds, each from the best so far, each
    hop_scale: float = 0.3                # coefficient scaled by 1 + hop_scale·N(0, 1); a round starts
    hop_evaluations: int = 24000          # only while the search used fewer evaluations (none: 1 start)
    select: str = "finalised"             # the finalists ranked as written (collision-free, no buffer);
                                          # 'objective': by the search's penalised objective
    polish: int = 2                       # then the best this many continue on the criterion on
    polish_samples: int | None = None     # this many samples (the search's is coarser: cheaper), for at
    polish_iterations: int = 600          # most this many iterations or until the objective falls less
    polish_tolerance: float = 5e-4        # than this over ``window`` (tighter: a restart ranks basins, the polish ends)
    budget_s: float | None = None         # wall-time cap of the search [s]; None: until converged
    workers: int | None = None            # processes running starts (0: none); None: one per core, at most 2
    # The grids' sample counts; None: SAMPLES_PER_CYCLE per cycle of the highest harmonic (60, 100,
    # 200, 400 for the default order 5 over one period). The result is checked and made feasible at
    # the controller rate (optimize._finalise), so the constraint grids may be coarse.
    criterion_samples: int | None = None
    collision_samples: int | None = None
    limit_samples: int | None = None
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
        if min(self.candidates, self.starts, self.finalists, self.window,
               *(self.samples(grid) for grid in SAMPLES_PER_CYCLE if grid != "polish")) < 1 \
                or min(self.iterations, self.screen_iterations) < 0:
            raise ValueError("sample counts, candidates, starts, finalists and window must be positive")
        if self.polish < 0 or self.samples("polish") < 1:
            raise ValueError(f"polish must not be negative and polish_samples positive, not {self.polish} and "
                             f"{self.polish_samples}")
        if self.polish_iterations < 0 or not self.polish_tolerance >= 0:
            raise ValueError(f"polish_iterations and polish_tolerance must not be negative, not "
                             f"{self.polish_iterations} and {self.polish_tolerance}")
        if min(self.hops, self.hop_rounds, self.hop_evaluations) < 0 or not self.hop_scale >= 0:
            raise ValueError(f"hops, hop_rounds, hop_evaluations and hop_scale must not be negative, not "
                             f"{self.hops}, {self.hop_rounds}, {self.hop_evaluations} and {self.hop_scale}")
        if self.select not in ("objective", "finalised"):
            raise ValueError(f"select must be 'objective' or 'finalised', not {self.select!r}")
        if not self.tolerance >= 0:
            raise ValueError(f"tolerance must not be negative, not {self.tolerance}")
        if self.budget_s is not None and not self.budget_s > 0:
            raise ValueError(f"budget_s must be positive, not {self.budget_s}")
        if self.workers is not None and self.workers < 0:
            raise ValueError(f"workers must not be negative, not {self.workers}")
        if self.max_velocity_rad_s is not None and not self.max_velocity_rad_s > 0:
            raise ValueError(f"max_velocity_rad_s must be positive, not {self.max_velocity_rad_s}")
        if not 0 < self.arm_joint_fraction <= 1:
            raise ValueError(f"arm_joint_fraction must be in (0, 1], not {self.arm_joint_fraction}")

    @property
    def omega(self) -> float:
        return base_frequency(self.duration_s, self.periods)

    def samples(self, grid: str) -> int:
        """The sample count of ``grid`` (a key of :data:`SAMPLES_PER_CYCLE`): the one set, else
        proportional to the cycles of the highest harmonic in the duration (harmonics · periods)."""
        count = getattr(self, GRID_FIELDS[grid])
        return SAMPLES_PER_CYCLE[grid] * self.harmonics * self.periods if count is None else count

    def resolved(self, rate_hz: float) -> ExcitationSettings:
        """These settings with every grid's count set: each one not set is :meth:`samples`, at most
        one per controller tick (the result is checked at that rate; a finer grid adds nothing)."""
        ticks = max(1, int(round(self.duration_s * rate_hz)))
        return replace(self, **{name: min(self.samples(grid), ticks) for grid, name in GRID_FIELDS.items()
                                if getattr(self, name) is None})



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
        self.basis_criterion = FourierBasis.build(grid(s.samples("criterion")), w, L)
        self.basis_collision = FourierBasis.build(grid(s.samples("collision")), w, L)
        self.basis_limits = FourierBasis.build(grid(s.samples("limits")), w, L)
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
        # the columns are a linear map of each sample's 78 regressor entries: Θ = blocks @ column_map
        self.column_map = np.ascontiguousarray(self.columns(np.eye(N_PARAMS)[:, None, :])[:, 0, :])
        # the base columns are a selection of them: a gather and a scatter (exact) instead of products
        self.column_index = None if s.for_payload else np.asarray(self.base.independent)
        self.evaluations = 0

    # -- building blocks ---------------------------------------------------------------------
    def project(self, x: np.ndarray, basis: FourierBasis | None = None) -> np.ndarray:
        """Scale each joint's coefficients down to its kinematic limits on ``basis``'s grid."""
        basis = self.basis_limits if basis is None else basis
        dq, qd, qdd = basis.evaluate(x)
        return x * joint_scale_factors(dq, qd, qdd, self.q0, self.limits)[..., None]

    def objective(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(criterion, collision penalty, torque penalty), each (B,), of coefficient sets x (B, 6, K)."""
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
        short = self.collision_shortfall(x)
        collision_pen = np.sum((short / COLLISION_SCALE_M) ** 2, axis=(1, 2)) / len(self.basis_collision.t)
        return crit, collision_pen, torque_pen

    def collision_shortfall(self, x: np.ndarray, buffer: bool = True) -> np.ndarray:
        """(B, N, P) how far each checked pair is inside its required distance + buffer (``buffer``
        False: the required distance alone)."""
        dq = self.basis_collision.evaluate(x)[0]
        d = self.capsules.distances(self.spec, (dq + self.q0).reshape(-1, 6))[:, self.checked]
        required = self.required if buffer else self.required - self.settings.collision_buffer_m
        return np.maximum(required - d, 0.0).reshape(x.shape[0], -1, d.shape[1])

    def kinematic_penalty(self, x: np.ndarray) -> np.ndarray:
        """(B,) mean squared relative excess over the position, velocity and acceleration limits
        on the fine limit grid (smooth, unlike the projection, so BFGS sees no kinks)."""
        dq, qd, qdd = self.basis_limits.evaluate(x)
        excess = (np.maximum(dq / (self.limits.q_max - self.q0) - 1.0, 0.0) ** 2
                  + np.maximum(-dq / (self.q0 - self.limits.q_min) - 1.0, 0.0) ** 2
                  + np.maximum(np.abs(qd) / self.limits.qd_max - 1.0, 0.0) ** 2
                  + np.maximum(np.abs(qdd) / self.limits.qdd_max - 1.0, 0.0) ** 2)
        return np.sum(excess, axis=(1, 2)) / dq.shape[1]

    def value(self, x: np.ndarray) -> np.ndarray:
        """(B,) the penalised objective BFGS minimises."""
        crit, coll, torque = self.objective(x)
        return crit + PENALTY_WEIGHT * (coll + torque) + KINEMATIC_WEIGHT * self.kinematic_penalty(x)

    def value_and_gradient(self, flat: np.ndarray) -> tuple[float, np.ndarray]:
        """The objective (:meth:`value`) and its exact gradient in the free coefficients.

        The criterion's derivative in the Gram matrix is ``W`` (from its eigenvectors), so its
        derivative in the stacked columns is ``H = 2/m · Θ S⁻¹ W S⁻¹``; the regressor's derivatives
        in each sample's state (exact; forward differences in q, q̇ without the compiled kernel) are
        taken on ``H``'s weighted sum (:func:`~urident.model.regressor.weighted_state_derivatives`),
        and each state is linear in the coefficients (:class:`FourierBasis`). The torque penalty
        uses the same derivatives; the kinematic penalty is differentiated analytically, the
        collision penalty through the capsule distances' exact derivatives in q, only at samples
        inside a required distance."""
        x = flat.reshape(6, self.n_free)
        basis = self.basis_criterion
        dq, qd, qdd = basis.evaluate_one(x)                                   # (N, 6)
        n = dq.shape[0]
        q = dq + self.q0
        point = regressor_blocks(self.spec, q, qd, qdd)                       # (N, 6, 78)
        self.evaluations += 1
        # 2-D products: one BLAS call instead of one per sample (the same sums, bit for bit)
        flat_point = point.reshape(-1, N_PARAMS)
        if self.column_index is None:
            flat_theta = flat_point @ self.column_map                          # (6N, b)
        else:
            flat_theta = flat_point[:, self.column_index]
        inv = 1.0 / self.scales
        lam = (flat_theta.T @ flat_theta) / n * inv[:, None] * inv[None, :]
        if not np.all(np.isfinite(lam)):  # a line-search trial far outside the limits: refuse the step
            return np.inf, np.zeros_like(flat)
        # not LAPACK's evd: 30× slower with contended BLAS threads; lam was checked finite above
        if self.settings.criterion == "cond":  # only the two extreme pairs carry weight: two
            # subset solves cost half a full one; abstol: bisection to full relative accuracy
            ends = [scipy.linalg.lapack.dsyevr(lam, compute_v=1, range="I", il=k, iu=k, abstol=EIG_ABSTOL)
                    for k in (1, lam.shape[0])]
            if any(e[-1] != 0 for e in ends):
                return np.inf, np.zeros_like(flat)
            eig, vec = np.concatenate([e[0][:1] for e in ends]), np.concatenate([e[1][:, :1] for e in ends], axis=1)
        else:
            eig, vec = scipy.linalg.eigh(lam, driver="evr", check_finite=False)
        eig = np.maximum(eig, 1e-300)
        crit, weights = criterion_weights(eig, self.settings.criterion)
        w_mat = (vec * weights) @ vec.T
        # the derivative in the regressor's 78 columns of every sample: criterion, then torque
        d_theta = (2.0 / n) * (flat_theta @ (inv[:, None] * w_mat * inv[None, :]))   # (6N, b)
        if self.column_index is None:
            adjoint = (d_theta @ self.column_map.T).reshape(n, 6, N_PARAMS)
        else:
            adjoint = np.zeros_like(flat_point)
            adjoint[:, self.column_index] = d_theta
            adjoint = adjoint.reshape(n, 6, N_PARAMS)
        loads = [self.p_nominal] if self.p_payload is None else [self.p_nominal, self.p_nominal + self.p_payload]
        taus = [point @ p for p in loads]                                     # (N, 6) each
        excess = [np.maximum(np.abs(tau) / self.limits.tau_max - 1.0, 0.0) for tau in taus]
        torque_pen = float(np.sum(np.maximum.reduce(excess) ** 2)) / n
        if any(e.any() for e in excess):  # else every term below is zero
            worst = np.argmax(np.stack(excess), axis=0)
            for k, p in enumerate(loads):
                g_tau = np.where(worst == k, 2.0 * excess[k] * np.sign(taus[k]) / self.limits.tau_max, 0.0) / n
                if np.any(g_tau):
                    adjoint += PENALTY_WEIGHT * g_tau[..., None] * p
        d_state = weighted_state_derivatives(self.spec, q, qd, qdd, adjoint, STATE_STEP)  # (18, N)
        grad = chain(basis, d_state)

        # kinematic penalty (linear in the coefficients)
        kin, g_kin = self.kinematic_penalty_gradient(x)
        # collision penalty
        coll, g_coll = self.collision_penalty_gradient(x)
        value = crit + PENALTY_WEIGHT * (coll + torque_pen) + KINEMATIC_WEIGHT * kin
        if g_coll is not None:
            grad = grad + PENALTY_WEIGHT * g_coll
        if g_kin is not None:
            grad = grad + KINEMATIC_WEIGHT * g_kin
        return float(value), grad.ravel()

    def kinematic_penalty_gradient(self, x: np.ndarray) -> tuple[float, np.ndarray | None]:
        """:meth:`kinematic_penalty` of one coefficient set (6, K) and its gradient (6, K) (None:
        within every limit, so zero): one product with :attr:`_limit_map`, whose columns are the
        limit grid's q − q0 over its upper and (negated) lower room, q̇ and q̈ over their limits."""
        n = self.basis_limits.t.shape[0]
        v = (np.ascontiguousarray(x)[:, None, :] @ self._limit_map)[:, 0, :]     # (6, 4N)
        sign = np.sign(v[:, 2 * n:])
        v[:, 2 * n:] = np.abs(v[:, 2 * n:])
        excess = np.maximum(v - 1.0, 0.0)
        if not excess.any():
            return 0.0, None
        value = float(np.sum(excess ** 2)) / n
        g_v = (2.0 / n) * excess
        g_v[:, 2 * n:] *= sign
        return value, (self._limit_map @ g_v[:, :, None])[:, :, 0]

    @cached_property
    def _limit_map(self) -> np.ndarray:
        """(6, K, 4N): the free coefficients to q − q0 over (q_max − q0), −(q − q0) over (q0 − q_min),
        q̇ over q̇_max and q̈ over q̈_max on the limit grid."""
        b, lim = self.basis_limits, self.limits
        up, down = (lim.q_max - self.q0)[:, None, None], (self.q0 - lim.q_min)[:, None, None]
        stacked = np.concatenate([b.q / up, -b.q / down, b.qd / lim.qd_max[:, None, None],
                                  b.qdd / lim.qdd_max[:, None, None]], axis=1)        # (6, 4N, K)
        return np.ascontiguousarray(stacked.transpose(0, 2, 1))

    def collision_penalty_gradient(self, x: np.ndarray) -> tuple[float, np.ndarray | None]:
        """The collision penalty of one coefficient set (6, K) and its gradient (6, K) (None: no
        sample inside a required distance, so zero), from the capsule distances' exact derivatives
        in the joint angles at the samples inside a required distance (+ buffer) only."""
        basis = self.basis_collision
        q = basis.evaluate_one(x, "q")[0] + self.q0                           # (N, 6)
        n = q.shape[0]
        d = self.capsules.distances(self.spec, q)[:, self.checked]
        short = np.maximum(self.required - d, 0.0)
        rows = np.flatnonzero(np.any(short > 0, axis=1))
        value = float(np.sum((short / COLLISION_SCALE_M) ** 2)) / n
        if not len(rows):
            return value, None
        where = np.zeros((len(rows), self.capsules.n_pairs), dtype=bool)   # the derivatives needed
        where[:, self.checked] = short[rows] > 0
        d_dq = self.capsules.distance_derivatives(self.spec, q[rows], where)[:, self.checked]   # (R, P, 6)
        g_d = -2.0 * short[rows] / COLLISION_SCALE_M ** 2 / n                  # (R, P)
        g_q = np.einsum("rp,rpj->rj", g_d, d_dq)                               # (R, 6)
        grad = np.einsum("rj,jrf->jf", g_q, basis.q[:, rows])
        return value, grad

    def shrink_to_collision_free(self, x: np.ndarray, factor: float = 0.85, steps: int = 30,
                                 buffer: bool = True) -> np.ndarray:
        """Scale each coefficient set (B, 6, K) towards q0 by factor**k, the smallest k that clears
        the collision grid (with buffer, unless ``buffer`` is False); q0 is collision-free, so small
        enough always works."""
        x = x.copy()
        pending = np.arange(x.shape[0])
        for _ in range(steps):
            if not len(pending):
                break
            bad = np.any(self.collision_shortfall(x[pending], buffer) > 0, axis=(1, 2))
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
