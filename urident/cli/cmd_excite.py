"""``urident excite``: optimise an excitation trajectory and write it to a trajectory file."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from urident.cli import options

MAX_HARMONICS = 100      # what trajectory files allow (urident.excitation.files.MAX_HARMONICS)
MAX_DURATION_S = 3600.0
SAMPLES_PER_PERIOD = 10  # the highest harmonic gets at least this many controller ticks
# --for-payload: the inertia needs acceleration, so two base periods in 30 s (2.7 times the
# frequency of one in 20 s); the wrist then runs near its velocity limit, kept at 0.7 of it and
# within payload_velocity_cap (servoJ's lag on a fast wrist). Measured with benchmarks/payload.py (docs/benchmarks.md).
PAYLOAD_PERIODS = 2
PAYLOAD_DURATION_S = 30.0
PAYLOAD_VELOCITY_FRACTION = 0.7
PAYLOAD_LAG_SHARE = 0.9       # of the tracking monitor that servoJ's lag bound may use


def payload_velocity_cap() -> float:
    """--for-payload's |q̇| bound [rad/s]: servoJ's lag, bounded by q̇ × the session's default
    lookahead (0.1 s), within 0.9 of its default tracking monitor (0.25 rad): 2.25 rad/s, which
    binds on wrists faster than 0.7 × 3.2 rad/s (UR3e/UR3, UR20/UR30)."""
    from urident.session.config import MonitorConfig, ServoConfig

    return PAYLOAD_LAG_SHARE * MonitorConfig().max_tracking_error_rad / ServoConfig().lookahead_time_s


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "excite", help="optimise a safe excitation trajectory (Fourier series, paper eq. 25-26)",
        description="Optimise the Fourier coefficients of an excitation trajectory that starts and "
                    "ends at rest, minimising cond(Λ) of the base regressor (or maximising log det Λ) "
                    "within the joint, velocity, acceleration, torque and collision limits, check it "
                    "densely at the controller rate and write it as a trajectory file.")
    p.add_argument("--robot", required=True, help="robot name (urident model --list) or robot file")
    p.add_argument("--out", required=True, help="trajectory file to write (YAML)")
    options.add_overwrite_argument(p, "an existing trajectory file")
    p.add_argument("--harmonics", type=options.int_range(2, MAX_HARMONICS), default=5,
                   help=f"order L of the series, 2-{MAX_HARMONICS} (default 5)")
    p.add_argument("--duration", type=options.float_range(0, MAX_DURATION_S), default=None,
                   help=f"duration [s], at most {MAX_DURATION_S:g} (default 20; {PAYLOAD_DURATION_S:g} "
                        "with --for-payload)")
    p.add_argument("--periods", type=options.int_range(1, 1000), default=None,
                   help="whole base periods in the duration; ω = 2π·periods/duration (default 1; "
                        f"{PAYLOAD_PERIODS} with --for-payload)")
    p.add_argument("--seed", type=options.seed, default=0, help="random seed (default 0)")
    p.add_argument("--criterion", choices=("cond", "logdet"), default="cond",
                   help="minimise cond(Λ) (default) or maximise log det(Λ)")
    p.add_argument("--reduced", action="store_true",
                   help="the paper's reduced model (33 base parameters) instead of the full one (52)")
    p.add_argument("--q0", type=options.joint_vector, default=None,
                   help="offsets q_i,0 [rad] as six comma-separated numbers (default: 0,-pi/2,0,0,0,0)")
    p.add_argument("--starts", type=options.int_range(1, 1000), default=None,
                   help="optimiser starts (default 8: each runs 60 BFGS iterations, the best 2 continue "
                        "until converged)")
    p.add_argument("--iterations", type=options.int_range(1, 100000), default=None,
                   help="BFGS iterations per start at most (default 1000; a start ends earlier once "
                        "cond fell less than 0.1 %% over its last 50 iterations)")
    p.add_argument("--budget", type=options.positive_float, default=None, metavar="SECONDS",
                   help="stop the search after this wall time [s] and keep the best point so far (the "
                        "dense checks after it add a few seconds); the output says how far from converged "
                        "it stopped (default: until converged)")
    p.add_argument("--velocity-fraction", type=options.fraction, default=None,
                   help=f"|q̇| ≤ fraction · robot limit (default 0.8; {PAYLOAD_VELOCITY_FRACTION} with "
                        "--for-payload, which also keeps |q̇| within 2.25 rad/s: servoJ's lag inside "
                        "the session's tracking monitor)")
    p.add_argument("--acceleration-fraction", type=options.fraction, default=None,
                   help="|q̈| ≤ fraction · robot limit (default 1.0)")
    p.add_argument("--torque-fraction", type=options.fraction, default=None,
                   help="nominal |τ| ≤ fraction · robot limit (default 0.9)")
    p.add_argument("--position-margin", type=options.nonnegative_float, default=None,
                   help="distance kept from the joint limits [rad] (default 0.2)")
    p.add_argument("--position-window", type=options.positive_float, default=None,
                   help="keep every joint within ±window [rad] (default pi: one turn)")
    p.add_argument("--clearance", type=options.nonnegative_float, default=None,
                   help="minimum capsule distance to the floor and between links [m] (default 0.05)")
    p.add_argument("--floor-height", type=options.finite_float, default=None,
                   help="height of the floor / mount plane in the base frame [m] (default 0)")
    p.add_argument("--for-payload", action="store_true",
                   help="design a payload excitation: minimise the condition number of the ten "
                        "payload columns (mass, centre of mass, inertia as seen through the flange, "
                        "the arm's parameters known), joints 1-3 within 20 %% of their velocity and "
                        "acceleration limits (wrist-dominated); needs the tool's size "
                        "(--tool-capsule or a --payload file with a capsule)")
    options.add_checked_payload_arguments(p, "the torque checks include it (with and without it) and "
                                             "its capsule (if any) is the tool's size for the collision "
                                             "checks; the trajectory file records it")
    options.add_tool_capsule_argument(p)
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from urident.errors import ConfigError
    from urident.excitation.check import check_trajectory
    from urident.excitation.constraints import Margins
    from urident.excitation.files import parse_trajectory_document, trajectory_document, write_trajectory
    from urident.excitation.files import trajectory_text
    from urident.excitation.optimize import ExcitationSettings, optimize_excitation
    from urident.model import load_robot
    from urident.yamlio import parse_yaml

    out = options.output_path("--out", args.out, args.overwrite)
    spec = load_robot(args.robot)
    payload, payload_source = options.checked_payload(args, spec)
    tool, tool_source = _tool(args, payload)
    if args.for_payload and tool is None:
        raise ConfigError("--for-payload needs the tool's size for the collision checks: give "
                          "--tool-capsule RADIUS,LENGTH or a --payload file with a capsule")
    spec = spec.with_tool(tool)
    if args.periods is None:
        args.periods = PAYLOAD_PERIODS if args.for_payload else 1
    if args.duration is None:
        args.duration = PAYLOAD_DURATION_S if args.for_payload else 20.0
    if args.velocity_fraction is None and args.for_payload:
        args.velocity_fraction = PAYLOAD_VELOCITY_FRACTION
    top_hz = args.harmonics * args.periods / args.duration
    if top_hz > spec.controller_rate_hz / SAMPLES_PER_PERIOD:
        raise ConfigError(
            f"--harmonics {args.harmonics} with --periods {args.periods} over --duration "
            f"{args.duration:g}: the highest harmonic ({top_hz:g} Hz) must be at most "
            f"{spec.controller_rate_hz / SAMPLES_PER_PERIOD:g} Hz ({spec.name}'s "
            f"{spec.controller_rate_hz:g} Hz controller rate / {SAMPLES_PER_PERIOD})")
    margin_args = {"velocity_fraction": args.velocity_fraction,
                   "acceleration_fraction": args.acceleration_fraction,
                   "torque_fraction": args.torque_fraction,
                   "position_margin_rad": args.position_margin,
                   "position_window_rad": args.position_window, "clearance_m": args.clearance,
                   "floor_height_m": args.floor_height}
    try:
        margins = Margins(**{k: v for k, v in margin_args.items() if v is not None})
        settings = ExcitationSettings(harmonics=args.harmonics, duration_s=args.duration,
                                      periods=args.periods, criterion=args.criterion,
                                      reduced=args.reduced, seed=args.seed, margins=margins,
                                      for_payload=args.for_payload,
                                      max_velocity_rad_s=payload_velocity_cap() if args.for_payload else None)
        if args.q0 is not None:
            settings = replace(settings, q0=tuple(args.q0))
        if args.starts is not None:
            settings = replace(settings, starts=args.starts)
        if args.iterations is not None:
            settings = replace(settings, iterations=args.iterations)
        if args.budget is not None:
            settings = replace(settings, budget_s=args.budget)
    except ValueError as exc:  # a combination of valid flags the settings refuse
        raise ConfigError(f"excitation settings: {exc}") from None
    progress = None if args.quiet else (lambda message: print(f"urident excite: {message}", file=sys.stderr,
                                                                flush=True))
    try:
        result = optimize_excitation(spec, settings, progress=progress, payload=payload)
    except ValueError as exc:
        raise ConfigError(f"cannot optimise an excitation for {spec.name}: {exc}") from None

    # the robot as the file will name it: a robot file given by path is referred to by path
    robot_ref = spec.name
    if str(args.robot).endswith((".yaml", ".yml")) or "/" in str(args.robot):
        robot_ref = os.path.relpath(Path(args.robot).resolve(), Path(out).resolve().parent)
    optimization = {"criterion": settings.criterion, "reduced": settings.reduced, "seed": settings.seed,
                    "starts": settings.starts, "screen_iterations": settings.screen_iterations,
                    "finalists": settings.finalists, "iterations": settings.iterations,
                    "tolerance": settings.tolerance, "criterion_samples": settings.criterion_samples,
                    "collision_samples": settings.collision_samples,
                    "limit_samples": settings.limit_samples, "periods": settings.periods,
                    "wall_s": round(result.wall_s, 3), "cpu_s": round(result.cpu_s, 3),
                    "evaluations": result.evaluations, **result.convergence.as_dict()}
    if settings.budget_s is not None:
        optimization["budget_s"] = settings.budget_s
    criteria = {**result.criteria.as_dict(), "rate_hz": spec.controller_rate_hz, "reduced": settings.reduced}
    if settings.for_payload:
        optimization.update(for_payload=True, arm_joint_fraction=settings.arm_joint_fraction,
                            max_velocity_rad_s=settings.max_velocity_rad_s)
        criteria["payload_cond"] = result.payload_cond
    report = check_trajectory(spec, result.trajectory, limits=result.limits, payload=payload)
    report.raise_if_unsafe(f"{args.out} (not written)")
    check = {"ok": report.ok, "rate_hz": report.rate_hz, "min_distance_m": report.min_distance_m,
             "min_distance_pair": report.min_distance_pair, "collision_margin_m": report.collision_margin_m}
    document = trajectory_document(robot_ref, result.trajectory, result.limits, optimization, criteria, check,
                                   tool=tool, payload=payload)
    what = (f"payload excitation (wrist-dominated): cond of the payload columns = {result.payload_cond:.4g};\n"
            if settings.for_payload else "")
    header = (f"urident excitation trajectory for {spec.description}: Kovincic et al. (2019) eq. (25),\n"
              f"at rest at both ends. {what}cond(Θ̄_B) = {result.criteria.cond_theta:.4g} "
              f"(cond Λ = {result.criteria.cond_lambda:.4g}; columns scaled by reference RMS).\n"
              + (f"Tool capsule (collision checks): radius {tool.radius_m:g} m, length {tool.length_m:g} m "
                 f"along the flange z axis ({tool_source}).\n" if tool is not None else "")
              + (f"Torque checks include the payload ({payload_source}): {payload.describe()}.\n"
                 if payload is not None else "")
              + f"Re-check with: urident check-trajectory {args.out}")
    # what check-trajectory will read: the written text, parsed back and checked before writing
    text = trajectory_text(document, header)
    loaded = parse_trajectory_document(parse_yaml(text, f"{out} (not written)"), out)
    if not _same(loaded, result):  # the dense check above holds for the file only if it reads back exactly
        check_trajectory(loaded.spec, loaded.trajectory, limits=loaded.limits,
                         payload=loaded.payload).raise_if_unsafe(
            f"{args.out} (not written)")
    write_trajectory(out, document, header, overwrite=args.overwrite)
    print(f"wrote {args.out}: {spec.name}, L = {settings.harmonics}, {settings.duration_s:g} s, "
          + (f"payload columns cond {result.payload_cond:.4g}, " if settings.for_payload else "")
          + f"cond(Θ̄_B) = {result.criteria.cond_theta:.4g} (cond Λ = {result.criteria.cond_lambda:.4g}, "
          f"{result.criteria.n_base} base parameters), min distance {report.min_distance_m:.4f} m "
          f"({report.min_distance_pair}), {result.wall_s:.1f} s")
    print(f"search: {result.convergence.describe(settings.criterion)}")
    if payload is not None:
        print(f"payload {payload.mass_kg:g} kg ({payload_source}): recorded in the file, the torque checks "
              f"hold with and without it (check-trajectory, run)")
    if tool is not None:
        print(f"tool capsule radius {tool.radius_m:g} m, length {tool.length_m:g} m ({tool_source}): "
              f"recorded in the file, part of every check of it (check-trajectory, run)")
    note = spec.nominal_note(("inertia_com", "rotor_inertia", "viscous_friction", "coulomb_friction",
                              "acceleration_limit", "torque_limit"))
    if note:  # the torque and acceleration checks use them
        print(note)
    return 0


def _tool(args: argparse.Namespace, payload):
    """The tool's capsule and where it came from: --tool-capsule, else the --payload file's."""
    from urident.model.robot import ToolCapsule

    if args.tool_capsule is not None:
        return args.tool_capsule, "--tool-capsule"
    cap = payload.info.get("capsule") if payload is not None else None
    if cap:
        return ToolCapsule(cap["radius_m"], cap["length_m"]), f"capsule of {args.payload}"
    return None, ""


def _same(loaded, result) -> bool:
    import numpy as np

    a, b = loaded.trajectory, result.trajectory
    same_traj = all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("a", "b", "omega", "q0"))
    same_limits = all(np.array_equal(getattr(loaded.limits, k), getattr(result.limits, k))
                      for k in ("q_min", "q_max", "qd_max", "qdd_max", "tau_max"))
    return same_traj and same_limits and a.duration == b.duration
