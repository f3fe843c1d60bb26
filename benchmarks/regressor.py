"""Regressor speed: the stacked UR5 regressor Θ (6N × 78) for N = 10,000 random samples.

Prints µs per sample for urident's compiled kernel (the default: large batches are split over the
machine's cores, up to 4; also shown on one thread), its numpy fallback, and a Python
loop over Pinocchio's computeJointTorqueRegressor (rigid body only) for reference. Best of several
repetitions (the minimum is the least disturbed by other load). Last line: one JSON object.

    python benchmarks/regressor.py [--samples 10000] [--repeat 7]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
import pinocchio as pin

from urident.model import load_robot, regressor
from urident.model.pinocchio_model import build_model
from urident.model.regressor import kernel_available, kernel_threads


def best_time(fn, repeat: int) -> float:
    fn()
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    spec = load_robot("ur5")
    rng = np.random.default_rng(0)
    n = args.samples
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    qd = rng.uniform(-3, 3, (n, 6))
    qdd = rng.uniform(-10, 10, (n, 6))

    results = {}
    if kernel_available():
        results["us_per_sample"] = best_time(lambda: regressor(spec, q, qd, qdd, backend="c"), args.repeat) / n * 1e6
        results["threads"] = kernel_threads()
        os.environ["URIDENT_REGRESSOR_THREADS"] = "1"
        results["single_thread_us_per_sample"] = best_time(
            lambda: regressor(spec, q, qd, qdd, backend="c"), args.repeat) / n * 1e6
        del os.environ["URIDENT_REGRESSOR_THREADS"]
    results["numpy_us_per_sample"] = best_time(lambda: regressor(spec, q, qd, qdd, backend="numpy"), args.repeat) / n * 1e6
    results.setdefault("us_per_sample", results["numpy_us_per_sample"])

    model = build_model(spec)
    data = model.createData()
    m = min(n, 2000)

    def pinocchio_loop() -> None:
        for k in range(m):
            pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])

    results["pinocchio_loop_us_per_sample"] = best_time(pinocchio_loop, 3) / m * 1e6
    results["samples"] = n
    results["backend"] = "c" if kernel_available() else "numpy"
    for key, value in results.items():
        print(f"{key:>30}: {value:.3f}" if isinstance(value, float) else f"{key:>30}: {value}")
    print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in results.items()}))


if __name__ == "__main__":
    main()
