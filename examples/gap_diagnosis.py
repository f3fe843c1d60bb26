"""Diagnose the sim-to-real gap: where the residual lies and which unmodelled effect explains it.

Run from the repository root:  python examples/gap_diagnosis.py
"""

import json

import urident as ur

gap = ur.diagnose_gap(["logs/sample_ident.csv"], ["logs/sample_valid.csv"], robot="ur5")
document = gap.to_dict()  # what `urident gap --json-out` writes
base, final = document["baseline"], document["final"]
print(f"baseline e_N {base['e_n']:.4f} -> {final['e_n']:.4f} with the effects found")
for finding in document["findings"]:
    print(f"  joint {finding['joint']}: {finding['effect']} "
          f"({finding['shrink_pct']:.1f} % smaller RMS on that joint)")
if not document["findings"]:
    print("  no unmodelled effect found")
json.dumps(document)  # plain JSON: numbers, strings, lists
