"""Benchmark: a 20 s, 500 Hz synthetic log (UR5, multi-sine, joint_torques + current noise) written
with LogWriter, then load → preprocess → identify → validate, per method. Prints the wall time per
method; the last line is one JSON object.

    python benchmarks/identify.py [--robot ur5] [--duration 20] [--rate 500]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robot", default="ur5")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--rate", type=float, default=500.0)
    args = ap.parse_args()

    from urident.ident import identify, prepare, validate
    from urident.ident.design import base_for
    from urident.ident.synthetic import synthetic_recording
    from urident.logs import LogWriter, load_log
    from urident.model import load_robot

    spec = load_robot(args.robot)
    base_for(spec, False)  # base-parameter structure: computed once per robot, cached
    rec, _, _ = synthetic_recording(spec, args.duration, args.rate, current_noise_a=0.03, seed=1)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.csv"
        with LogWriter(path, fields=["timestamp", "actual_q", "actual_qd", "actual_current"],
                       metadata={"robot": spec.name, "rate_hz": args.rate}) as w:
            for k in range(len(rec)):
                w.append_sample(float(rec.t[k]), q=rec.q[k], qd=rec.qd[k], current=rec.current[k])
        t0 = time.perf_counter()
        loaded = load_log(path)
        t_load = time.perf_counter() - t0
    out = {"robot": spec.name, "samples": len(rec), "load_s": round(t_load, 3)}
    for method in ("ols", "bounded", "consistent"):
        t0 = time.perf_counter()
        data = prepare([loaded], spec)
        model = identify(spec, data, method)
        res = validate(model, spec, data)
        dt = time.perf_counter() - t0
        out[f"{method}_s"] = round(dt, 3)
        out[f"{method}_mean_rms_nm"] = round(float(np.mean(res.rms_nm)), 4)
        print(f"{method:10s} {dt:7.3f} s  (preprocess + identify + validate), e_N {res.e_n:.5f}, "
              f"mean RMS {res.mean_rms_nm:.3f} N·m")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
