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
    tool_capsule: {radius_m: 0.05, length_m: 0.15}   # optional: a tool on the flange (see
                                        # urident.model.robot.ToolCapsule); every check of this
                                        # trajectory (check-trajectory, urident run) includes it
    payload: {mass_kg: 5.0, com_m: [0, 0, 0.1], inertia_kg_m2: [[..], [..], [..]]}   # optional: the
                                        # load the torque checks included (flange frame, inertia
                                        # about the centre of mass; none: the empty flange)
    optimization: {...}                 # optional: criterion, reduced, seed, settings, wall_s, how the search ended
    criteria: {...}                     # optional: cond_theta, cond_lambda, logdet_lambda, ...
    check: {...}                        # optional: rate_hz, min_distance_m, min_distance_pair

Read with the strict reader :mod:`urident.yamlio`: unknown and duplicate keys are rejected; every
error is one line ``FILE: key.path: message``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from urident.fileio import write_text_atomic

from urident.version import __version__
from urident.errors import ConfigError
from urident.excitation.constraints import Limits, Margins
from urident.excitation.fourier import FourierTrajectory
from urident.model.payload import Payload
from urident.model.robot import RobotSpec, ToolCapsule, load_robot
from urident.yamlio import Fields, load_yaml

FORMAT_NAME = "urident-excitation-trajectory"
FORMAT_VERSION = 1
MAX_HARMONICS = 100
_TOP_KEYS = {"format", "format_version", "urident_version", "robot", "trajectory", "limits",
             "tool_capsule", "payload", "optimization", "criteria", "check"}
_REQUIRED_TOP = ("format", "format_version", "robot", "trajectory", "limits")
_TRAJ_KEYS = {"harmonics", "duration_s", "base_frequency_rad_s", "q0_rad", "a_rad_s", "b_rad_s",
              "q_start_rad"}
_MARGIN_KEYS = {"velocity_fraction", "acceleration_fraction", "torque_fraction",
                "position_margin_rad", "position_window_rad", "clearance_m", "floor_height_m"}
_ABS_LIMIT_KEYS = {"q_min_rad": "q_min", "q_max_rad": "q_max", "qd_max_rad_s": "qd_max",
                   "qdd_max_rad_s2": "qdd_max", "tau_max_nm": "tau_max"}
_OPT_KEYS = {"criterion", "reduced", "seed", "starts", "iterations", "criterion_samples",
             "collision_samples", "limit_samples", "periods", "wall_s", "evaluations", "for_payload",
             "arm_joint_fraction", "max_velocity_rad_s", "screen_iterations", "finalists", "tolerance",
             "cpu_s", "budget_s", "converged", "stop_reason", "total_iterations", "gradient_norm",
             "last_window_improvement", "window", "hops", "hop_rounds", "polish", "polish_samples", "select",
             "polish_iterations", "polish_tolerance", "shipped_designs", "from_shipped"}
_CRITERIA_KEYS = {"cond_theta", "cond_lambda", "logdet_lambda", "cond_theta_raw", "cond_theta_equilibrated", "n_samples",
                  "n_base", "rate_hz", "reduced", "payload_cond"}
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
    payload: Payload | None = None   # the tool the torque checks included

    @property
    def criterion(self) -> str | None:
        return self.optimization.get("criterion")

    @property
    def min_distance_m(self) -> float | None:
        return self.check.get("min_distance_m")

    @property
    def tool(self) -> ToolCapsule | None:
        return self.spec.tool

    def checked_spec(self, spec: RobotSpec) -> RobotSpec:
        """``spec`` with this file's tool mounted: a trajectory designed for a tool is always
        checked with it."""
        return spec.with_tool(self.spec.tool)


def trajectory_document(robot: str, trajectory: FourierTrajectory, limits: Limits,
                        optimization: dict[str, Any] | None = None,
                        criteria: dict[str, Any] | None = None,
                        check: dict[str, Any] | None = None,
                        tool: ToolCapsule | None = None, payload: Payload | None = None) -> dict[str, Any]:
    """The YAML document (plain Python types) for a trajectory file (``tool``: the mounted tool
    its checks include; ``payload``: the load its torque checks include, a
    :class:`urident.model.payload.Payload`)."""
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
    if tool is not None:
        doc["tool_capsule"] = tool.as_dict()
    if payload is not None:
        from urident.ident.payload_file import inertial_dict

        doc["payload"] = inertial_dict(payload)
    for key, value in (("optimization", optimization), ("criteria", criteria), ("check", check)):
        if value:
            doc[key] = _plain(value)
    return doc


def trajectory_text(document: dict[str, Any], header: str = "") -> str:
    """The text of a trajectory file: ``header`` as comments, then the document."""
    text = yaml.safe_dump(document, sort_keys=False, default_flow_style=None, width=120)
    comment = "".join(f"# {line}\n" for line in header.splitlines()) if header else ""
    return comment + text


def write_trajectory(path: str | Path, document: dict[str, Any], header: str = "",
                     overwrite: bool = True) -> None:
    """Write a trajectory document atomically (temp file + rename; never through a symbolic
    link; ``overwrite=False``: the file must not exist)."""
    write_text_atomic(Path(path), trajectory_text(document, header), fsync=False, overwrite=overwrite)


def load_trajectory(path: str | Path) -> TrajectoryFile:
    """Read and validate a trajectory file. Raises :class:`ConfigError` (one line
    ``FILE: key.path: message``, with the line of a YAML syntax error or duplicate key)."""
    path = Path(path)
    data = load_yaml(path, "trajectory file")
    try:
        return parse_trajectory_document(data, path)
    except ConfigError:
        raise
    except (TypeError, ValueError, OverflowError, RecursionError, KeyError, IndexError) as exc:
        # Defensive: every malformed input must end in a ConfigError.
        raise ConfigError(f"{path}: invalid trajectory file ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else ''})") from None


def parse_trajectory_document(data: Any, path: Path | None = None) -> TrajectoryFile:
    r = Fields(path if path is not None else "<trajectory>")
    r.mapping(data, "", "a mapping at the top level")
    r.keys(data, _TOP_KEYS, "", required=_REQUIRED_TOP)
    if data["format"] != FORMAT_NAME:
        raise r.fail("format", f"must be '{FORMAT_NAME}'")
    version = r.integer(data, "format_version")
    if version != FORMAT_VERSION:
        raise r.fail("format_version", f"{version} is not supported (expected {FORMAT_VERSION})")
    urident_version = data.get("urident_version")
    if "urident_version" in data and (not isinstance(urident_version, (str, int, float))
                                      or isinstance(urident_version, bool)
                                      or not _finite_if_number(urident_version)):
        raise r.fail("urident_version", "must be a string")

    robot_ref = r.get(data, "robot", str)
    robot_path = Path(robot_ref)
    if path is not None and robot_ref.endswith((".yaml", ".yml")) and not robot_path.is_absolute():
        robot_ref = str(path.parent / robot_path)
    try:
        spec = load_robot(robot_ref)
    except ConfigError as exc:
        raise r.fail("robot", str(exc)) from None
    if data.get("tool_capsule") is not None:
        cap = r.mapping(data["tool_capsule"], "tool_capsule")
        r.keys(cap, {"radius_m", "length_m"}, "tool_capsule", required=("radius_m", "length_m"))
        spec = spec.with_tool(ToolCapsule(r.number(cap, "radius_m", "tool_capsule", positive=True),
                                          r.number(cap, "length_m", "tool_capsule", nonnegative=True)))

    payload = None
    if data.get("payload") is not None:
        from urident.ident.payload_file import inertial_fields

        section = r.mapping(data["payload"], "payload")
        r.keys(section, {"mass_kg", "com_m", "inertia_kg_m2"}, "payload", required=("mass_kg", "com_m"))
        mass, com, inertia = inertial_fields(r, section, "payload", spec=spec)
        payload = Payload(spec.name, mass, com, inertia)

    traj = r.get(data, "trajectory", dict)
    r.keys(traj, _TRAJ_KEYS, "trajectory")
    harmonics = r.integer(traj, "harmonics", "trajectory", minimum=1, maximum=MAX_HARMONICS)
    duration = r.number(traj, "duration_s", "trajectory", positive=True)
    omega_raw = traj.get("base_frequency_rad_s")
    if isinstance(omega_raw, list):
        omega = r.array(traj, "base_frequency_rad_s", "trajectory", (6,))
        if np.any(omega <= 0):
            raise r.fail("trajectory.base_frequency_rad_s", "must be positive")
    else:
        omega = np.full(6, r.number(traj, "base_frequency_rad_s", "trajectory", positive=True))
    q0 = r.array(traj, "q0_rad", "trajectory", (6,))
    a = r.array(traj, "a_rad_s", "trajectory", (6, harmonics))
    b = r.array(traj, "b_rad_s", "trajectory", (6, harmonics))
    trajectory = FourierTrajectory(a, b, omega, q0, duration)
    if "q_start_rad" in traj:
        q_start = r.array(traj, "q_start_rad", "trajectory", (6,))
        if not np.allclose(q_start, trajectory.q_start, rtol=0, atol=1e-6):
            raise r.fail("trajectory.q_start_rad", "does not match q(0) of the coefficients")

    lim = r.get(data, "limits", dict)
    r.keys(lim, _MARGIN_KEYS | set(_ABS_LIMIT_KEYS), "limits", required=sorted(_MARGIN_KEYS))
    values = {key: r.number(lim, key, "limits") for key in sorted(_MARGIN_KEYS)}
    try:
        margins = Margins(**values)
        limits = Limits.from_robot(spec, margins)
    except ValueError as exc:
        raise r.fail("limits", str(exc)) from None
    for key, attr in _ABS_LIMIT_KEYS.items():
        if key in lim:
            stored = r.array(lim, key, "limits", (6,))
            if not np.allclose(stored, getattr(limits, attr), rtol=1e-9, atol=1e-9):
                raise r.fail(f"limits.{key}", f"does not match robot {spec.name}'s limits with the "
                                              f"file's margins")

    sections = {}
    for key, allowed in (("optimization", _OPT_KEYS), ("criteria", _CRITERIA_KEYS), ("check", _CHECK_KEYS)):
        section = r.mapping(data.get(key, {}), key)
        r.keys(section, allowed, key)
        for k, v in section.items():
            if not isinstance(v, (str, int, float, bool)) or not _finite_if_number(v):
                raise r.fail(f"{key}.{k}", "must be a finite number, string or boolean")
        sections[key] = dict(section)
    return TrajectoryFile(path, spec.name, spec, trajectory, margins, limits,
                          None if urident_version is None else str(urident_version), **sections,
                          payload=payload)


def _finite_if_number(value: Any) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return True
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


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
