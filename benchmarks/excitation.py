"""Benchmark: optimise an identification trajectory (order 5, 20 s, the paper's reduced model) for one
robot (default UR5) and compare its condition number with random trajectories that satisfy the same
constraints.

Prints the wall time of the optimisation, the achieved cond(Θ̄_B) (columns scaled by reference RMS,
see urident.excitation.criteria; cond(Λ) is its square), and the median cond(Θ̄_B) of 1,000 random
feasible trajectories, all on the optimiser's criterion grid; the last line is one JSON object.

    python benchmarks/excitation.py [--robot ur5] [--seed 0] [--random 1000]
"""

from __future__ import annotations

import os

# One BLAS thread: the batched small products here gain nothing from threads, and on a shared
# 2-core machine OpenBLAS threads spinning against other processes cost far more than they give.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from urident.excitation.check import check_trajectory  # noqa: E402
from urident.excitation.optimize import (ExcitationSettings, optimize_excitation,  # noqa: E402
                                         random_feasible_criteria)
from urident.model import load_robot  # noqa: E402
from urident.model.base import base_parameters  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="ur5", help="robot name or robot file (default ur5)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--random", type=int, default=1000, help="random feasible trajectories")
    args = parser.parse_args()

    spec = load_robot(args.robot)
    settings = ExcitationSettings(harmonics=5, duration_s=20.0, reduced=True, seed=args.seed)
    start, cpu_start = time.perf_counter(), time.process_time()
    base = base_parameters(spec, reduced=True)
    result = optimize_excitation(spec, settings, base=base,
                                 progress=lambda m: print(f"  {m}", file=sys.stderr, flush=True))
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    load = os.getloadavg()[0]  # 1-minute load average at the end: how shared the CPU was
    report = check_trajectory(spec, result.trajectory, limits=result.limits)
    print(f"optimised {spec.name} trajectory (L = 5, 20 s, reduced model, {base.n_base} base parameters, "
          f"seed {args.seed}): {wall:.1f} s ({cpu:.1f} s CPU; host load average {load:.1f} "
          f"on {os.cpu_count()} cores)")
    print(f"  cond(Θ̄_B) = {result.coarse_criteria.cond_theta:.4g} on the {settings.criterion_samples}-sample "
          f"criterion grid, {result.criteria.cond_theta:.4g} at {spec.controller_rate_hz:g} Hz "
          f"(cond Λ = {result.criteria.cond_lambda:.4g}); dense check ok: {report.ok}, "
          f"min distance {report.min_distance_m:.4f} m")

    start = time.perf_counter()
    conds = random_feasible_criteria(spec, settings, args.random, seed=args.seed + 1, base=base)
    random_wall = time.perf_counter() - start
    median = float(np.median(conds))
    print(f"{args.random} random feasible trajectories ({random_wall:.1f} s): median cond(Θ̄_B) = {median:.4g} "
          f"(5 %: {np.percentile(conds, 5):.4g}, best: {conds.min():.4g}); optimised is "
          f"{median / result.coarse_criteria.cond_theta:.1f}x lower")
    print(json.dumps({"robot": spec.name, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                      "load_average": round(load, 2), "cond": round(result.coarse_criteria.cond_theta, 3),
                      "cond_dense": round(result.criteria.cond_theta, 3),
                      "random_median_cond": round(median, 3), "check_ok": report.ok}))


if __name__ == "__main__":
    main()
