"""Benchmark: wall time and peak memory of identify, validate and gap as the data grow.

A 20 s UR5e identification and validation log at 500 Hz are simulated once (``urident simulate``,
realistic effects); a size of M minutes passes the log 3·M times. Each command runs in its own
subprocess (``python -m urident.cli.main ...``); its peak RSS is the child's ``ru_maxrss`` from
``os.wait4``. Prints one line per command and size; the last line is one JSON object.

    python benchmarks/scale.py [--minutes 1,10,60] [--gap-minutes 1,10] [--commands identify,validate,gap]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
LOG_S = 20.0     # seconds per simulated log
RATE_HZ = 500.0


def measure(argv: list[str]) -> tuple[float, float, int, float]:
    """(wall s, peak RSS MB, exit code, CPU s) of ``urident argv`` in a subprocess."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "urident.cli.main", *argv], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    stderr = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        sys.stderr.write(stderr.decode(errors="replace")[-2000:])
    return wall, usage.ru_maxrss / 1024.0, proc.returncode, usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", default="1,10,60", help="sizes for identify and validate [min]")
    ap.add_argument("--gap-minutes", default="1,10", help="sizes for gap (each of ident and valid) [min]")
    ap.add_argument("--commands", default="identify,validate,gap")
    args = ap.parse_args()
    sizes = [float(x) for x in args.minutes.split(",") if x]
    gap_sizes = [float(x) for x in args.gap_minutes.split(",") if x]
    commands = args.commands.split(",")

    results = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in ("ident", "valid"):
            wall, rss, rc, _ = measure(["simulate", "--trajectory", str(REPO / f"experiments/ur5e_{name}.yaml"),
                                     "--out", str(tmp / name), "--effects", "realistic"])
            if rc:
                raise SystemExit(f"simulate failed ({rc})")
        params = tmp / "params.yaml"
        if measure(["identify", str(tmp / "ident.csv"), "--robot", "ur5e", "--out", str(params)])[2]:
            raise SystemExit("identify of one log failed")

        def logs(name: str, minutes: float) -> list[str]:
            return [str(tmp / f"{name}.csv")] * max(1, round(minutes * 60 / LOG_S))

        def row(command: str, minutes: float, argv: list[str], samples: int) -> None:
            wall, rss, rc, cpu = measure(argv)
            r = {"command": command, "minutes": minutes, "samples": samples, "wall_s": round(wall, 2),
                 "cpu_s": round(cpu, 2), "peak_rss_mb": round(rss, 1), "exit": rc}
            results.append(r)
            print(f"{command:9s} {minutes:5g} min  {samples:9d} samples  {wall:7.1f} s wall  {cpu:7.1f} s CPU  "
                  f"{rss:7.0f} MB"
                  + ("" if rc == 0 else f"  exit {rc}"), flush=True)

        per_log = int(LOG_S * RATE_HZ) + 1
        for minutes in sizes:
            files = logs("ident", minutes)
            if "identify" in commands:
                row("identify", minutes, ["identify", *files, "--robot", "ur5e", "--out", str(tmp / "p.yaml"),
                                          "--overwrite"], per_log * len(files))
            if "validate" in commands:
                files = logs("valid", minutes)
                row("validate", minutes, ["validate", *files, "--params", str(params)], per_log * len(files))
        if "gap" in commands:
            for minutes in gap_sizes:
                ident, valid = logs("ident", minutes), logs("valid", minutes)
                row("gap", minutes, ["gap", "--robot", "ur5e", "--ident", *ident, "--valid", *valid],
                    per_log * (len(ident) + len(valid)))

    growth = {}
    for command in sorted({r["command"] for r in results}):
        rs = sorted((r for r in results if r["command"] == command), key=lambda r: r["samples"])
        if len(rs) >= 2 and rs[-1]["samples"] > rs[0]["samples"]:
            growth[command] = round(1024 * (rs[-1]["peak_rss_mb"] - rs[0]["peak_rss_mb"])
                                    / (rs[-1]["samples"] - rs[0]["samples"]), 3)
            print(f"{command}: {growth[command]} kB per sample (between the smallest and largest size)")
    print(json.dumps({"benchmark": "scale", "results": results, "growth_kb_per_sample": growth}))


if __name__ == "__main__":
    main()
