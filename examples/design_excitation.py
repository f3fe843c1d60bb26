"""Design an excitation trajectory, check it and write the file `urident run` executes.

Run from the repository root:  python examples/design_excitation.py [OUT.yaml]

A short search for the example (order 3, 8 s, one start, at most 40 iterations or 10 s);
`urident excite`'s defaults (order 5, 20 s, 8 starts until converged) take 10-30 s on two cores.
"""

import sys
import tempfile
from pathlib import Path

import urident as ur


def save_and_check(design, out: Path) -> None:
    design.save(out)  # its text is read back and checked before it is written
    report = ur.check_trajectory(out)  # what `urident check-trajectory` and `urident run` check
    print(f"wrote {out}; check-trajectory ok: {report.ok}")


def main() -> None:
    design = ur.design_excitation("ur5", harmonics=3, duration_s=8.0, reduced=True, seed=1,
                                  starts=1, iterations=40, budget_s=10.0)
    print(f"cond(Θ̄_B) = {design.cond:.4g} at {design.check.rate_hz:g} Hz "
          f"({design.criteria.n_base} base parameters)")
    print(f"search: {design.convergence.describe('cond')}")
    print(f"dense check ok: {design.check.ok}, min distance {design.check.min_distance_m:.3f} m "
          f"({design.check.min_distance_pair})")
    document = design.to_dict()  # the file's document: trajectory, limits, optimization, criteria, check
    print(f"search ended by {document['optimization']['stop_reason']} after "
          f"{document['optimization']['total_iterations']} iterations, {document['optimization']['wall_s']:.1f} s")
    if len(sys.argv) > 1:
        save_and_check(design, Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            save_and_check(design, Path(tmp) / "ident.yaml")


if __name__ == "__main__":  # the optimiser's starts run in spawned processes
    main()
