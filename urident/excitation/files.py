"""Trajectory files: a YAML document holding everything needed to replay an excitation trajectory.

Format (``format_version: 1``)::

    format: urident-excitation-trajectory
    format_version: 1
    urident_version: 0.1.0
    robot: ur5                          # robot name or robot file path (relative to this file)
    trajectory:                         # paper eq. (25)
      harmonics: 5                      # order L
      duration_s: 20.0                  # a whole number of base periods; rest at both ends
      base_frequency_rad_s: 0.314159    # ω, shared; or a list of 6 (one per joint)
      q0_rad: [0.0, -1.5708, 0.0, 0.0, 0.0, 0.0]
      a_rad_s: [[...L...], ... 6 rows]
      b_rad_s: [[...L...], ... 6 rows]
      q_start_rad: [...]                # optional, informational: q(0)
    limits:                             # margins used; the absolute limits follow from the robot
      velocity_fraction: 0.8
      acceleration_fraction: 1.0
      torque_fraction: 0.9
      position_margin_rad: 0.2
      position_window_rad: 3.14159      # and |q| ≤ window
      clearance_m: 0.05
      floor_height_m: 0.0
      q_min_rad: [...]                  # optional, informational; checked against the robot
      q_max_rad: [...]
      qd_max_rad_s: [...]
      qdd_max_rad_s2: [...]
      tau_max_nm: [...]
    optimization: {...}                 # optional: criterion, reduced, seed, settings, wall_s
    criteria: {...}                     # optional: cond_theta, cond_lambda, logdet_lambda, ...
    check: {...}                        # optional: rate_hz, min_distance_m, min_distance_pair

Unknown keys are rejected; every error is a one-line :class:`ConfigError` naming the file and key
(and the line for YAML syntax errors).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from urident.fileio import write_text_atomic

from urident import __version__
from urident.errors import ConfigError, shown
from urident.excitation.constraints import Limits, Margins
from urident.excitation.fourier import FourierTrajectory
from urident.model.robot import RobotSpec, load_robot

_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when available: ~20x faster
FORMAT_NAME = "urident-excitation-trajectory"
FORMAT_VERSION = 1
MAX_HARMONICS = 100
_TOP_KEYS = {"format", "format_version", "urident_version", "robot", "trajectory", "limits",
             "optimization", "criteria", "check"}
_REQUIRED_TOP = ("format", "format_version", "robot", "trajectory", "limits")
_TRAJ_KEYS = {"harmonics", "duration_s", "base_frequency_rad_s", "q0_rad", "a_rad_s", "b_rad_s",
              "q_start_rad"}
_MARGIN_KEYS = {"velocity_fraction", "acceleration_fraction", "torque_fraction",
                "position_margin_rad", "position_window_rad", "clearance_m", "floor_height_m"}
_ABS_LIMIT_KEYS = {"q_min_rad": "q_min", "q_max_rad": "q_max", "qd_max_rad_s": "qd_max",
                   "qdd_max_rad_s2": "qdd_max", "tau_max_nm": "tau_max"}
_OPT_KEYS = {"criterion", "reduced", "seed", "starts", "iterations", "criterion_samples",
             "collision_samples", "limit_samples", "periods", "wall_s", "evaluations"}
_CRITERIA_KEYS = {"cond_theta", "cond_lambda", "logdet_lambda", "cond_theta_raw", "cond_theta_equilibrated", "n_samples",
                  "n_base", "rate_hz", "reduced"}
_CHECK_KEYS = {"rate_hz", "min_distance_m", "min_distance_pair", "collision_margin_m", "ok"}


@dataclass(frozen=True)
class TrajectoryFile:
    """A loaded trajectory file."""

    path: Path | None
    robot: str                       # the robot name
    spec: RobotSpec
    trajectory: FourierTrajectory
    margins: Margins
    limits: Limits
    urident_version: str | None = None
    optimization: dict[str, Any] = field(default_factory=dict)
    criteria: dict[str, Any] = field(default_factory=dict)
    check: dict[str, Any] = field(default_factory=dict)

    @property
    def criterion(self) -> str | None:
        return self.optimization.get("criterion")

    @property
    def min_distance_m(self) -> float | None:
        return self.check.get("min_distance_m")


def trajectory_document(robot: str, trajectory: FourierTrajectory, limits: Limits,
                        optimization: dict[str, Any] | None = None,
                        criteria: dict[str, Any] | None = None,
                        check: dict[str, Any] | None = None) -> dict[str, Any]:
    """The YAML document (plain Python types) for a trajectory file."""
    omega = trajectory.omega
    shared = bool(np.all(omega == omega[0]))
    m = limits.margins
    doc: dict[str, Any] = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "urident_version": __version__,
        "robot": robot,
        "trajectory": {
            "harmonics": trajectory.harmonics,
            "duration_s": float(trajectory.duration),
            "base_frequency_rad_s": float(omega[0]) if shared else [float(w) for w in omega],
            "q0_rad": _floats(trajectory.q0),
            "a_rad_s": [_floats(row) for row in trajectory.a],
            "b_rad_s": [_floats(row) for row in trajectory.b],
            "q_start_rad": _floats(trajectory.q_start),
        },
        "limits": {
            "velocity_fraction": m.velocity_fraction,
            "acceleration_fraction": m.acceleration_fraction,
            "torque_fraction": m.torque_fraction,
            "position_margin_rad": m.position_margin_rad,
            "position_window_rad": m.position_window_rad,
            "clearance_m": m.clearance_m,
            "floor_height_m": m.floor_height_m,
            **{key: _floats(getattr(limits, attr)) for key, attr in _ABS_LIMIT_KEYS.items()},
        },
    }
    for key, value in (("optimization", optimization), ("criteria", criteria), ("check", check)):
        if value:
            doc[key] = _plain(value)
    return doc


def write_trajectory(path: str | Path, document: dict[str, Any], header: str = "") -> None:
    """Write a trajectory document atomically (temp file + rename)."""
    path = Path(path)
    text = yaml.safe_dump(document, sort_keys=False, default_flow_style=None, width=120)
    comment = "".join(f"# {line}\n" for line in header.splitlines()) if header else ""
    write_text_atomic(path, comment + text, fsync=False)


def load_trajectory(path: str | Path) -> TrajectoryFile:
    """Read and validate a trajectory file. Raises :class:`ConfigError` (one line, naming the file
    and key, or the line of a YAML syntax error) for anything malformed."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: trajectory file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read trajectory file ({type(exc).__name__})") from None
    try:
        data = yaml.load(text, Loader=_SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f":{mark.line + 1}" if mark is not None else ""
        problem = str(getattr(exc, "problem", None) or type(exc).__name__).replace("\n", " ")
        raise ConfigError(f"{path}{where}: malformed YAML ({problem})") from None
    except (RecursionError, ValueError, OverflowError) as exc:
        raise ConfigError(f"{path}: malformed YAML ({type(exc).__name__})") from None
    try:
        return parse_trajectory_document(data, path)
    except ConfigError:
        raise
    except (TypeError, ValueError, OverflowError, RecursionError, KeyError, IndexError) as exc:
        # Defensive: every malformed input must end in a ConfigError.
        raise ConfigError(f"{path}: invalid trajectory file ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else ''})") from None


def parse_trajectory_document(data: Any, path: Path | None = None) -> TrajectoryFile:
    r = _Reader(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{r.name}: expected a mapping at the top level")
    r.keys(data, _TOP_KEYS, "")
    for key in _REQUIRED_TOP:
        if key not in data:
            raise ConfigError(f"{r.name}: missing key '{key}'")
    if data["format"] != FORMAT_NAME:
        raise ConfigError(f"{r.name}: key 'format' must be '{FORMAT_NAME}'")
    version = r.integer(data, "format_version", "")
    if version != FORMAT_VERSION:
        raise ConfigError(f"{r.name}: key 'format_version' {version} is not supported (expected {FORMAT_VERSION})")
    urident_version = data.get("urident_version")
    if "urident_version" in data and (not isinstance(urident_version, (str, int, float))
                                      or isinstance(urident_version, bool)):
        raise ConfigError(f"{r.name}: key 'urident_version' must be a string")

    robot_ref = r.get(data, "robot", str, "")
    robot_path = Path(robot_ref)
    if path is not None and robot_ref.endswith((".yaml", ".yml")) and not robot_path.is_absolute():
        robot_ref = str(path.parent / robot_path)
    try:
        spec = load_robot(robot_ref)
    except ConfigError as exc:
        raise ConfigError(f"{r.name}: key 'robot': {exc}") from None

    traj = r.get(data, "trajectory", dict, "")
    r.keys(traj, _TRAJ_KEYS, "trajectory")
    harmonics = r.integer(traj, "harmonics", "trajectory")
    if not 1 <= harmonics <= MAX_HARMONICS:
        raise ConfigError(f"{r.name}: key 'trajectory.harmonics' must be between 1 and {MAX_HARMONICS}")
    duration = r.number(traj, "duration_s", "trajectory", positive=True)
    omega_raw = traj.get("base_frequency_rad_s")
    if isinstance(omega_raw, list):
        omega = r.array(traj, "base_frequency_rad_s", "trajectory", (6,))
        if np.any(omega <= 0):
            raise ConfigError(f"{r.name}: key 'trajectory.base_frequency_rad_s' must be positive")
    else:
        omega = np.full(6, r.number(traj, "base_frequency_rad_s", "trajectory", positive=True))
    q0 = r.array(traj, "q0_rad", "trajectory", (6,))
    a = r.array(traj, "a_rad_s", "trajectory", (6, harmonics))
    b = r.array(traj, "b_rad_s", "trajectory", (6, harmonics))
    trajectory = FourierTrajectory(a, b, omega, q0, duration)
    if "q_start_rad" in traj:
        q_start = r.array(traj, "q_start_rad", "trajectory", (6,))
        if not np.allclose(q_start, trajectory.q_start, rtol=0, atol=1e-6):
            raise ConfigError(f"{r.name}: key 'trajectory.q_start_rad' does not match q(0) of the "
                              f"coefficients")

    lim = r.get(data, "limits", dict, "")
    r.keys(lim, _MARGIN_KEYS | set(_ABS_LIMIT_KEYS), "limits")
    values = {}
    for key in sorted(_MARGIN_KEYS):
        if key not in lim:
            raise ConfigError(f"{r.name}: missing key 'limits.{key}'")
        values[key] = r.number(lim, key, "limits")
    try:
        margins = Margins(**values)
        limits = Limits.from_robot(spec, margins)
    except ValueError as exc:
        raise ConfigError(f"{r.name}: key 'limits': {exc}") from None
    for key, attr in _ABS_LIMIT_KEYS.items():
        if key in lim:
            stored = r.array(lim, key, "limits", (6,))
            if not np.allclose(stored, getattr(limits, attr), rtol=1e-9, atol=1e-9):
                raise ConfigError(f"{r.name}: key 'limits.{key}' does not match robot {spec.name}'s "
                                  f"limits with the file's margins")

    sections = {}
    for key, allowed in (("optimization", _OPT_KEYS), ("criteria", _CRITERIA_KEYS), ("check", _CHECK_KEYS)):
        section = data.get(key, {})
        if not isinstance(section, dict):
            raise ConfigError(f"{r.name}: key '{key}' must be a mapping")
        r.keys(section, allowed, key)
        for k, v in section.items():
            if not isinstance(v, (str, int, float, bool)) or not _finite_if_number(v):
                raise ConfigError(f"{r.name}: key '{key}.{k}' must be a finite number, string or boolean")
        sections[key] = dict(section)
    return TrajectoryFile(path, spec.name, spec, trajectory, margins, limits,
                          None if urident_version is None else str(urident_version), **sections)


class _Reader:
    def __init__(self, path: Path | None):
        self.name = str(path) if path is not None else "<trajectory>"

    @staticmethod
    def _key(where: str, key: str) -> str:
        return f"{where}.{key}" if where else key

    def keys(self, mapping: dict, allowed: set[str], where: str) -> None:
        unknown = sorted(str(k) for k in mapping if not isinstance(k, str) or k not in allowed)
        if unknown:
            raise ConfigError(f"{self.name}: unknown key '{shown(self._key(where, unknown[0]))}' "
                              f"(allowed: {', '.join(sorted(allowed))})")

    def get(self, mapping: dict, key: str, kind: Any, where: str) -> Any:
        if key not in mapping:
            raise ConfigError(f"{self.name}: missing key '{self._key(where, key)}'")
        value = mapping[key]
        if not isinstance(value, kind) or isinstance(value, bool):
            raise ConfigError(f"{self.name}: key '{self._key(where, key)}' has the wrong type "
                              f"({type(value).__name__})")
        return value

    def integer(self, mapping: dict, key: str, where: str) -> int:
        return int(self.get(mapping, key, int, where))

    def number(self, mapping: dict, key: str, where: str, positive: bool = False) -> float:
        name = self._key(where, key)
        try:
            value = float(self.get(mapping, key, (int, float), where))
        except OverflowError:
            raise ConfigError(f"{self.name}: key '{name}' is out of range") from None
        if not math.isfinite(value):
            raise ConfigError(f"{self.name}: key '{name}' must be finite")
        if positive and value <= 0:
            raise ConfigError(f"{self.name}: key '{name}' must be positive, not {value}")
        return value

    def array(self, mapping: dict, key: str, where: str, shape: tuple[int, ...]) -> np.ndarray:
        name = self._key(where, key)
        value = self.get(mapping, key, list, where)
        described = "x".join(map(str, shape))
        if not _is_numeric_nest(value, len(shape)):
            raise ConfigError(f"{self.name}: key '{name}' must be a {described} list of numbers")
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise ConfigError(f"{self.name}: key '{name}' must be a {described} list of numbers") from None
        if array.shape != shape:
            raise ConfigError(f"{self.name}: key '{name}' must have shape {described}, "
                              f"not {'x'.join(map(str, array.shape))}")
        if not np.all(np.isfinite(array)):
            raise ConfigError(f"{self.name}: key '{name}' must hold finite numbers")
        return array


def _finite_if_number(value: Any) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return True
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def _is_numeric_nest(value: Any, depth: int) -> bool:
    if depth == 0:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, list) and all(_is_numeric_nest(v, depth - 1) for v in value)


def _floats(values: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float)]


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value
