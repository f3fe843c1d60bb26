"""Control-loop timing: ur_rtde's bare servo loop vs ``urident run``, both at 500 Hz against
urident's simulated controller (UR5e) on loopback.

1. bare: ``t = initPeriod(); servoJ(q, …); waitPeriod(t)`` and nothing else, holding a pose,
   with the same real-time scheduling urident gives its loop when the OS allows it;
2. urident: ``urident run`` of experiments/ur5e_ident.yaml, repeated to the same length, with monitors, the recorder
   (every controller sample to the log) and live streaming to a .rrd file on.

For each: the fraction of late cycles (a period longer than 2 ms + 0.5 ms) and the p50 / p99 /
max of |period − 2 ms|, measured the same way (perf_counter at each initPeriod). Target: urident
adds under 10 % to the bare loop's p99 and misses no deadline the bare loop does not.

    python benchmarks/loop_timing.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

HOST = "127.0.0.8"
EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"
PERIOD = 0.002
TOLERANCE = 0.0005

BARE_LOOP = textwrap.dedent("""
    import json, os, sys, time
    import numpy as np
    try:  # the same scheduling urident's control loop uses, for a fair comparison
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
    except (AttributeError, OSError):
        pass
    import rtde_control, rtde_receive
    host, seconds = sys.argv[1], float(sys.argv[2])
    c = rtde_control.RTDEControlInterface(host, 500.0)
    r = rtde_receive.RTDEReceiveInterface(host, 500.0)
    q = r.getActualQ()
    n = int(seconds * 500)
    stamps = np.empty(n)
    try:
        for k in range(n):
            t = c.initPeriod()
            stamps[k] = time.perf_counter()
            c.servoJ(q, 0.0, 0.0, 0.002, 0.1, 300.0)
            c.waitPeriod(t)
    finally:
        c.servoStop(); c.stopScript(); c.disconnect(); r.disconnect()
    print(json.dumps(np.diff(stamps).tolist()))
""")


def summary(periods: np.ndarray) -> dict[str, float]:
    errors = np.abs(periods - PERIOD)
    return {"late_cycle_pct": float(100 * np.mean(periods > PERIOD + TOLERANCE)),
            "late_cycles": int(np.sum(periods > PERIOD + TOLERANCE)),
            "p50_us": float(np.percentile(errors, 50) * 1e6),
            "p99_us": float(np.percentile(errors, 99) * 1e6),
            "max_us": float(errors.max() * 1e6), "cycles": int(len(periods))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    from urident.excitation import load_trajectory
    from urident.logs import load_log
    from urident.simcontroller.process import SimControllerProcess

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        with SimControllerProcess(host=HOST, robot="ur5e"):
            out = subprocess.run([sys.executable, "-c", BARE_LOOP, HOST, str(args.seconds)],
                                 capture_output=True, text=True, check=True)
        bare = summary(np.array(json.loads(out.stdout.strip().splitlines()[-1])))

        # The shipped UR5e identification trajectory (20 s), repeated to last args.seconds.
        traj = EXPERIMENTS / "ur5e_ident.yaml"
        repeat = max(1, round(args.seconds / load_trajectory(traj).trajectory.duration))
        config = tmp / "config.yaml"
        config.write_text("monitors:\n  max_late_fraction: 1.0\n  max_consecutive_late: 1000000\nrest_s: 0.0\n")
        log = tmp / "run.csv"
        start = load_trajectory(traj).trajectory.q_start + 0.02
        with SimControllerProcess(host=HOST, robot="ur5e", initial_q=start):
            subprocess.run([sys.executable, "-m", "urident.cli.main", "run", "--robot", "ur5e", "--host", HOST,
                            "--trajectory", str(traj), "--out", str(log), "--config", str(config), "--yes",
                            "--save", str(tmp / "run.rrd"), "--record-periods", "--repeat", str(repeat)],
                           check=True, capture_output=True, text=True)
        periods = np.load(log.with_suffix(".periods.npy"))
        ours = summary(periods)
        recorded = load_log(log)
        ours["log_missed_samples"] = int(recorded.metadata["extra"]["recorder"]["missed_samples"])

    result = {"bare": bare, "urident": ours,
              "p99_overhead_pct": 100.0 * (ours["p99_us"] - bare["p99_us"]) / bare["p99_us"],
              "extra_late_cycles": ours["late_cycles"] - bare["late_cycles"],
              "seconds": args.seconds}
    for name in ("bare", "urident"):
        r = result[name]
        print(f"{name:>8}: late {r['late_cycle_pct']:.3f} % ({r['late_cycles']} of {r['cycles']}), |period error| "
              f"p50 {r['p50_us']:.1f} µs, p99 {r['p99_us']:.1f} µs, max {r['max_us']:.0f} µs")
    print(f"p99 overhead: {result['p99_overhead_pct']:+.1f} %; extra late cycles: {result['extra_late_cycles']}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
