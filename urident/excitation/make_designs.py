"""Remake the shipped excitation designs (:mod:`urident.excitation.library`): for each arm and model
given, the long search (:data:`~urident.excitation.library.LONG_SEARCH`, the default settings,
without the shipped designs) with each seed given; the lowest cond(Θ̄_B) is kept, against the shipped
design re-checked on today's robot file unless ``--replace``, and written as each pair ends (about
2 min per search on a 2-core machine).

    python -m urident.excitation.make_designs [--robots ur5e,ur10e] [--models reduced,full] [--seeds 0,1,2] [--replace] [--file F]
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import sys
from pathlib import Path

from urident.errors import ConfigError
from urident.excitation.check import check_trajectory
from urident.excitation.constraints import Limits, Margins
from urident.excitation.criteria import evaluate_criteria
from urident.excitation.fourier import free_coefficients, sample_times
from urident.excitation.library import (LIBRARY_FILE, LONG_SEARCH, MODELS, Design, design_trajectory, load_designs,
                                        write_designs)
from urident.excitation.optimize import ExcitationSettings, optimize_excitation
from urident.model import available_robots, load_robot
from urident.model.base import base_parameters


def make_design(robot: str, reduced: bool, seed: int = 0, progress=None) -> Design:
    """The long search (:data:`LONG_SEARCH`, default settings, no shipped designs) for one arm,
    model and seed."""
    settings = ExcitationSettings(reduced=reduced, seed=seed, library=False, **LONG_SEARCH)
    result = optimize_excitation(load_robot(robot), settings, progress=progress)
    return Design(robot, reduced, settings.harmonics, settings.duration_s, settings.q0, float(result.criteria.cond_theta),
                  free_coefficients(result.trajectory), datetime.date.today().isoformat(), seed)


def design_cond(design: Design) -> float:
    """The design's cond(Θ̄_B) at its arm's controller rate on today's robot file."""
    spec = load_robot(design.robot)
    t = sample_times(design.duration_s, spec.controller_rate_hz)
    return float(evaluate_criteria(spec, base_parameters(spec, reduced=design.reduced),
                                   *design_trajectory(design).evaluate(t)).cond_theta)


def recheck(design: Design) -> Design | None:
    """The shipped design with its cond on today's robot file, or None where it no longer passes the
    dense check under the default margins (it can then not compete with new searches)."""
    spec = load_robot(design.robot)
    report = check_trajectory(spec, design_trajectory(design), limits=Limits.from_robot(spec, Margins()),
                              collision_backend="numpy")
    return dataclasses.replace(design, cond_theta=design_cond(design)) if report.ok else None


def _ints(text: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m urident.excitation.make_designs", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", default=",".join(available_robots()), help="comma-separated arms (default: every one)")
    parser.add_argument("--models", default="reduced,full", help="reduced, full or both (default both)")
    parser.add_argument("--seeds", type=_ints, default=[0, 1, 2], help="the long search's seeds (default 0,1,2)")
    parser.add_argument("--replace", action="store_true", help="drop the shipped design instead of keeping it where it is better")
    parser.add_argument("--file", type=Path, default=LIBRARY_FILE, help="the designs file to update (default the shipped one)")
    args = parser.parse_args(argv)
    robots, models = args.robots.split(","), args.models.split(",")
    unknown = [m for m in models if m not in MODELS] + [r for r in robots if r not in available_robots()]
    if unknown:
        parser.error(f"unknown robot or model: {', '.join(unknown)}")
    try:
        current = {(d.robot, d.reduced): d for d in load_designs(args.file)} if args.file.exists() else {}
    except ConfigError as exc:
        parser.error(str(exc))
    for robot in robots:
        for model in models:
            shipped = None if args.replace or (robot, MODELS[model]) not in current else recheck(current[(robot, MODELS[model])])
            found = [make_design(robot, MODELS[model], seed) for seed in args.seeds]
            for d in found:
                print(f"{robot} {model} seed {d.seed}: cond(Θ̄_B) {d.cond_theta:.4g}", flush=True)
            best = min(found + ([shipped] if shipped else []), key=lambda d: d.cond_theta)
            print(f"{robot} {model}: kept {'the shipped design' if best is shipped else f'seed {best.seed}'}, "
                  f"cond(Θ̄_B) {best.cond_theta:.4g}", flush=True)
            current[(robot, MODELS[model])] = best
            write_designs(sorted(current.values(), key=lambda d: (d.robot, not d.reduced)), args.file)
    return 0


if __name__ == "__main__":  # the long search's starts run in spawned processes
    sys.exit(main())
