"""Measurement (issue 21): how much of the UR10e pair's standstill residual does the presliding
(Dahl) candidate explain, per joint?

On top of the findings of ``urident gap`` on the shared UR10e pair (identification rows 635-3510
of the 12-harmonic run, validation rows 700-4200 of the point-to-point run), the diagnosis' own
``presliding`` candidate (urident.gap.candidates: z − tanh(q̇/ε), the normalised Dahl state driven
by the integrated velocity minus the baseline's tanh Coulomb state, presliding distance δ on its
grid) on each joint that has none yet, fitted in identification mode and scored with the
diagnosis' own held-out tests. Prints per joint the best δ, the validation shrink and whether it
is significant; the last line is one JSON object.

Usage: ``python benchmarks/gap_presliding.py [DATA_DIR]`` (default ../shared/data/ur10e-dynamic-calibration).
"""

import argparse
import json
import sys

import numpy as np

import urident.cli.cmd_gap as cg
from urident.gap import candidates as C
from urident.gap import diagnose
from urident.gap.bootstrap import default_block_length
from urident.gap.significance import score_all
from urident.model import load_robot


def main(argv=None) -> int:
    d = (argv or sys.argv[1:] or ["../shared/data/ur10e-dynamic-calibration"])[0]
    ap = argparse.ArgumentParser()
    cg.register(ap.add_subparsers())
    args = ap.parse_args(["gap", "--robot", "ur10e", "--format", "dynamic_calibration", "--ident", "-", "--valid", "-"])
    spec = load_robot("ur10e")
    ident = cg._load_all([f"{d}/ur-20_02_10-30sec_12harm.csv"], args, "635-3510", spec.name, "identification")
    valid = cg._load_all([f"{d}/ur-20_01_17-ptp_10_points.csv"], args, "700-4200", spec.name, "validation")
    res = diagnose(ident, valid, spec)
    print(f"findings: {res.verdict}")
    block = default_block_length(res.valid.n, res.valid.data.sample_rate * res.config.block_s)
    taken = {c.key for c in res.chosen()}
    pool = [C.presliding(j, x) for j in range(6) for x in C.PRESLIDING_DELTAS if ("presliding", j) not in taken]
    scores = score_all(res.scorer, res.fit, pool, block, res.config)
    out = {"findings": res.verdict, "joints": {}}
    for j in sorted({c.joint for c in pool}):
        s = max((s for s in scores if s.candidate.joint == j), key=lambda s: s.gain)
        coef = float(np.ravel(s.fit.coefficients()[s.candidate])[0])
        print(f"joint {j + 1}: {s.candidate.variant}: shrink {s.shrink_pct:.1f} % on top of the findings, "
              f"held-out gain {s.gain:.3g} N·m² [{s.ci[0]:.3g}, {s.ci[1]:.3g}], significant {s.significant}, "
              f"coefficient {coef:.3g} N·m")
        out["joints"][str(j + 1)] = {"delta_rad": s.candidate.settings["delta"], "shrink_pct": s.shrink_pct,
                                     "significant": bool(s.significant), "holding_friction_nm": coef}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
