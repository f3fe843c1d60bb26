"""Benchmark: the gap rule on bag-like stamp streams (tests/bag_timing.py's models of UR's ROS 2
driver: ros2_control's absolute-schedule loop under three wake-up latency models, symmetric
jitter, a 200 ppm clock drift, the recorder's receive times with DDS batching).

For each stream model and seed: gaps found on the jitter-only stream by the plain rule (every
interval > 1.5 median periods) and by urident.logs.gaps.find_gaps; then single messages and one
burst of messages deleted at random: periods found missing (of those deleted), losses left inside a
gap-free piece (must be 0: nothing is differentiated across them) and samples left out of pieces.
Then accelerations (urident.ident.preprocess.accelerations, 10 Hz) of a smooth q̇ sampled at the
jittered stamps, against the same filter on a uniform grid: with the stamps as time (what urident
does) and with a uniform time base assumed instead. The last line is one JSON object.

    python benchmarks/bag_jitter.py [--seeds 20] [--samples 30000]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

# the stamp models live with the tests that write them into bags (one place for both)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from bag_timing import control_loop_stamps, receive_times  # noqa: E402

from urident.ident.preprocess import accelerations  # noqa: E402
from urident.logs.gaps import GAP_FACTOR, find_gaps, nominal_period  # noqa: E402

PERIOD = 0.002  # UR e-Series, 500 Hz


def stream(model: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if model in ("rt_kernel", "generic_kernel", "overloaded"):
        return control_loop_stamps(n, PERIOD, rng, model)
    if model == "symmetric_15pct":
        jitter = rng.normal(0, 0.15 * PERIOD, n).clip(-0.45 * PERIOD, 0.45 * PERIOD)
        return 1.0 + PERIOD * np.arange(n) + jitter
    if model == "drift_200ppm":
        return control_loop_stamps(n, PERIOD * (1 + 200e-6), rng, "generic_kernel")
    if model == "receive_time_batched":
        return receive_times(control_loop_stamps(n, PERIOD, rng, "generic_kernel"), rng)
    raise ValueError(model)


def pieces(gaps, n):
    starts = [0] + [g.index if g.resume is None else g.resume for g in gaps]
    ends = [g.index for g in gaps] + [n]
    return [(a, b) for a, b in zip(starts, ends) if b > a]


def losses(t: np.ndarray, rng: np.random.Generator, singles: int = 5, burst: int = 20) -> dict:
    n = t.size
    single = rng.choice(np.arange(200, n - 200), singles, replace=False)
    start = int(rng.integers(200, n - 200 - burst))
    gone = np.unique(np.concatenate([single, np.arange(start, start + burst)]))
    kept = np.setdiff1d(np.arange(n), gone)
    t2 = t[kept]
    gaps = find_gaps(t2, nominal_period(t2))
    # a loss lies between kept samples i-1 and i where kept[i] - kept[i-1] > 1
    where = np.flatnonzero(np.diff(kept) > 1) + 1
    ps = pieces(gaps, t2.size)
    inside = sum(any(a <= i - 1 and i < b for a, b in ps) for i in where)
    return {"deleted": int(gone.size), "found_missing": int(sum(g.missing for g in gaps)),
            "inside_piece": int(inside), "left_out": int(t2.size - sum(b - a for a, b in ps))}


def acceleration_error(rng: np.random.Generator, n: int = 5000) -> dict:
    """RMS [rad/s²] of accelerations from q̇ sampled at jittered stamps, against the uniform-grid
    result, stamps as time vs a uniform time base."""
    t = control_loop_stamps(n, PERIOD, rng, "overloaded")
    f = np.array([0.3, 0.7, 1.1, 1.9, 2.3, 3.1])
    qd = lambda x: np.sin(2 * np.pi * f * (x[:, None] - 1.0))  # noqa: E731
    grid = t[0] + PERIOD * np.arange(n)
    ref = accelerations(grid, qd(grid))
    truth_at_t = np.column_stack([np.interp(t, grid, ref[:, j]) for j in range(6)])
    core = slice(200, n - 200)
    stamps = accelerations(t, qd(t))
    uniform = accelerations(grid, qd(t))       # the same samples, their time taken as k·T
    rms = lambda a, b: float(np.sqrt(np.mean((a[core] - b[core]) ** 2)))  # noqa: E731
    return {"stamps_as_time": rms(stamps, truth_at_t), "uniform_assumed": rms(uniform, truth_at_t)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--samples", type=int, default=30000)
    args = parser.parse_args()
    models = ["rt_kernel", "generic_kernel", "overloaded", "symmetric_15pct", "drift_200ppm",
              "receive_time_batched"]
    out = {}
    for model in models:
        row = {"plain_rule_gaps": 0, "gaps": 0, "deleted": 0, "found_missing": 0,
               "inside_piece": 0, "left_out": 0}
        for seed in range(args.seeds):
            rng = np.random.default_rng(seed)
            t = stream(model, args.samples, rng)
            dt = np.diff(t)
            row["plain_rule_gaps"] += int(np.sum(dt > GAP_FACTOR * np.median(dt)))
            row["gaps"] += len(find_gaps(t, nominal_period(t)))
            for k, v in losses(t, rng).items():
                row[k] += v
        print(f"{model:22s} jitter only: plain rule {row['plain_rule_gaps']:6d} gaps, urident "
              f"{row['gaps']} | deleted {row['deleted']}, found missing {row['found_missing']}, "
              f"losses inside a piece {row['inside_piece']}, samples left out {row['left_out']}")
        out[model] = row
    acc = acceleration_error(np.random.default_rng(0))
    print(f"accelerations, overloaded stamps: RMS error {acc['stamps_as_time']:.3g} rad/s² with "
          f"the stamps as time, {acc['uniform_assumed']:.3g} rad/s² assuming uniform sampling")
    print(json.dumps({"seeds": args.seeds, "samples": args.samples, "models": out,
                      "acceleration_rms": acc}))


if __name__ == "__main__":
    main()
