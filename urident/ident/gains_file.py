"""GAINS.yaml: joint drive gains i_G·k [N·m/A] estimated by ``urident drive-gains``.

    format: urident-drive-gains
    version: 1
    robot: ur10e
    drive_gains: [g1, ..., g6]      # N·m per A, joint side
    sigma: [s1, ..., s6]             # standard deviations (optional)
    method: ...                      # informational
    data: {...}                      # informational
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from urident.errors import ConfigError
from urident.fileio import write_text_atomic
from urident.yamlio import Fields, load_yaml

FORMAT = "urident-drive-gains"
VERSION = 1
_TOP = {"format", "version", "robot", "drive_gains", "sigma", "method", "data"}


class GainsFileError(ConfigError):
    """A drive-gains file is missing or malformed."""


def save_gains(path, robot: str, gains, sigma, method: str, data: dict | None = None,
               overwrite: bool = False) -> None:
    doc = {"format": FORMAT, "version": VERSION, "robot": robot,
           "drive_gains": [float(g) for g in gains], "sigma": [float(s) for s in sigma],
           "method": method, "data": data or {}}
    write_text_atomic(path, yaml.safe_dump(doc, sort_keys=False, width=120), fsync=False, overwrite=overwrite)


def load_gains(path) -> tuple[str, np.ndarray, np.ndarray | None]:
    """(robot, gains (6,), sigma (6,) or None); GainsFileError naming the file and key."""
    path = Path(path)
    data = load_yaml(path, "drive-gains file", GainsFileError)
    f = Fields(path, GainsFileError)
    f.document(data, _TOP, ("format", "robot", "drive_gains"), FORMAT, "drive-gains file")
    if data.get("version", VERSION) != VERSION:
        raise f.fail("version", f"not supported (expected {VERSION})")
    robot = f.get(data, "robot", str)
    gains = f.array(data, "drive_gains", "", 6)
    if np.any(gains <= 0):
        raise f.fail("drive_gains", "must be positive [N·m/A]")
    sigma = None if data.get("sigma") is None else f.array(data, "sigma", "", 6)
    return robot, gains, sigma
