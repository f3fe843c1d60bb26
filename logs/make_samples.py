"""Regenerate the sample log pair of this folder (used by the README's post-hoc examples).

Offline simulation of the shipped UR5 identification and validation trajectories at the CB3's
125 Hz with the ``realistic`` preset of unmodelled effects, then rewritten with only the fields
post-hoc analysis needs (time, q, q̇, currents, temperatures) to keep them small. The simulation's ground truth is dropped from the sidecars, as a real log would have none.

    python logs/make_samples.py

The shipped sample_*.csv were made from the UR5 pair before its regeneration on 2026-12-03 (issue 33);
made from the current pair, tests/test_sim_gap.py's drive-term recovery on them misses its 10 % on
joint 1's damping (5.89 against 5.0 N·m·s/rad), so they are not replaced yet.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from urident.excitation import load_trajectory
from urident.logs import LogWriter, load_log
from urident.simcontroller.offline import simulate

HERE = Path(__file__).resolve().parent
EXPERIMENTS = HERE.parent / "experiments"
FIELDS = ["timestamp", "actual_q", "actual_qd", "actual_current", "joint_temperatures"]
COLUMNS = {"timestamp": "t", "actual_q": "q", "actual_qd": "qd", "actual_current": "current",
           "joint_temperatures": "temperature"}


def main() -> None:
    for kind, seed in (("ident", 1), ("valid", 2)):
        trajectory_path = EXPERIMENTS / f"ur5_{kind}.yaml"
        trajectory = load_trajectory(trajectory_path)
        with tempfile.TemporaryDirectory() as tmp:
            full = Path(tmp) / "full.csv"
            simulate(trajectory.spec, trajectory.trajectory, 125.0, "realistic", seed=seed, out=full,
                     trajectory_file=trajectory_path)
            rec = load_log(full)
        keep = {k: rec.metadata[k] for k in ("robot", "controller_version", "rate_hz", "gear_ratios",
                                             "torque_constants", "start_time") if rec.metadata.get(k)}
        keep["trajectory_file"] = f"experiments/ur5_{kind}.yaml"
        keep["trajectory_sha256"] = rec.metadata.get("trajectory_sha256")
        out = HERE / f"sample_{kind}.csv"
        with LogWriter(out, fields=FIELDS, metadata=keep, overwrite=True) as writer:
            for k in range(len(rec.t)):
                writer.append({name: getattr(rec, attr)[k] for name, attr in COLUMNS.items()})
            writer.close(status="completed", extra={"source": "urident simulate, realistic effects, "
                                                              f"seed {seed} (logs/make_samples.py)"})
        print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB, {len(rec.t)} samples)")


if __name__ == "__main__":
    main()
