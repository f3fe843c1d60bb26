"""Shipped designs: per UR arm and model the best trajectory the long searches of several seeds
found at the default settings (order 5, 20 s, one period, the paper's offsets, the default margins),
used as starts of the default search.

A design joins the random candidates of :func:`urident.excitation.optimize.optimize_excitation`
where the arm's name and the number of harmonics match (any model, duration, offsets, margins,
payload or tool) and ``library`` says so (by default with seed 0 only: another seed asks for another
trajectory): projected onto the user's limits, shrunk only where it is inside the user's clearance,
then ranked with the random ones by the same objective, so it becomes a start only where it scores
among the best. From random candidates alone the default search reaches a basin within 5 % of a ten
times longer search on 13 of 18 arm-and-model pairs; which basin it reaches is a draw
(docs/excitation.md). A design found by the long search once is a start later searches begin from.

``python -m urident.excitation.make_designs [--robots ur5e,ur10e] [--models reduced,full]
[--seeds 0,1,2] [--replace]`` reruns the long search (without the designs: each comes from random
candidates alone) with each seed and keeps the best, the shipped design included unless
``--replace``, in :data:`LIBRARY_FILE`; ``tests/test_excitation_library.py`` fails when a robot
file's change makes a design's recorded cond stale."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from urident.errors import ConfigError
from urident.excitation.fourier import FourierTrajectory, base_frequency
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
    made: str = ""             # the date it was made (ISO)
    seed: int | None = None    # the seed of the long search that found it

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
                            q0, float(entry["cond_theta"]), free, str(entry.get("made", "")),
                            None if entry.get("seed") is None else int(entry["seed"]))
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


def design_trajectory(design: Design):
    """The design's trajectory (its free coefficients on its offsets and duration)."""
    return FourierTrajectory.from_free(design.free, base_frequency(design.duration_s), np.array(design.q0),
                                       design.duration_s)


def design_document(designs: list[Design]) -> dict:
    """The YAML document of ``designs``."""
    return {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "designs": [
        {"robot": d.robot, "model": d.model, "harmonics": d.harmonics, "duration_s": d.duration_s,
         "q0_rad": [float(v) for v in d.q0], "cond_theta": round(d.cond_theta, 4), "made": d.made,
         **({} if d.seed is None else {"seed": d.seed}),
         "free_rad_s": [[float(v) for v in row] for row in d.free]} for d in designs]}


def write_designs(designs: list[Design], path: Path = LIBRARY_FILE) -> None:
    from urident.fileio import write_text_atomic

    header = ("# urident's shipped excitation designs (urident/excitation/library.py): per arm and model the\n"
              "# best of the long search's seeds, default settings; python -m urident.excitation.make_designs\n")
    text = yaml.safe_dump(design_document(designs), sort_keys=False, default_flow_style=None, width=200)
    write_text_atomic(path, header + text, fsync=False, overwrite=True)
