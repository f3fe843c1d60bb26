"""Benchmark: cross-file held-out accuracy on the real UR10e recordings.

Every model is identified on the shared identification run (``ur-20_02_10-30sec_12harm.csv`` rows
635-3510, the README's) and validated on every other free-motion recording of the arm, none of
which played a part in any choice:

* ``2019``: ``ur-19_09_27-11_32_02.csv`` (another year; 19 columns, its bad rows dropped as
  ``--drop-bad`` does: the 20 corrupt first rows);
* ``ptp``: the point-to-point run with stops, rows 700-4200 (the README's);
* ``unload``: the unloaded excitation run, its moving rows 199-2515;
* ``load``: the same motion with a tool of unstated mass, as ``urident payload`` handles it
  (``docs/how-to/payload.md``): the tool is identified on rows 345-1890 with each model's arm,
  and the arm plus tool validated on rows 1891-2662.

The push run (the arm held at rest while pushed) is not free motion and is left out. Prints one
line per model and file, the per-file and mean RMS [N·m]; the last line is one JSON object.

    python benchmarks/friction_heldout.py [--presets paper,ur10e-2020,auto] [--method consistent]
                                          [--min-t T] [--folds K]
"""

from __future__ import annotations

import argparse
import io
import json
import time
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "ur10e-dynamic-calibration"
IDENT = ("ur-20_02_10-30sec_12harm.csv", (635, 3510))
FILES = {   # label: (file, log options)
    "2019": ("ur-19_09_27-11_32_02.csv", {"format": "dynamic_calibration_19", "drop_bad": True}),
    "ptp": ("ur-20_01_17-ptp_10_points.csv", {"format": "dynamic_calibration", "rows": (700, 4200)}),
    "unload": ("ur-20_01_31-unload.csv", {"format": "dynamic_calibration", "rows": (199, 2515)}),
    "load": ("ur-20_01_31-load.csv", {"format": "dynamic_calibration", "rows": (1891, 2662)}),
}
LOAD_TOOL_ROWS = (345, 1890)


def held_out(data_dir: Path, models, method: str = "consistent", quiet: bool = False) -> dict:
    """Per model, RMS [N·m] per file and joint. ``models``: preset names, or label → keyword
    arguments of :func:`urident.identify` (``preset``, ``model``, ``weighting``)."""
    import urident as ur

    if not isinstance(models, dict):
        models = {p: {"preset": None if p == "paper" else p} for p in models}
    out = {}
    for preset, kwargs in models.items():
        t0 = time.process_time()
        with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
            ident = ur.identify([data_dir / IDENT[0]], "ur10e", method, **kwargs,
                                log_options={"format": "dynamic_calibration", "rows": IDENT[1]})
        row = {"identify_cpu_s": round(time.process_time() - t0, 1)}
        if ident.selection:
            row["selection"] = ident.selection
        for label, (name, options) in FILES.items():
            payload = None
            if label == "load":
                tool = ur.identify_payload([data_dir / name], ident, log_options={
                    "format": "dynamic_calibration", "rows": LOAD_TOOL_ROWS})
                payload = tool.payload
                row["tool_mass_kg"] = round(float(payload.mass_kg), 3)
            res = ur.validate(ident, [data_dir / name], payload=payload, log_options=options)
            row[label] = [round(float(v), 3) for v in res.rms_nm]
        row["mean_per_file"] = {k: round(float(np.mean(row[k])), 3) for k in FILES}
        row["mean"] = round(float(np.mean(list(row["mean_per_file"].values()))), 3)
        out[preset] = row
        if quiet:
            continue
        print(f"{preset:<10} " + "  ".join(f"{k} {v:.3f}" for k, v in row["mean_per_file"].items())
              + f"  mean {row['mean']:.3f}", flush=True)
        for k in FILES:
            print(f"    {k:<7}" + " ".join(f"{v:6.3f}" for v in row[k]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--presets", default="paper,ur10e-2020,auto")
    ap.add_argument("--method", default="consistent")
    ap.add_argument("--data", default=str(DATA))
    ap.add_argument("--min-t", type=float, help="auto's t threshold instead of friction_select.MIN_T (a variant)")
    ap.add_argument("--folds", type=int, help="auto's CV folds instead of presets.CV_FOLDS (a variant)")
    args = ap.parse_args()
    if args.min_t is not None:
        import urident.ident.friction_select as fs

        fs.MIN_T = args.min_t
    if args.folds is not None:
        import urident.ident.presets as presets

        presets.choose_on_data.__defaults__ = (args.folds,)
    models = held_out(Path(args.data), args.presets.split(","), args.method)
    out = {"method": args.method, "min_t": args.min_t, "folds": args.folds, "models": models,
           "mean_rms_nm": {k: v["mean"] for k, v in models.items()},
           "per_joint_mean_rms_nm": {k: [round(float(np.mean([v[f][j] for f in FILES])), 3) for j in range(6)]
                                     for k, v in models.items()}}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
