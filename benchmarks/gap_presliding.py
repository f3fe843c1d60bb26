"""Measurement (issue 21): would a presliding (Dahl) candidate explain the UR10e pair's standstill
residual? Not part of the catalogue or of the selection.

On top of the findings of ``urident gap`` on the shared UR10e pair (identification rows 635-3510
of the 12-harmonic run, validation rows 700-4200 of the point-to-point run), one column per joint,
z − tanh(q̇/ε): the normalised Dahl state z (urident.ident.friction.dahl_state, driven by the
integrated velocity as in ``--preset real-robot``, presliding distance δ on a grid) minus the
baseline's tanh Coulomb state, fitted in identification mode and scored with the diagnosis' own
held-out tests. Prints per joint the best δ, the validation shrink and whether it is significant.

Usage: ``python benchmarks/gap_presliding.py [DATA_DIR]`` (default ../shared/data/ur10e-dynamic-calibration).
"""

import argparse
import sys

import numpy as np

import urident.cli.cmd_gap as cg
from urident.gap import candidates as C
from urident.gap import diagnose
from urident.gap.bootstrap import default_block_length
from urident.gap.significance import score_all
from urident.ident.friction import dahl_state, velocity_displacement
from urident.model import load_robot

DELTAS = (1e-4, 3e-4, 1e-3, 3e-3, 1e-2)   # presliding distance grid [rad]


def presliding(j: int, delta: float) -> C.Candidate:
    def build(ctx):
        z = dahl_state(velocity_displacement(ctx.t, ctx.qd, ctx.data.segment), delta, ctx.data.segment)
        return C._on_joint(ctx, j, [z[:, j] - ctx.sign()[:, j]])
    return C.Candidate("presliding", j, f"Dahl delta {delta:g} rad", "ident", ("z-tanh",), build)


def main(argv=None) -> int:
    d = (argv or sys.argv[1:] or ["../shared/data/ur10e-dynamic-calibration"])[0]
    ap = argparse.ArgumentParser()
    cg.register(ap.add_subparsers())
    args = ap.parse_args(["gap", "--robot", "ur10e", "--format", "dynamic_calibration", "--ident", "-", "--valid", "-"])
    spec = load_robot("ur10e")
    ident = cg._load_all([f"{d}/ur-20_02_10-30sec_12harm.csv"], args, (635, 3510), spec.name)
    valid = cg._load_all([f"{d}/ur-20_01_17-ptp_10_points.csv"], args, (700, 4200), spec.name)
    res = diagnose(ident, valid, spec)
    print(f"findings: {res.verdict}")
    block = default_block_length(res.valid.n, res.valid.data.sample_rate * res.config.block_s)
    scores = score_all(res.scorer, res.fit, [presliding(j, x) for j in range(6) for x in DELTAS], block, res.config)
    for j in range(6):
        s = max((s for s in scores if s.candidate.joint == j), key=lambda s: s.gain)
        print(f"joint {j + 1}: {s.candidate.variant}: shrink {s.shrink_pct:.1f} % on top of the findings, "
              f"held-out gain {s.gain:.3g} N·m² [{s.ci[0]:.3g}, {s.ci[1]:.3g}], significant {s.significant}, "
              f"coefficient {float(np.ravel(s.fit.coefficients()[s.candidate])[0]):.3g} N·m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
