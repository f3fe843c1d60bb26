"""Optimised excitation trajectories (paper eq. 26): minimise cond(Λ) (or maximise log det Λ) of the
base regressor over the Fourier coefficients, subject to joint, velocity, acceleration, torque and
collision constraints (the problem and its exact gradient: :mod:`urident.excitation.problem`).

Method (measured against L-BFGS-B with forward differences and a smooth bound of cond, README)
* Starts: ``candidates`` random coefficient sets and (``library``; by default with seed 0 only) the
  arm's shipped designs of this order (:mod:`urident.excitation.library`), scaled per joint onto the position, velocity and
  acceleration limits and towards q0 until collision-free; the best ``starts`` of them.
* Each start runs BFGS (a dense quasi-Newton matrix: 6·2(L−1) variables) on the penalised
  objective with its exact gradient, ``screen_iterations`` at first; the best ``finalists``
  continue (their BFGS matrix kept) until converged: the objective fell by less than
  ``tolerance`` over the last ``window`` iterations, or the gradient vanished, or ``iterations``.
  Local optima differ by tens of percent between starts, so screening many beats running few long.
* Then rounds of ``hops`` restarts from the best converged point so far (one per worker), each
  coefficient scaled by 1 + ``hop_scale``·N(0, 1) (basin hopping), run to convergence the same way;
  at most ``hop_rounds``, and a round starts only while the search used fewer than
  ``hop_evaluations`` objective-and-gradient evaluations (so its CPU time stays bounded). From a
  converged point a restart reached a lower basin far more often than a fresh start did
  (docs/excitation.md). None for a single start (``starts=1``: that start alone, quick). The best
  of all is polished: the best ``polish`` continue on the criterion on ``polish_samples`` samples
  (the search's ``criterion_samples`` are fewer: cheaper, but its optimum is 1–2.5 % worse there),
  to ``polish_tolerance`` (four times tighter than the search's: a restart only has to rank its
  basin, the polish ends the design) or ``polish_iterations``.
  The finalists are ranked as written (``select='finalised'``): each made collision-free at the
  controller rate without the search's buffer, then scored on the criterion plus the torque penalty;
  ``'objective'`` ranks them by the search's penalised objective, whose collision part includes the
  buffer (it ranked UR20 seed 2's best two finalists out; docs/excitation.md).
* Starts run in ``workers`` spawned processes with one BLAS thread each, and so does this process (``workers=0``, the
  default for a single start: in this process). On a shared machine, threaded BLAS made the small matrix products of one evaluation
  10-70 times slower (eigh of 52×52: 58 ms against 0.7 ms). Every start's result is independent of
  the others and of the order they run in, so a seed gives one trajectory on a given machine and
  numpy/BLAS build (another CPU's BLAS kernels change the last bits, and the path: docs/excitation.md).
* ``budget_s`` caps the search's wall time; :class:`Convergence` says how far from converged it
  stopped.
* The result is projected onto the limits at the controller rate, and shrunk towards q0 if the dense
  collision check needs it, so it passes :func:`check_trajectory`.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
import scipy.optimize

from urident.blas import one_blas_thread
from urident.excitation.constraints import Limits
from urident.excitation.criteria import CriterionValues, evaluate_criteria
from urident.excitation.fourier import FourierBasis, FourierTrajectory, sample_times
from urident.excitation.library import starts_for
from urident.excitation.problem import (ARM_JOINT_FRACTION, PAPER_Q0, PENALTY_WEIGHT, ExcitationProblem,
                                        ExcitationSettings)
from urident.model.base import BaseParameters
from urident.model.regressor import regressor_blocks
from urident.model.robot import RobotSpec
from urident.progress import Progress

__all__ = ["ARM_JOINT_FRACTION", "PAPER_Q0", "Convergence", "ExcitationProblem", "ExcitationResult",
           "ExcitationSettings", "optimize_excitation", "random_feasible_criteria"]

MAX_WORKERS = 2            # the starts gain nothing from more processes than the 2 cores we target
_GRADIENT_TOL = 1e-8       # BFGS's own stop (|∇|∞); the window rule usually ends a start first
_REPORT_EVERY = 10         # iterations between a worker's progress reports
_HOP_SEED_OFFSET = 1000    # the perturbed restarts' generator: seed + this


@dataclass(frozen=True)
class Convergence:
    """How the chosen start's search ended."""

    iterations: int            # BFGS iterations in all (screening, continuation and polish)
    reason: str                # 'converged', 'gradient', 'iterations', 'budget' or 'line search'
    gradient_norm: float       # 2-norm of the penalised objective's gradient at the end
    improvement: float         # fall of the objective over the last ``window`` iterations (nan: fewer)
    window: int

    @property
    def converged(self) -> bool:
        return self.reason in ("converged", "gradient", "line search")

    def as_dict(self) -> dict:
        """For the trajectory file's ``optimization`` section (numbers, strings and booleans only)."""
        out = {"converged": self.converged, "stop_reason": self.reason, "total_iterations": self.iterations,
               "gradient_norm": float(self.gradient_norm), "window": self.window}
        if not np.isnan(self.improvement):
            out["last_window_improvement"] = float(self.improvement)
        return out

    def describe(self, criterion: str) -> str:
        """One line: why the search stopped and how far from converged."""
        what = {"converged": "converged", "gradient": "converged (gradient vanished)",
                "line search": "converged (no further descent found)",
                "iterations": "stopped at the iteration limit", "budget": "stopped by the time budget"}[self.reason]
        if np.isnan(self.improvement):
            fall = "fewer iterations than the window"
        elif criterion == "cond":
            fall = f"cond fell {100 * -np.expm1(-self.improvement / 2):.2f} % over the last {self.window} iterations"
        else:
            fall = f"det(Λ)^(1/b) rose {100 * np.expm1(self.improvement):.2f} % over the last {self.window} iterations"
        return f"{what} after {self.iterations} iterations ({fall}, |∇| {self.gradient_norm:.2g})"


@dataclass(frozen=True)
class ExcitationResult:
    trajectory: FourierTrajectory
    criteria: CriterionValues           # at the controller rate
    coarse_criteria: CriterionValues    # on the criterion grid of the polish (of the search without one)
    min_distance_m: float               # numpy capsule distance at the controller rate
    wall_s: float
    evaluations: int                    # objective-and-gradient evaluations, all starts
    settings: ExcitationSettings
    limits: Limits
    history: tuple[float, ...]          # each start's objective at its end, in start order
    payload_cond: float | None = None   # for_payload: cond of the payload columns at the controller rate
    convergence: Convergence | None = None
    cpu_s: float = 0.0                  # CPU time of this process and the workers' starts [s]
    shipped_designs: int = 0            # shipped designs among the candidates (excitation.library)
    from_shipped: bool = False          # the result began at one of them


@dataclass(frozen=True)
class _Start:
    """One start's state between BFGS runs (picklable: it crosses to the worker processes)."""

    key: int
    x: np.ndarray
    hess_inv: np.ndarray | None = None
    history: tuple[float, ...] = ()     # objective after each iteration
    reason: str = ""                    # why the last run ended
    gradient_norm: float = np.inf
    evaluations: int = 0
    cpu_s: float = 0.0                  # CPU time spent on it [s]
    done: bool = False                  # converged: not worth continuing
    prior_iterations: int = 0           # iterations before ``history`` began (on the coarser grid)
    shipped: bool = False               # it began at a shipped design (or restarted from one that did)

    @property
    def objective(self) -> float:
        return self.history[-1] if self.history else np.inf


def _advance(problem: ExcitationProblem, start: _Start, until: int, deadline: float | None,
             report: Callable[[int, int, float], None]) -> _Start:
    """BFGS iterations of ``start`` (its BFGS matrix kept) until it has run ``until`` in all, converged
    or reached ``deadline``; a failed line search is retried once from a fresh matrix."""
    s = problem.settings
    cpu = time.process_time()
    history = list(start.history)
    x, hess_inv, evaluations, reason, gnorm = start.x, start.hess_inv, start.evaluations, "iterations", np.inf
    limit = until
    retried = False
    while len(history) < limit:
        stop = [""]

        def callback(intermediate_result: scipy.optimize.OptimizeResult) -> None:
            history.append(float(intermediate_result.fun))
            if len(history) % _REPORT_EVERY == 0:
                report(start.key, len(history), history[-1])
            if len(history) > s.window and history[-s.window - 1] - history[-1] < s.tolerance:
                stop[0] = "converged"
            elif deadline is not None and time.monotonic() > deadline:
                stop[0] = "budget"
            if stop[0]:
                raise StopIteration

        options = {"maxiter": limit - len(history), "gtol": _GRADIENT_TOL}
        if hess_inv is not None:
            options["hess_inv0"] = hess_inv
        before = len(history)
        res = scipy.optimize.minimize(problem.value_and_gradient, x.ravel(), jac=True, method="BFGS",
                                      callback=callback, options=options)
        evaluations += int(res.nfev)
        x, gnorm = res.x.reshape(x.shape), float(np.linalg.norm(res.jac))
        hess_inv = _positive_definite(res.hess_inv)
        if stop[0]:
            reason = stop[0]
            break
        if res.status == 0:
            reason = "gradient"
            break
        if res.status == 2:  # precision loss in the line search: once more from a fresh BFGS matrix
            if retried or len(history) == before:
                reason = "line search"
                break
            retried, hess_inv = True, None
            continue
        reason = "iterations"
        break
    return replace(start, x=x, hess_inv=hess_inv, history=tuple(history), reason=reason, gradient_norm=gnorm,
                   evaluations=evaluations, cpu_s=start.cpu_s + time.process_time() - cpu,
                   done=reason in ("converged", "gradient", "line search", "budget"))


def _positive_definite(matrix: np.ndarray) -> np.ndarray | None:
    """BFGS's inverse Hessian, symmetrised, if it is positive definite (else start afresh)."""
    sym = 0.5 * (matrix + matrix.T)
    try:
        np.linalg.cholesky(sym)
    except np.linalg.LinAlgError:
        return None
    return sym


# -- worker processes -----------------------------------------------------------------------------
_WORKER: dict = {}


def _init_worker(spec, settings, base, payload, queue) -> None:
    _WORKER["problems"] = _problems(spec, settings, base, payload)
    _WORKER["queue"] = queue


def _problems(spec, settings, base, payload) -> dict[bool, ExcitationProblem]:
    """The search's problem (False) and the polish's on ``polish_samples`` (True)."""
    problem = ExcitationProblem(spec, settings, base, payload)
    fine = problem
    if settings.polish:  # its own grid and tolerance
        fine = ExcitationProblem(spec, replace(settings, criterion_samples=settings.samples("polish"),
                                               tolerance=settings.polish_tolerance), problem.base, payload)
    return {False: problem, True: fine}


def _advance_in_worker(start: _Start, until: int, deadline: float | None, polish: bool) -> _Start:
    queue = _WORKER["queue"]
    with one_blas_thread():
        return _advance(_WORKER["problems"][polish], start, until, deadline,
                        lambda key, it, value: queue.put((key, it, value)))


class _Runner:
    """Runs :func:`_advance` on many starts, in worker processes or in this one."""

    def __init__(self, problems: dict[bool, ExcitationProblem], payload, workers: int, progress: Progress,
                 show: Callable[[float], str]):
        self.problems, self.progress, self.show = problems, progress, show
        problem = problems[False]
        self.latest: dict[int, tuple[int, float]] = {}
        self.pool = self.queue = None
        if workers >= 1:
            import multiprocessing

            context = multiprocessing.get_context("spawn")
            self.queue = context.Queue()
            self.pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_init_worker,
                                            initargs=(problem.spec, problem.settings, problem.base, payload, self.queue))

    def report(self, key: int, iteration: int, value: float) -> None:
        self.latest[key] = (iteration, value)
        best = min(v for _, v in self.latest.values())
        iterations = sum(i for i, _ in self.latest.values())
        self.progress.done = iterations
        self.progress.advance(0, f"iterations, best {self.show(best)}")

    def run(self, starts: list[_Start], until: int, deadline: float | None, polish: bool = False) -> list[_Start]:
        """Advance each start until its ``history`` has ``until`` iterations (on the polish's problem)."""
        if self.pool is None:
            return [_advance(self.problems[polish], s, until, deadline, self.report) for s in starts]
        futures: list[Future] = [self.pool.submit(_advance_in_worker, s, until, deadline, polish) for s in starts]
        pending = set(futures)
        while pending:
            _, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            self._drain()
        self._drain()
        return [f.result() for f in futures]

    def _drain(self) -> None:
        import queue as queue_module

        while True:
            try:
                self.report(*self.queue.get_nowait())
            except queue_module.Empty:
                return

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(cancel_futures=True)
            self.queue.close()


def optimize_excitation(spec: RobotSpec, settings: ExcitationSettings | None = None,
                        progress: Callable[[str], None] | None = None,
                        base: BaseParameters | None = None, payload=None) -> ExcitationResult:
    """Optimise an excitation trajectory for ``spec``; reproducible for a given ``settings.seed``
    (unless ``settings.budget_s`` stops it). ``payload`` (:class:`urident.model.payload.Payload`):
    the torque limits hold with it too. ``progress`` gets a message after each stage, and with it a
    progress line is written to a terminal's stderr while the starts run. The starts run in spawned
    processes: a script calling this needs the ``if __name__ == "__main__":`` guard."""
    with one_blas_thread():  # this process's share too (see Method above)
        return _optimize(spec, settings, progress, base, payload)


def _optimize(spec: RobotSpec, settings: ExcitationSettings | None, progress: Callable[[str], None] | None,
              base: BaseParameters | None, payload) -> ExcitationResult:
    settings = (ExcitationSettings() if settings is None else settings).resolved(spec.controller_rate_hz)
    say = progress or (lambda message: None)
    start_time, cpu_start = time.perf_counter(), time.process_time()
    deadline = None if settings.budget_s is None else time.monotonic() + settings.budget_s
    problems = _problems(spec, settings, base, payload)
    problem, fine = problems[False], problems[True]
    rng = np.random.default_rng(settings.seed)

    candidates = problem.shrink_to_collision_free(problem.random_coefficients(rng, settings.candidates))
    shipped = starts_for(spec.name, settings.harmonics) if _uses_library(settings) else ()
    # a design is written at the clearance itself: shrunk only where it is inside it (other margins)
    shipped = (problem.shrink_to_collision_free(problem.project(shipped), buffer=False) if len(shipped)
               else np.empty((0, *candidates.shape[1:])))
    candidates = np.concatenate([shipped, candidates])
    crit, coll, torque = problem.objective(candidates)
    scores = crit + PENALTY_WEIGHT * (coll + torque)
    order = np.argsort(scores, kind="stable")[: settings.starts]
    say(f"{settings.candidates} random feasible candidates"
        + (f" and {len(shipped)} shipped designs (best {_show(settings, crit[:len(shipped)].min())})"
           if len(shipped) else "") + f": best criterion {_show(settings, crit[order[0]])}")
    starts = [_Start(k, candidates[c], shipped=bool(c < len(shipped))) for k, c in enumerate(order)]
    workers = settings.workers
    if workers is None:  # one start: not worth a process's start-up (≈ 2 s)
        workers = min(MAX_WORKERS, os.cpu_count() or 1) if len(starts) > 1 else 0
    workers = min(workers, len(starts))
    with Progress("urident excite: BFGS") as line:
        line.enabled = line.enabled and progress is not None
        runner = _Runner(problems, payload, workers, line, lambda v: _show(settings, v))
        try:
            screen = min(settings.screen_iterations, settings.iterations)
            if len(starts) > settings.finalists and screen > 0:
                starts = runner.run(starts, screen, deadline)
                ranked = sorted(starts, key=lambda s: s.objective)
                say(f"{len(starts)} starts after {screen} iterations: best {_show(settings, ranked[0].objective)}, "
                    f"worst {_show(settings, ranked[-1].objective)}; continuing the best {settings.finalists} "
                    f"({time.perf_counter() - start_time:.1f} s)")
                finalists = ranked[: settings.finalists]
            else:
                finalists = starts
            going = [s for s in finalists if not s.done]
            if going:
                ended = {s.key: s for s in runner.run(going, settings.iterations, deadline)}
                finalists = [ended.get(s.key, s) for s in finalists]
                starts = [ended.get(s.key, s) for s in starts]
            best = min(finalists, key=lambda s: s.objective)
            rng = np.random.default_rng(settings.seed + _HOP_SEED_OFFSET)  # its own: the candidates stay
            rounds = settings.hop_rounds if settings.hops and settings.starts > 1 else 0  # a single start: alone
            for round_ in range(rounds):
                if ((deadline is not None and time.monotonic() >= deadline)
                        or sum(s.evaluations for s in starts) >= settings.hop_evaluations):
                    break
                hops = runner.run(_hops(problem, settings, best, len(starts), rng), settings.iterations, deadline)
                say(f"perturbed restarts of the best, round {round_ + 1}: "
                    f"{', '.join(_show(settings, h.objective) for h in hops)}")
                finalists, starts = finalists + hops, starts + hops
                best = min([best] + hops, key=lambda s: s.objective)
            if settings.polish and (deadline is None or time.monotonic() < deadline):
                # at most min(polish_iterations, iterations) more, on the finer grid, to polish_tolerance
                chosen = sorted(finalists, key=lambda s: s.objective)[: settings.polish]
                ended = {s.key: s for s in runner.run(
                    [replace(s, history=(), reason="", done=False, prior_iterations=s.prior_iterations + len(s.history))
                     for s in chosen], min(settings.polish_iterations, settings.iterations), deadline, polish=True)}
                say(f"the best {len(chosen)} polished on {settings.samples('polish')} criterion samples: "
                    f"{', '.join(_show(settings, s.objective) for s in ended.values())}")
                finalists = [ended.get(s.key, s) for s in finalists]
                starts = [ended.get(s.key, s) for s in starts]
        finally:
            runner.close()

    # Best by objective (the penalty includes the buffer, so a tiny one is harmless) after
    # projecting onto the limits; then make it exactly feasible at the controller rate.
    results = []
    for s in finalists:  # on the polish's grid (the finer one)
        x = problem.project(s.x[None])
        c_val, coll_val, tau_val = (float(v[0]) for v in fine.objective(x))
        key, final, written = c_val + PENALTY_WEIGHT * (coll_val + tau_val), None, ""
        if settings.select == "finalised":
            # ranked as written: collision-free without the search's buffer (shrunk if need be)
            final = _finalise(problem, spec, x[0])
            c_fin, _, tau_fin = (float(v[0]) for v in fine.objective(final[2][None]))
            key, written = c_fin + PENALTY_WEIGHT * tau_fin, f" (as written {_show(settings, c_fin)})"
        results.append((key, s, x[0], final))
        say(f"start {s.key + 1}: {_show(settings, c_val)}, penalty {coll_val + tau_val:.3g}{written}, "
            + _convergence(settings, s).describe(settings.criterion))
    results.sort(key=lambda r: r[0])
    best = results[0][1]
    convergence = _convergence(settings, best)
    trajectory, min_distance, _ = results[0][3] or _finalise(problem, spec, results[0][2])
    t = sample_times(settings.duration_s, spec.controller_rate_hz)
    dense = evaluate_criteria(spec, problem.base, *trajectory.evaluate(t))
    coarse = evaluate_criteria(spec, problem.base, *trajectory.evaluate(fine.basis_criterion.t))
    payload_cond = None
    if settings.for_payload:
        from urident.ident.payload import payload_condition

        payload_cond = payload_condition(spec, *trajectory.evaluate(t))
    wall = time.perf_counter() - start_time
    say(f"done in {wall:.1f} s: cond(Θ̄_B) = {dense.cond_theta:.4g} at {spec.controller_rate_hz:g} Hz"
        + (" (from a shipped design)" if best.shipped else "") + ", "
        + (f"payload columns cond {payload_cond:.4g}, " if payload_cond is not None else "")
        + f"min distance {min_distance:.4f} m")
    return ExcitationResult(trajectory, dense, coarse, min_distance, wall,
                            sum(s.evaluations for s in starts), settings, problem.file_limits,
                            tuple(s.objective for s in starts), payload_cond, convergence,
                            time.process_time() - cpu_start + (sum(s.cpu_s for s in starts) if workers else 0.0),
                            len(shipped), best.shipped)


def _uses_library(settings: ExcitationSettings) -> bool:
    """Whether the arm's shipped designs join the candidates: ``library``, by default with seed 0 only
    (the designs are one basin; a validation trajectory from another seed must differ from them)."""
    chosen = settings.seed == 0 if settings.library is None else settings.library
    return chosen and not settings.for_payload


def _hops(problem: ExcitationProblem, settings: ExcitationSettings, best: _Start, first_key: int,
          rng: np.random.Generator) -> list[_Start]:
    """``settings.hops`` new starts from ``best``, each coefficient scaled by 1 + ``hop_scale``·N(0, 1),
    then projected onto the limits and shrunk until collision-free."""
    x = best.x * (1.0 + settings.hop_scale * rng.standard_normal((settings.hops, *best.x.shape)))
    x = problem.shrink_to_collision_free(problem.project(x))
    return [_Start(first_key + i, x[i], shipped=best.shipped) for i in range(settings.hops)]


def _convergence(settings: ExcitationSettings, start: _Start) -> Convergence:
    h = start.history
    improvement = h[-settings.window - 1] - h[-1] if len(h) > settings.window else float("nan")
    return Convergence(start.prior_iterations + len(h), start.reason, start.gradient_norm, improvement,
                       settings.window)


def _finalise(problem: ExcitationProblem, spec: RobotSpec,
              x: np.ndarray) -> tuple[FourierTrajectory, float, np.ndarray]:
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
            return trajectory, float(d.min()), x * shrink
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
