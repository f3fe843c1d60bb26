"""One excitation design from start to file: the settings a user's choices imply (the payload
defaults of ``for_payload``, the highest harmonic the controller rate allows), the optimisation
(:func:`urident.excitation.optimize.optimize_excitation`), the dense check at the controller rate,
and the trajectory file, written only once its text reads back to the trajectory that was checked.
``urident excite`` and ``urident.design_excitation`` are this module."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

from urident.errors import ConfigError
from urident.excitation.check import CheckReport, check_trajectory
from urident.excitation.constraints import Limits, Margins
from urident.excitation.criteria import CriterionValues
from urident.excitation.files import (parse_trajectory_document, trajectory_document, trajectory_text,
                                      write_trajectory)
from urident.excitation.fourier import FourierTrajectory
from urident.excitation.optimize import Convergence, ExcitationSettings, optimize_excitation
from urident.model.robot import ROBOTS_DIR, RobotSpec, ToolCapsule, load_robot, robot_path

SAMPLES_PER_PERIOD = 10  # the highest harmonic gets at least this many controller ticks
# for_payload: the inertia needs acceleration, so two base periods in 30 s (2.7 times the
# frequency of one in 20 s); the wrist then runs near its velocity limit, kept at 0.7 of it and
# within payload_velocity_cap (servoJ's lag on a fast wrist). Measured with benchmarks/payload.py
# (docs/benchmarks.md).
DURATION_S = 20.0
PAYLOAD_PERIODS = 2
PAYLOAD_DURATION_S = 30.0
PAYLOAD_VELOCITY_FRACTION = 0.7
PAYLOAD_LAG_SHARE = 0.9       # of the tracking monitor that servoJ's lag bound may use


def payload_velocity_cap() -> float:
    """``for_payload``'s |q̇| bound [rad/s]: servoJ's lag, bounded by q̇ × the session's default
    lookahead (0.1 s), within 0.9 of its default tracking monitor (0.25 rad): 2.25 rad/s, which
    binds on wrists faster than 0.7 × 3.2 rad/s (UR3e/UR3, UR20/UR30)."""
    from urident.session.config import MonitorConfig, ServoConfig

    return PAYLOAD_LAG_SHARE * MonitorConfig().max_tracking_error_rad / ServoConfig().lookahead_time_s


def _velocity_cap(max_velocity_rad_s: float | None, for_payload: bool) -> float | None:
    """The optimiser's |q̇| bound: the caller's, and with ``for_payload`` at most :func:`payload_velocity_cap`."""
    caps = [v for v in (max_velocity_rad_s, payload_velocity_cap() if for_payload else None) if v is not None]
    return min(caps) if caps else None


class HarmonicRateError(ConfigError):
    """The highest harmonic is too fast for the robot's controller rate (fewer than
    :data:`SAMPLES_PER_PERIOD` ticks per period)."""

    def __init__(self, robot: str, rate_hz: float, harmonics: int, periods: int, duration_s: float):
        self.robot, self.rate_hz = robot, rate_hz
        self.harmonics, self.periods, self.duration_s = harmonics, periods, duration_s
        self.top_hz, self.max_hz = harmonics * periods / duration_s, rate_hz / SAMPLES_PER_PERIOD
        super().__init__(self.message())

    def message(self, prefix: str = "") -> str:
        """The one-line message, the settings named with ``prefix`` ("--" on the command line)."""
        return (f"{prefix}harmonics {self.harmonics} with {prefix}periods {self.periods} over {prefix}duration "
                f"{self.duration_s:g}: the highest harmonic ({self.top_hz:g} Hz) must be at most "
                f"{self.max_hz:g} Hz ({self.robot}'s {self.rate_hz:g} Hz controller rate / {SAMPLES_PER_PERIOD})")


class ToolSizeError(ConfigError):
    """``for_payload`` without the tool's size: its collision checks need the tool's capsule."""

    def __init__(self) -> None:
        super().__init__("for_payload needs the tool's size for the collision checks: give a tool capsule "
                         "(tool=ToolCapsule(radius_m, length_m)) or a payload with a capsule")


@dataclass(frozen=True)
class ExcitationDesign:
    """An optimised excitation trajectory that passed the dense check at the controller rate.

    ``cond`` is cond(Θ̄_B) at the controller rate (columns scaled by reference RMS; cond Λ is its
    square), ``convergence`` how the search ended, ``check`` the dense check's report (``ok``,
    ``min_distance_m``). ``to_dict()`` is the trajectory file's document; :meth:`save` writes it
    once its text reads back to the checked trajectory."""

    robot: str                          # the robot's name
    trajectory: FourierTrajectory
    limits: Limits                      # the file's limits (the margins applied to the robot's)
    settings: ExcitationSettings
    criteria: CriterionValues           # at the controller rate
    convergence: Convergence
    check: CheckReport
    wall_s: float                       # the optimisation's wall time [s]
    cpu_s: float                        # its CPU time, worker processes included [s]
    evaluations: int
    spec: RobotSpec = field(repr=False, compare=False)   # the robot, with the tool mounted
    robot_file: Path | None = None      # the robot file, when the robot was given by path
    payload_cond: float | None = None   # for_payload: cond of the ten payload columns
    payload: Any = None                 # the load the torque checks included (a Payload), or None
    payload_source: str = ""            # where the payload and the tool came from (the file's header)
    tool_source: str = ""
    shipped_designs: int = 0            # shipped designs among the search's candidates (excitation.library)
    from_shipped: bool = False          # the design began at one of them

    @property
    def cond(self) -> float:
        return float(self.criteria.cond_theta)

    def __repr__(self) -> str:  # the arrays would fill a notebook's cell
        return (f"ExcitationDesign(robot={self.robot!r}, L={self.settings.harmonics}, "
                f"duration_s={self.trajectory.duration:g}, cond={self.cond:.4g}, converged={self.converged}, "
                f"check_ok={self.check.ok})")

    @property
    def tool(self) -> ToolCapsule | None:
        return self.spec.tool

    @property
    def converged(self) -> bool:
        return self.convergence.converged

    def optimization(self) -> dict:
        """The file's ``optimization`` section: the settings, times and how the search ended."""
        s = self.settings
        out = {"criterion": s.criterion, "reduced": s.reduced, "seed": s.seed, "starts": s.starts,
               "screen_iterations": s.screen_iterations, "finalists": s.finalists, "iterations": s.iterations,
               "tolerance": s.tolerance, "hops": s.hops, "hop_rounds": s.hop_rounds, "polish": s.polish,
               "polish_iterations": s.polish_iterations, "polish_tolerance": s.polish_tolerance,
               "criterion_samples": s.samples("criterion"), "polish_samples": s.samples("polish"),
               "collision_samples": s.samples("collision"), "limit_samples": s.samples("limits"), "periods": s.periods,
               "select": s.select, "shipped_designs": self.shipped_designs, "from_shipped": self.from_shipped,
               "wall_s": round(self.wall_s, 3), "cpu_s": round(self.cpu_s, 3), "evaluations": self.evaluations,
               **self.convergence.as_dict()}
        if s.budget_s is not None:
            out["budget_s"] = s.budget_s
        if s.for_payload:
            out.update(for_payload=True, arm_joint_fraction=s.arm_joint_fraction)
        if s.max_velocity_rad_s is not None:
            out["max_velocity_rad_s"] = s.max_velocity_rad_s
        return out

    def document(self, path: str | Path | None = None) -> dict:
        """The trajectory file's document; a robot given by path is named relative to ``path``'s
        directory (absolute without ``path``)."""
        robot = self.robot
        if self.robot_file is not None:
            robot = (os.path.relpath(self.robot_file.resolve(), Path(path).resolve().parent) if path is not None
                     else str(self.robot_file.resolve()))
        criteria = {**self.criteria.as_dict(), "rate_hz": self.spec.controller_rate_hz,
                    "reduced": self.settings.reduced}
        if self.settings.for_payload:
            criteria["payload_cond"] = self.payload_cond
        r = self.check
        check = {"ok": r.ok, "rate_hz": r.rate_hz, "min_distance_m": r.min_distance_m,
                 "min_distance_pair": r.min_distance_pair, "collision_margin_m": r.collision_margin_m}
        return trajectory_document(robot, self.trajectory, self.limits, self.optimization(), criteria, check,
                                   tool=self.tool, payload=self.payload)

    def header(self, path: str | Path) -> str:
        """The comment lines at the top of the file written to ``path``."""
        tool, payload = self.tool, self.payload
        what = (f"payload excitation (wrist-dominated): cond of the payload columns = {self.payload_cond:.4g};\n"
                if self.settings.for_payload else "")
        return (f"urident excitation trajectory for {self.spec.description}: Kovincic et al. (2019) eq. (25),\n"
                f"at rest at both ends. {what}cond(Θ̄_B) = {self.criteria.cond_theta:.4g} "
                f"(cond Λ = {self.criteria.cond_lambda:.4g}; columns scaled by reference RMS).\n"
                + (f"Tool capsule (collision checks): radius {tool.radius_m:g} m, length {tool.length_m:g} m "
                   f"along the flange z axis ({self.tool_source}).\n" if tool is not None else "")
                + (f"Torque checks include the payload ({self.payload_source}): {payload.describe()}.\n"
                   if payload is not None else "")
                + f"Re-check with: urident check-trajectory {path}")

    def to_dict(self) -> dict:
        return self.document()

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    def save(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write the trajectory file, after checking that its text reads back to the trajectory and
        limits the dense check passed (else the read-back is checked again); :class:`SafetyError`
        (nothing written) if a check fails."""
        from urident.yamlio import parse_yaml

        target = Path(path)
        self.check.raise_if_unsafe(f"{path} (not written)")
        document = self.document(target)
        header = self.header(path)
        # what check-trajectory will read: the written text, parsed back and checked before writing
        text = trajectory_text(document, header)
        loaded = parse_trajectory_document(parse_yaml(text, f"{target} (not written)"), target)
        if not _same(loaded, self.trajectory, self.limits):
            check_trajectory(loaded.spec, loaded.trajectory, limits=loaded.limits,
                             payload=loaded.payload).raise_if_unsafe(f"{path} (not written)")
        write_trajectory(target, document, header, overwrite=overwrite)
        return target


def design(robot: str | Path | RobotSpec, *, harmonics: int = 5, duration_s: float | None = None,
           periods: int | None = None, criterion: str = "cond", reduced: bool = False, seed: int = 0,
           q0=None, starts: int | None = None, iterations: int | None = None, budget_s: float | None = None,
           margins: Mapping[str, float] | None = None, for_payload: bool = False, payload=None,
           tool: ToolCapsule | None = None, payload_source: str = "payload", tool_source: str | None = None,
           max_velocity_rad_s: float | None = None, library: bool | None = None,
           progress: Callable[[str], None] | None = None) -> ExcitationDesign:
    """Optimise, check and return an excitation design (see :func:`urident.design_excitation`;
    ``payload`` is a :class:`urident.ident.payload.Payload`, ``*_source`` say where the payload and
    tool came from in the file's header; ``max_velocity_rad_s`` bounds every joint's |q̇| besides the
    margins', :func:`payload_velocity_cap` with ``for_payload``; ``library``: the arm's shipped designs
    join the search's candidates, :mod:`urident.excitation.library`; None: with seed 0 only)."""
    robot_file = None
    if isinstance(robot, RobotSpec):
        spec = robot
        if spec.source.resolve() != (ROBOTS_DIR / f"{spec.name}.yaml").resolve():
            robot_file = spec.source
    else:
        spec, robot_file = load_robot(robot), robot_path(robot)
    if payload is not None:
        spec.check_rated_payload(payload.mass_kg, payload_source)
    if tool is None:
        cap = payload.info.get("capsule") if payload is not None else None
        if cap:  # a payload file's capsule is the tool's size
            tool, tool_source = ToolCapsule(cap["radius_m"], cap["length_m"]), tool_source or "capsule of the payload"
    elif tool_source is None:
        tool_source = "tool"
    if for_payload and tool is None:
        raise ToolSizeError()
    spec = spec.with_tool(tool)
    periods = periods if periods is not None else PAYLOAD_PERIODS if for_payload else 1
    duration_s = duration_s if duration_s is not None else PAYLOAD_DURATION_S if for_payload else DURATION_S
    if harmonics * periods / duration_s > spec.controller_rate_hz / SAMPLES_PER_PERIOD:
        raise HarmonicRateError(spec.name, spec.controller_rate_hz, harmonics, periods, duration_s)
    overrides = {k: v for k, v in dict(margins or {}).items() if v is not None}
    if for_payload:
        overrides.setdefault("velocity_fraction", PAYLOAD_VELOCITY_FRACTION)
    try:
        settings = ExcitationSettings(harmonics=harmonics, duration_s=duration_s, periods=periods,
                                      criterion=criterion, reduced=reduced, seed=seed, margins=Margins(**overrides),
                                      for_payload=for_payload, library=library,
                                      max_velocity_rad_s=_velocity_cap(max_velocity_rad_s, for_payload))
        chosen = {"q0": None if q0 is None else tuple(q0), "starts": starts, "iterations": iterations,
                  "budget_s": budget_s}
        settings = replace(settings, **{k: v for k, v in chosen.items() if v is not None})
    except (TypeError, ValueError) as exc:  # a combination of valid values the settings refuse
        raise ConfigError(f"excitation settings: {exc}") from None
    try:
        result = optimize_excitation(spec, settings, progress=progress, payload=payload)
    except ValueError as exc:
        raise ConfigError(f"cannot optimise an excitation for {spec.name}: {exc}") from None
    report = check_trajectory(spec, result.trajectory, limits=result.limits, payload=payload)
    return ExcitationDesign(spec.name, result.trajectory, result.limits, result.settings, result.criteria,
                            result.convergence, report, result.wall_s, result.cpu_s, result.evaluations, spec,
                            robot_file, result.payload_cond, payload, payload_source if payload is not None else "",
                            tool_source if tool is not None else "", result.shipped_designs, result.from_shipped)


def _same(loaded, trajectory: FourierTrajectory, limits: Limits) -> bool:
    import numpy as np

    a, b = loaded.trajectory, trajectory
    same_traj = all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("a", "b", "omega", "q0"))
    same_limits = all(np.array_equal(getattr(loaded.limits, k), getattr(limits, k))
                      for k in ("q_min", "q_max", "qd_max", "qdd_max", "tau_max"))
    return same_traj and same_limits and a.duration == b.duration
