"""``urident excite``: optimise an excitation trajectory and write it to a trajectory file."""

from __future__ import annotations

import argparse
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "excite", help="optimise a safe excitation trajectory (Fourier series, paper eq. 25-26)",
        description="Optimise the Fourier coefficients of an excitation trajectory that starts and "
                    "ends at rest, minimising cond(Λ) of the base regressor (or maximising log det Λ) "
                    "within the joint, velocity, acceleration, torque and collision limits, check it "
                    "densely at the controller rate and write it as a trajectory file.")
    p.add_argument("--robot", required=True, help="robot name (urident model --list) or robot file")
    p.add_argument("--out", required=True, help="trajectory file to write (YAML)")
    p.add_argument("--harmonics", type=_positive_int, default=5, help="order L of the series (default 5)")
    p.add_argument("--duration", type=_positive_float, default=20.0, help="duration [s] (default 20)")
    p.add_argument("--periods", type=_positive_int, default=1,
                   help="whole base periods in the duration; ω = 2π·periods/duration (default 1)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--criterion", choices=("cond", "logdet"), default="cond",
                   help="minimise cond(Λ) (default) or maximise log det(Λ)")
    p.add_argument("--reduced", action="store_true",
                   help="the paper's reduced model (33 base parameters) instead of the full one (52)")
    p.add_argument("--q0", type=_six_floats, default=None,
                   help="offsets q_i,0 [rad] as six comma-separated numbers (default: 0,-pi/2,0,0,0,0)")
    p.add_argument("--starts", type=_positive_int, default=None, help="optimiser starts (default 2)")
    p.add_argument("--iterations", type=_positive_int, default=None,
                   help="L-BFGS-B iterations per start (default 100)")
    p.add_argument("--velocity-fraction", type=_fraction, default=None,
                   help="|q̇| ≤ fraction · robot limit (default 0.8)")
    p.add_argument("--acceleration-fraction", type=_fraction, default=None,
                   help="|q̈| ≤ fraction · robot limit (default 1.0)")
    p.add_argument("--torque-fraction", type=_fraction, default=None,
                   help="nominal |τ| ≤ fraction · robot limit (default 0.9)")
    p.add_argument("--position-margin", type=_nonnegative_float, default=None,
                   help="distance kept from the joint limits [rad] (default 0.2)")
    p.add_argument("--position-window", type=_positive_float, default=None,
                   help="keep every joint within ±window [rad] (default pi: one turn)")
    p.add_argument("--clearance", type=_nonnegative_float, default=None,
                   help="minimum capsule distance to the floor and between links [m] (default 0.05)")
    p.add_argument("--floor-height", type=float, default=None,
                   help="height of the floor / mount plane in the base frame [m] (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from urident.errors import ConfigError
    from urident.excitation.check import check_trajectory
    from urident.excitation.constraints import Margins
    from urident.excitation.files import trajectory_document, write_trajectory
    from urident.excitation.optimize import ExcitationSettings, optimize_excitation
    from urident.model import load_robot

    spec = load_robot(args.robot)
    margin_args = {"velocity_fraction": args.velocity_fraction,
                   "acceleration_fraction": args.acceleration_fraction,
                   "torque_fraction": args.torque_fraction,
                   "position_margin_rad": args.position_margin,
                   "position_window_rad": args.position_window, "clearance_m": args.clearance,
                   "floor_height_m": args.floor_height}
    margins = Margins(**{k: v for k, v in margin_args.items() if v is not None})
    settings = ExcitationSettings(harmonics=args.harmonics, duration_s=args.duration,
                                  periods=args.periods, criterion=args.criterion,
                                  reduced=args.reduced, seed=args.seed, margins=margins)
    if args.q0 is not None:
        settings = replace(settings, q0=tuple(args.q0))
    if args.starts is not None:
        settings = replace(settings, starts=args.starts)
    if args.iterations is not None:
        settings = replace(settings, iterations=args.iterations)
    progress = None if args.quiet else (lambda message: print(f"urident excite: {message}", file=sys.stderr,
                                                                flush=True))
    try:
        result = optimize_excitation(spec, settings, progress=progress)
    except ValueError as exc:
        raise ConfigError(f"--robot {spec.name}: {exc}") from None

    report = check_trajectory(spec, result.trajectory, limits=result.limits)
    report.raise_if_unsafe(f"{args.out} (not written)")
    optimization = {"criterion": settings.criterion, "reduced": settings.reduced, "seed": settings.seed,
                    "starts": settings.starts, "iterations": settings.iterations,
                    "criterion_samples": settings.criterion_samples,
                    "collision_samples": settings.collision_samples,
                    "limit_samples": settings.limit_samples, "periods": settings.periods,
                    "wall_s": round(result.wall_s, 3), "evaluations": result.evaluations}
    criteria = {**result.criteria.as_dict(), "rate_hz": spec.controller_rate_hz, "reduced": settings.reduced}
    check = {"ok": report.ok, "rate_hz": report.rate_hz, "min_distance_m": report.min_distance_m,
             "min_distance_pair": report.min_distance_pair, "collision_margin_m": report.collision_margin_m}
    document = trajectory_document(spec.name, result.trajectory, result.limits, optimization, criteria, check)
    header = (f"urident excitation trajectory for {spec.description}: Kovincic et al. (2019) eq. (25),\n"
              f"at rest at both ends. cond(Θ̄_B) = {result.criteria.cond_theta:.4g} "
              f"(cond Λ = {result.criteria.cond_lambda:.4g}; columns scaled by reference RMS).\n"
              f"Re-check with: urident check-trajectory {args.out}")
    try:
        write_trajectory(args.out, document, header)
    except OSError as exc:
        raise ConfigError(f"{args.out}: cannot write trajectory file ({exc.strerror or exc})") from None
    print(f"wrote {args.out}: {spec.name}, L = {settings.harmonics}, {settings.duration_s:g} s, "
          f"cond(Θ̄_B) = {result.criteria.cond_theta:.4g} (cond Λ = {result.criteria.cond_lambda:.4g}, "
          f"{result.criteria.n_base} base parameters), min distance {report.min_distance_m:.4f} m "
          f"({report.min_distance_pair}), {result.wall_s:.1f} s")
    note = spec.nominal_note(("inertia_com", "rotor_inertia", "viscous_friction", "coulomb_friction",
                              "acceleration_limit", "torque_limit"))
    if note:  # the torque and acceleration checks use them
        print(note)
    return 0


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, not {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number, not {text}")
    return value


def _nonnegative_float(text: str) -> float:
    value = float(text)
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a non-negative number, not {text}")
    return value


def _fraction(text: str) -> float:
    value = float(text)
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1], not {text}")
    return value


def _six_floats(text: str) -> list[float]:
    import math

    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be six comma-separated numbers, not {text!r}") from None
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"must be six comma-separated finite numbers, not {text!r}")
    return values
