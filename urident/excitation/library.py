"""Shipped designs: the best trajectory a long search found for each UR arm and model, at the
default settings (order 5, 20 s, one period, the paper's offsets, the default margins), used as
starts of the default search.

A design joins the random candidates of :func:`urident.excitation.optimize.optimize_excitation`
whenever the arm's name and the number of harmonics match (any model, duration, offsets, margins,
payload or tool): projected onto the user's limits and shrunk until collision-free like the random
ones, then ranked with them by the same objective, so it becomes a start only where it scores among
the best. The default search reaches a basin within 5 % of a ten times longer search on 13 of 18
arm-and-model pairs from random candidates alone; which basin it reaches is a draw
(docs/excitation.md). A design found by the long search once is a start every later search can
begin from, on any seed.

``python -m urident.excitation.library [--robots ur5e,ur10e] [--models reduced,full]`` reruns the
long search (seed 0, without the designs: each comes from random candidates alone) and rewrites
those entries of :data:`LIBRARY_FILE`; ``tests/test_excitation_library.py`` fails when a robot
file's change makes a design's recorded cond stale.
"""

from __future__ import annotations

import argparse
import datetime
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from urident.errors import ConfigError
from urident.yamlio import load_yaml

LIBRARY_FILE = Path(__file__).with_name("designs.yaml")
FORMAT_NAME = "urident-excitation-designs"
FORMAT_VERSION = 1
#: The long search the designs come from (and ``benchmarks/excitation.py``'s reference): the
#: default's with four times the candidates, twice the starts and finalists and up to 120 restart
#: rounds while below ten times its evaluations.
LONG_SEARCH = dict(candidates=256, starts=16, finalists=4, hop_rounds=120, hop_evaluations=240_000)
MODELS = {"reduced": True, "full": False}


@dataclass(frozen=True)
class Design:
    robot: str
    reduced: bool
    harmonics: int
    duration_s: float
    q0: tuple[float, ...]      # the offsets it was made for [rad]
    cond_theta: float          # at the controller rate when it was made
    free: np.ndarray           # (6, 2(L−1)) free Fourier coefficients [rad/s]

    @property
    def model(self) -> str:
        return "reduced" if self.reduced else "full"


def load_designs(path: Path = LIBRARY_FILE) -> list[Design]:
    """Every design in ``path``; a malformed entry is a :class:`ConfigError` naming the file and key."""
    data = load_yaml(path, "excitation designs")
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        raise ConfigError(f"{path}: format: expected {FORMAT_NAME!r}")
    if data.get("format_version") != FORMAT_VERSION:
        raise ConfigError(f"{path}: format_version: expected {FORMAT_VERSION}, got {data.get('format_version')!r}")
    entries = data.get("designs")
    if not isinstance(entries, list):
        raise ConfigError(f"{path}: designs: expected a list")
    designs = []
    for i, entry in enumerate(entries):
        where = f"{path}: designs[{i}]"
        try:
            harmonics = int(entry["harmonics"])
            free = np.asarray(entry["free_rad_s"], dtype=float)
            q0 = tuple(float(v) for v in entry["q0_rad"])
            design = Design(str(entry["robot"]), MODELS[entry["model"]], harmonics, float(entry["duration_s"]),
                            q0, float(entry["cond_theta"]), free)
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"{where}: {type(exc).__name__}: {exc}") from None
        if len(q0) != 6 or not np.all(np.isfinite(q0)):
            raise ConfigError(f"{where}.q0_rad: expected 6 finite numbers")
        if harmonics < 2 or free.shape != (6, 2 * (harmonics - 1)) or not np.all(np.isfinite(free)):
            raise ConfigError(f"{where}.free_rad_s: expected 6 rows of {2 * (harmonics - 1)} finite numbers")
        designs.append(design)
    return designs


def starts_for(robot: str, harmonics: int, path: Path = LIBRARY_FILE) -> np.ndarray:
    """(k, 6, 2(L−1)) the free coefficients of the designs for ``robot`` of order ``harmonics``
    (k = 0 where none is shipped)."""
    found = [d.free for d in load_designs(path) if d.robot == robot and d.harmonics == harmonics]
    return np.array(found, dtype=float).reshape(len(found), 6, 2 * (harmonics - 1))


def design_document(designs: list[Design], made: dict[tuple[str, bool], str]) -> dict:
    """The YAML document of ``designs``; ``made``: each one's date, by (robot, reduced)."""
    return {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "designs": [
        {"robot": d.robot, "model": d.model, "harmonics": d.harmonics, "duration_s": d.duration_s,
         "q0_rad": [float(v) for v in d.q0], "cond_theta": round(d.cond_theta, 4), "made": made[(d.robot, d.reduced)],
         "free_rad_s": [[float(v) for v in row] for row in d.free]} for d in designs]}


def write_designs(designs: list[Design], made: dict[tuple[str, bool], str], path: Path = LIBRARY_FILE) -> None:
    from urident.fileio import write_text_atomic

    header = ("# urident's shipped excitation designs (urident/excitation/library.py): seed 0 of the long\n"
              "# search, default settings; remade with: python -m urident.excitation.library\n")
    text = yaml.safe_dump(design_document(designs, made), sort_keys=False, default_flow_style=None, width=200)
    write_text_atomic(path, header + text, fsync=False, overwrite=True)


def make_design(robot: str, reduced: bool, progress=None) -> Design:
    """The long search (:data:`LONG_SEARCH`, seed 0, default settings, no shipped designs) for one
    arm and model."""
    from urident.excitation.fourier import free_coefficients
    from urident.excitation.optimize import ExcitationSettings, optimize_excitation
    from urident.model import load_robot

    settings = ExcitationSettings(reduced=reduced, seed=0, library=False, **LONG_SEARCH)
    result = optimize_excitation(load_robot(robot), settings, progress=progress)
    return Design(robot, reduced, settings.harmonics, settings.duration_s, settings.q0, float(result.criteria.cond_theta),
                  free_coefficients(result.trajectory))


def main(argv: list[str] | None = None) -> int:
    from urident.model.robot import available_robots

    parser = argparse.ArgumentParser(prog="python -m urident.excitation.library", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", default=",".join(available_robots()), help="comma-separated arms (default: every one)")
    parser.add_argument("--models", default="reduced,full", help="reduced, full or both (default both)")
    args = parser.parse_args(argv)
    robots, models = args.robots.split(","), args.models.split(",")
    unknown = [m for m in models if m not in MODELS] + [r for r in robots if r not in available_robots()]
    if unknown:
        parser.error(f"unknown robot or model: {', '.join(unknown)}")
    current = {(d.robot, d.reduced): d for d in load_designs()} if LIBRARY_FILE.exists() else {}
    made = _dates()
    for robot in robots:
        for model in models:
            design = make_design(robot, MODELS[model])
            current[(robot, MODELS[model])] = design
            made[(robot, MODELS[model])] = datetime.date.today().isoformat()
            print(f"{robot} {model}: cond(Θ̄_B) {design.cond_theta:.4g}", flush=True)
            write_designs(sorted(current.values(), key=lambda d: (d.robot, not d.reduced)), made)
    return 0


def _dates() -> dict[tuple[str, bool], str]:
    if not LIBRARY_FILE.exists():
        return {}
    return {(e["robot"], MODELS[e["model"]]): e["made"] for e in load_yaml(LIBRARY_FILE, "excitation designs")["designs"]}


if __name__ == "__main__":
    sys.exit(main())
