"""Identify a UR10e from another lab's CSV logs and validate it on a run it never saw.

The shared recordings of a real UR10e (github.com/shamilmamedov/dynamic_calibration's format):
an identification run (30 s, 12 harmonics) and a point-to-point validation run. Run from the
repository root:  python examples/identify_ur10e.py [DATA_DIR]
"""

import sys
import tempfile
from pathlib import Path

import urident as ur

data = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/ur10e-dynamic-calibration")

# Headerless CSVs: the column layout is a preset; rows select the motion (1-based, inclusive).
ident_log = ur.load_log(data / "ur-20_02_10-30sec_12harm.csv", robot="ur10e",
                        format="dynamic_calibration", rows=(635, 3510))
valid_log = ur.load_log(data / "ur-20_01_17-ptp_10_points.csv", robot="ur10e",
                        format="dynamic_calibration", rows=(700, 4200))
print(f"identification run: {len(ident_log.t)} samples at {ident_log.rate_hz:g} Hz")

# The paper's method (OLS) and urident's preset for real arms, side by side.
for preset in ("paper", "real-robot"):
    ident = ur.identify([ident_log], robot="ur10e", method="ols", preset=preset)
    check = ur.validate(ident, [valid_log])
    rms = " ".join(f"{v:.2f}" for v in check.rms_nm)
    print(f"{preset:<10} {len(ident.parameters())} base parameters; validation e_N "
          f"{check.e_n:.4f}, RMS per joint [N·m] {rms}")

# Arrays for a plot of your own: t (N,), measured and predicted torques (N, 6), SI units.
print("torque arrays:", check.tau_measured.shape, check.tau_predicted.shape)
with tempfile.TemporaryDirectory() as out:  # a parameters file, as `urident identify --out` writes
    print("wrote", ", ".join(p.name for p in ident.save(Path(out) / "ur10e.yaml")))
