"""Benchmark: optimise an identification trajectory (order 5, 20 s) for one or more robots (default UR5),
for the paper's reduced model and the full one: the default settings (time, cond) against a long multi-start
run of the same optimiser with ten times its evaluations (its cond: the reference the default must come
within 5 % of), and against random trajectories that satisfy the same constraints.

Two runs of the default's search: with the arm's shipped designs among its candidates
(urident.excitation.library: the best of the long run's seeds, made once; each design records its
seed) and the search alone (random candidates only); `urident excite` uses the first with seed 0, the
second with any other seed. The long run starts from random candidates only, with --long-seed (default
--seed): on a seed none of the designs came from it is a held-out reference, on one of theirs it
repeats the search that made them.

Prints per model the default's wall and CPU time (this process and its worker processes), its
cond(Θ̄_B) on the optimiser's criterion grid (columns scaled by reference RMS, see
urident.excitation.criteria; cond(Λ) is its square) and at the controller rate, how its search ended,
the other run's, the long run's cond and the ratios (of the conds at the controller rate: the runs'
criterion grids differ), and the median cond(Θ̄_B) of random feasible trajectories; then one summary
line per robot and model, and last one JSON object. The machine is shared: the wall time depends on the
load (printed), the CPU time much less.

    python benchmarks/excitation.py [--robot ur5[,ur10e,...]] [--seed 1] [--long-seed 3]
                                    [--models reduced,full] [--random 1000] [--no-long]
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
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402

from urident.excitation.check import check_trajectory  # noqa: E402
from urident.excitation.library import LONG_SEARCH as LONG  # noqa: E402
from urident.excitation.optimize import (ExcitationSettings, optimize_excitation,  # noqa: E402
                                         random_feasible_criteria)
from urident.model import load_robot  # noqa: E402
from urident.model.base import base_parameters  # noqa: E402

def run(spec, settings, base, label: str) -> dict:
    start = time.perf_counter()
    result = optimize_excitation(spec, settings, base=base,
                                 progress=lambda m: print(f"  [{label}] {m}", file=sys.stderr, flush=True))
    wall = time.perf_counter() - start
    report = check_trajectory(spec, result.trajectory, limits=result.limits)
    c = result.convergence
    return {"cond": round(result.coarse_criteria.cond_theta, 3), "cond_dense": round(result.criteria.cond_theta, 3),
            "wall_s": round(wall, 2), "cpu_s": round(result.cpu_s, 2), "load_average": round(os.getloadavg()[0], 2),
            "check_ok": report.ok, "min_distance_m": round(report.min_distance_m, 4),
            "stop_reason": c.reason, "iterations": c.iterations, "evaluations": result.evaluations,
            "search": c.describe(settings.criterion), "shipped_designs": result.shipped_designs,
            "from_shipped": result.from_shipped}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="ur5",
                        help="robot name or robot file, or several separated by commas (default ur5)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--long-seed", type=int, default=None, help="the long run's seed (default --seed)")
    parser.add_argument("--models", default="reduced,full", help="reduced, full, or both (reduced,full; the default)")
    parser.add_argument("--random", type=int, default=1000, help="random feasible trajectories (0: none)")
    parser.add_argument("--no-long", action="store_true", help="skip the long reference run")
    args = parser.parse_args()

    models = ["reduced", "full"] if args.models == "both" else args.models.split(",")
    if not models or any(m not in ("reduced", "full") for m in models):
        parser.error(f"--models must be reduced, full, reduced,full or both, not {args.models!r}")
    specs = [load_robot(name) for name in args.robot.split(",")]
    if args.long_seed is None:
        args.long_seed = args.seed
    out = {"seed": args.seed, "long_seed": args.long_seed, "cores": os.cpu_count(), "robots": {}}
    summary = []
    for spec in specs:
        out["robots"][spec.name] = robot_out = {}
        for model in models:
            robot_out[model] = entry = bench(spec, model, args)
            d = entry["default"]
            line = (f"{spec.name} {model}: default cond(Θ̄_B) {d['cond_dense']:.4g} in {d['wall_s']:.1f} s wall, "
                    f"{d['cpu_s']:.1f} s CPU")
            line += (f" ({entry['default_is']}); with the designs {entry['designs']['cond_dense']:.4g}, the search "
                     f"alone {entry['alone']['cond_dense']:.4g}")
            if "long" in entry:
                line += (f"; long run {entry['long']['cond_dense']:.4g}; default / long = {entry['ratio']:.3f} "
                         f"(with the designs {entry['ratio_designs']:.3f}, alone {entry['ratio_alone']:.3f})")
            summary.append(line)
    print("summary (cond at the controller rate):")
    for line in summary:
        print("  " + line)
    print(json.dumps(out))


def bench(spec, model: str, args) -> dict:
    reduced = model == "reduced"
    base = base_parameters(spec, reduced=reduced)
    settings = ExcitationSettings(harmonics=5, duration_s=20.0, reduced=reduced, seed=args.seed)
    print(f"{spec.name} {model} model ({base.n_base} base parameters), L = 5, 20 s, seed {args.seed} (load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores):")
    entry = {"n_base": base.n_base}
    for key, library, what in (("designs", True, "with the shipped designs among the candidates"),
                               ("alone", False, "the search alone (random candidates only)")):
        entry[key] = r = run(spec, replace(settings, library=library), base, f"{spec.name} {model} {key}")
        print(f"  {what}: {r['wall_s']:.1f} s wall ({r['cpu_s']:.1f} s CPU), cond(Θ̄_B) = {r['cond']:.4g} "
              f"({r['cond_dense']:.4g} at {spec.controller_rate_hz:g} Hz), {r['evaluations']:,} evaluations, "
              f"{r['search']}" + (", began at a shipped design" if r["from_shipped"] else "")
              + f", dense check ok: {r['check_ok']}")
    # what `urident excite --seed S` does: the shipped designs with seed 0 only
    entry["default_is"] = "designs" if args.seed == 0 else "alone"
    entry["default"] = d = entry[entry["default_is"]]
    print(f"  the default (urident excite --seed {args.seed}) is the {entry['default_is']} run")
    if not args.no_long:
        entry["long"] = long = run(spec, replace(settings, library=False, seed=args.long_seed, **LONG), base,
                                   f"{spec.name} {model} long")
        for key in ("designs", "alone"):
            entry[f"ratio_{key}"] = round(entry[key]["cond_dense"] / long["cond_dense"], 4)
        entry["ratio"] = entry[f"ratio_{entry['default_is']}"]
        print(f"  long run (seed {args.long_seed}, {LONG['candidates']} candidates, {LONG['starts']} starts, {LONG['finalists']} continued, "
              f"up to {LONG['hop_rounds']} restart rounds below {LONG['hop_evaluations']:,} evaluations, random "
              f"candidates only): cond(Θ̄_B) = {long['cond']:.4g} ({long['cond_dense']:.4g} at "
              f"{spec.controller_rate_hz:g} Hz), {long['evaluations']:,} evaluations, {long['wall_s']:.1f} s wall "
              f"({long['cpu_s']:.1f} s CPU); with the designs / long = {entry['ratio_designs']:.3f}, the search "
              f"alone / long = {entry['ratio_alone']:.3f} (at {spec.controller_rate_hz:g} Hz)")
    if args.random:
        start = time.perf_counter()
        conds = random_feasible_criteria(spec, replace(settings, criterion_samples=100), args.random,
                                         seed=args.seed + 1, base=base)
        median = float(np.median(conds))
        entry["random_median_cond"] = round(median, 3)
        print(f"  {args.random} random feasible trajectories ({time.perf_counter() - start:.1f} s): median "
              f"cond(Θ̄_B) = {median:.4g} (best {conds.min():.4g}); the default is {median / d['cond_dense']:.1f}x "
              f"lower at {spec.controller_rate_hz:g} Hz")
    return entry


if __name__ == "__main__":
    main()
