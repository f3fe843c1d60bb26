"""Benchmark: the simulated controller's real-time loop while ur_rtde servos it at 500 Hz.

Starts the simulated controller (UR5e, e-Series 500 Hz) as a child process, connects the unmodified
ur_rtde control and receive interfaces, moves to a start pose, then streams servoJ at 500 Hz with
initPeriod/waitPeriod for ``--seconds`` (default 60). Reports the controller's late-cycle fraction
(a cycle is late when its data leave more than half a period after the deadline), its CPU use, and
the client's view (command rate, timestamp gaps). Last line: one JSON object.

Host floor: on a virtual machine the hypervisor can hold a virtual CPU for milliseconds (CPU
steal), and no code running on it can be on time then. So that the controller's own share can be
told apart, a probe process runs alongside for the same time: a loop that does nothing but sleep
to a deadline every period, at the controller's priority, judged by the same rule (awake more than
half a period after its deadline = late). ``host_floor_late_pct`` is its late fraction and
``excess_late_pct`` the controller's minus it.

    python benchmarks/sim_controller.py --seconds 10
"""

from __future__ import annotations

import argparse
import json
import math
import time


def cpu_times() -> list[int]:
    """Aggregate /proc/stat CPU counters (user nice system idle iowait irq softirq steal ...)."""
    try:
        with open("/proc/stat") as f:
            return [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return []


def probe(seconds: float, period: float, out_path: str) -> int:
    """The host-floor probe: sleep to each deadline, count wake-ups later than half a period."""
    import os

    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
    except (AttributeError, OSError):
        pass
    clock = time.perf_counter
    deadline = clock() + period
    end = deadline + seconds
    cycles = late = 0
    worst = 0.0
    while deadline < end:
        remaining = deadline - clock()
        if remaining > 0:
            time.sleep(remaining)
        lateness = clock() - deadline
        cycles += 1
        late += lateness > 0.5 * period
        worst = max(worst, lateness)
        deadline += period
        if lateness > 50 * period:      # re-anchor like the controller does
            deadline = clock() + period
    with open(out_path, "w") as f:
        json.dump({"cycles": cycles, "late_cycles": late, "max_lateness_s": worst}, f)
    return 0


def start_probe(seconds: float, period: float):
    import subprocess
    import sys
    import tempfile

    out = tempfile.NamedTemporaryFile(prefix="urident-probe-", suffix=".json", delete=False)
    out.close()
    process = subprocess.Popen([sys.executable, __file__, "--probe", str(seconds), "--probe-out", out.name,
                                "--probe-period", str(period)])
    return process, out.name


def finish_probe(process, path: str) -> dict:
    import os

    process.wait(timeout=60)
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}
    finally:
        os.unlink(path)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="servoJ duration [s] (default 60)")
    parser.add_argument("--host", default="127.0.0.9", help="loopback address for the controller")
    parser.add_argument("--robot", default="ur5e")
    parser.add_argument("--probe", type=float, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--probe-out", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--probe-period", type=float, default=0.002, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.probe is not None:
        return probe(args.probe, args.probe_period, args.probe_out)

    import rtde_control
    import rtde_receive

    from urident.simcontroller.process import SimControllerProcess

    start_q = [0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0]
    with SimControllerProcess(host=args.host, robot=args.robot) as sim:
        control = rtde_control.RTDEControlInterface(sim.host)
        receive = rtde_receive.RTDEReceiveInterface(sim.host)
        control.moveJ(start_q, 1.0, 1.0)
        period = 0.002
        n = int(round(args.seconds / period))
        timestamps = []
        probe_process, probe_path = start_probe(args.seconds, period)
        stat_begin = cpu_times()
        t_begin = time.perf_counter()
        for k in range(n):
            t_cycle = control.initPeriod()
            phase = 2.0 * math.pi * 0.2 * k * period
            q = [start_q[j] + 0.3 * math.sin(phase + j) - 0.3 * math.sin(j) for j in range(6)]
            control.servoJ(q, 0.5, 0.5, period, 0.1, 300)
            if k % 10 == 0:
                timestamps.append(receive.getTimestamp())
            control.waitPeriod(t_cycle)
        elapsed = time.perf_counter() - t_begin
        stat_end = cpu_times()
        control.servoStop(10.0)
        control.stopScript()
        receive.disconnect()
        control.disconnect()
        floor = finish_probe(probe_process, probe_path)
    stats = sim.stats or {}
    floor_pct = 100.0 * floor["late_cycles"] / floor["cycles"] if floor.get("cycles") else float("nan")
    gaps = [b - a for a, b in zip(timestamps, timestamps[1:])]
    delta = [b - a for a, b in zip(stat_begin, stat_end)]
    machine_steal_pct = 100.0 * delta[7] / sum(delta) if len(delta) > 7 and sum(delta) else float("nan")
    machine_busy_pct = 100.0 * (1 - (delta[3] + delta[4]) / sum(delta)) if len(delta) > 4 and sum(delta) else float("nan")
    figures = {
        "seconds": args.seconds,
        "client_command_rate_hz": n / elapsed,
        "cycles": stats.get("cycles"),
        "late_cycles": stats.get("late_cycles"),
        "late_cycle_pct": stats.get("late_cycle_pct"),
        "late_wakeups": stats.get("late_wakeups"),
        "max_work_ms": 1000.0 * stats.get("max_work_s", float("nan")),
        "host_floor_late_pct": floor_pct,
        "excess_late_pct": stats.get("late_cycle_pct", float("nan")) - floor_pct,
        "host_floor_max_lateness_ms": 1000.0 * floor.get("max_lateness_s", float("nan")),
        "max_lateness_ms": 1000.0 * stats.get("max_lateness_s", float("nan")),
        "cpu_pct": stats.get("cpu_pct"),
        "resyncs": stats.get("resyncs"),
        "client_timestamp_gap_max_ms": 1000.0 * max(gaps) if gaps else None,
        "machine_busy_pct": machine_busy_pct,
        "machine_steal_pct": machine_steal_pct,
    }
    for key, value in figures.items():
        print(f"{key:32s} {value:.3f}" if isinstance(value, float) else f"{key:32s} {value}")
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in figures.items()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
