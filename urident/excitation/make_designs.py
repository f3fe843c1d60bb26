"""Remake the shipped excitation designs (:mod:`urident.excitation.library`): the long search
(:data:`~urident.excitation.library.LONG_SEARCH`, seed 0, the default settings, without the shipped
designs) for each arm and model given, each written into the designs file as it ends (about 2 min
per design on a 2-core machine).

    python -m urident.excitation.make_designs [--robots ur5e,ur10e] [--models reduced,full]
"""

from __future__ import annotations

import argparse
import datetime
import sys

from urident.excitation.fourier import free_coefficients
from urident.excitation.library import LIBRARY_FILE, LONG_SEARCH, MODELS, Design, load_designs, write_designs
from urident.excitation.optimize import ExcitationSettings, optimize_excitation
from urident.model import available_robots, load_robot


def make_design(robot: str, reduced: bool, progress=None) -> Design:
    """The long search (:data:`LONG_SEARCH`, seed 0, default settings, no shipped designs) for one
    arm and model."""
    settings = ExcitationSettings(reduced=reduced, seed=0, library=False, **LONG_SEARCH)
    result = optimize_excitation(load_robot(robot), settings, progress=progress)
    return Design(robot, reduced, settings.harmonics, settings.duration_s, settings.q0, float(result.criteria.cond_theta),
                  free_coefficients(result.trajectory), datetime.date.today().isoformat())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m urident.excitation.make_designs", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", default=",".join(available_robots()), help="comma-separated arms (default: every one)")
    parser.add_argument("--models", default="reduced,full", help="reduced, full or both (default both)")
    args = parser.parse_args(argv)
    robots, models = args.robots.split(","), args.models.split(",")
    unknown = [m for m in models if m not in MODELS] + [r for r in robots if r not in available_robots()]
    if unknown:
        parser.error(f"unknown robot or model: {', '.join(unknown)}")
    current = {(d.robot, d.reduced): d for d in load_designs()} if LIBRARY_FILE.exists() else {}
    for robot in robots:
        for model in models:
            design = make_design(robot, MODELS[model])
            current[(robot, MODELS[model])] = design
            print(f"{robot} {model}: cond(Θ̄_B) {design.cond_theta:.4g}", flush=True)
            write_designs(sorted(current.values(), key=lambda d: (d.robot, not d.reduced)))
    return 0


if __name__ == "__main__":  # the long search's starts run in spawned processes
    sys.exit(main())
