"""``urident excite``: optimise an excitation trajectory and write it to a trajectory file."""

from __future__ import annotations

import argparse
import math
import sys

from urident.cli import options

MAX_HARMONICS = 100      # what trajectory files allow (urident.excitation.files.MAX_HARMONICS)
MAX_DURATION_S = 3600.0
# --for-payload's defaults, written into the help (urident.excitation.design holds them; a test
# keeps the two equal without importing numpy when the parser is built)
PAYLOAD_PERIODS = 2
PAYLOAD_DURATION_S = 30.0
PAYLOAD_VELOCITY_FRACTION = 0.7
PAYLOAD_VELOCITY_CAP_RAD_S = 2.25   # design.payload_velocity_cap(), to two decimals
ARM_JOINT_FRACTION = 0.2
# The search's and the margins' defaults, written into the help: ExcitationSettings and Margins hold
# them, and the same test keeps these equal.
SEARCH = {"duration_s": 20.0, "periods": 1, "starts": 8, "screen_iterations": 60, "finalists": 2,
          "hops": 2, "hop_rounds": 12, "iterations": 1000, "tolerance": 2e-3, "window": 50, "polish": 2,
          "polish_iterations": 600, "polish_tolerance": 5e-4}
MARGINS = {"velocity_fraction": 0.8, "acceleration_fraction": 1.0, "torque_fraction": 0.9,
           "position_margin_rad": 0.2, "position_window_rad": math.pi, "clearance_m": 0.05,
           "floor_height_m": 0.0}


def _cond_percent(tolerance: float) -> str:
    """A fall of the objective (log cond Λ = 2 log cond Θ̄) as cond Θ̄'s percentage, for the help."""
    return f"{100 * tolerance / 2:g} %%"


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
                   help=f"duration [s], at most {MAX_DURATION_S:g} (default {SEARCH['duration_s']:g}; {PAYLOAD_DURATION_S:g} "
                        "with --for-payload)")
    p.add_argument("--periods", type=options.int_range(1, 1000), default=None,
                   help="whole base periods in the duration; ω = 2π·periods/duration "
                        f"(default {SEARCH['periods']}; "
                        f"{PAYLOAD_PERIODS} with --for-payload)")
    p.add_argument("--seed", type=options.seed, default=0, help="random seed (default 0)")
    p.add_argument("--criterion", choices=("cond", "logdet"), default="cond",
                   help="minimise cond(Λ) (default) or maximise log det(Λ)")
    p.add_argument("--reduced", action="store_true",
                   help="the paper's reduced model (33 base parameters) instead of the full one (52)")
    p.add_argument("--q0", type=options.joint_vector, default=None,
                   help="offsets q_i,0 [rad] as six comma-separated numbers (default: 0,-pi/2,0,0,0,0)")
    p.add_argument("--starts", type=options.int_range(1, 1000), default=None,
                   help=f"optimiser starts (default {SEARCH['starts']}: each runs {SEARCH['screen_iterations']} "
                        f"BFGS iterations, the best {SEARCH['finalists']} continue until converged, then up to "
                        f"{SEARCH['hop_rounds']} rounds of {SEARCH['hops']} perturbed restarts from the best)")
    p.add_argument("--iterations", type=options.int_range(1, 100000), default=None,
                   help=f"BFGS iterations per start at most (default {SEARCH['iterations']}; a start ends "
                        f"earlier once cond fell less than {_cond_percent(SEARCH['tolerance'])} over its last "
                        f"{SEARCH['window']} iterations), and as many (at most {SEARCH['polish_iterations']}) "
                        f"more for the best {SEARCH['polish']} on a finer criterion grid, until cond falls less "
                        f"than {_cond_percent(SEARCH['polish_tolerance'])} over {SEARCH['window']}")
    p.add_argument("--library", action=argparse.BooleanOptionalAction, default=None,
                   help="--library: urident's shipped designs of the arm for this order join the random "
                        "candidates (urident/excitation/designs.yaml: the best a ten times longer search found "
                        "at the default settings); --no-library: random candidates only (default: the designs "
                        "with seed 0 only; another seed asks for another trajectory, e.g. for validation)")
    p.add_argument("--budget", type=options.positive_float, default=None, metavar="SECONDS",
                   help="stop the search after this wall time [s] and keep the best point so far (the "
                        "dense checks after it add a few seconds); the output says how far from converged "
                        "it stopped (default: until converged)")
    p.add_argument("--velocity-fraction", type=options.fraction, default=None,
                   help=f"|q̇| ≤ fraction · robot limit (default {MARGINS['velocity_fraction']:g}; "
                        f"{PAYLOAD_VELOCITY_FRACTION} with --for-payload, which also keeps |q̇| within "
                        f"{PAYLOAD_VELOCITY_CAP_RAD_S:.2f} rad/s: servoJ's lag inside "
                        "the session's tracking monitor)")
    p.add_argument("--max-velocity", type=options.positive_float, default=None, metavar="RAD_S",
                   help="also keep every joint's |q̇| within this [rad/s] (e.g. 2.2 on a fast wrist: servoJ's "
                        "0.1 s lag stays inside the session's 0.25 rad tracking monitor; default none, "
                        f"{PAYLOAD_VELOCITY_CAP_RAD_S:.2f} with --for-payload)")
    p.add_argument("--acceleration-fraction", type=options.fraction, default=None,
                   help=f"|q̈| ≤ fraction · robot limit (default {MARGINS['acceleration_fraction']:.1f})")
    p.add_argument("--torque-fraction", type=options.fraction, default=None,
                   help=f"nominal |τ| ≤ fraction · robot limit (default {MARGINS['torque_fraction']:g})")
    p.add_argument("--position-margin", type=options.nonnegative_float, default=None,
                   help=f"distance kept from the joint limits [rad] (default {MARGINS['position_margin_rad']:g})")
    p.add_argument("--position-window", type=options.positive_float, default=None,
                   help="keep every joint within ±window [rad] (default pi: one turn)")
    p.add_argument("--clearance", type=options.nonnegative_float, default=None,
                   help="minimum capsule distance to the floor and between links [m] "
                        f"(default {MARGINS['clearance_m']:g})")
    p.add_argument("--floor-height", type=options.finite_float, default=None,
                   help="height of the floor / mount plane in the base frame [m] "
                        f"(default {MARGINS['floor_height_m']:g})")
    p.add_argument("--for-payload", action="store_true",
                   help="design a payload excitation: minimise the condition number of the ten "
                        "payload columns (mass, centre of mass, inertia as seen through the flange, "
                        f"the arm's parameters known), joints 1-3 within {100 * ARM_JOINT_FRACTION:g} %% of their velocity and "
                        "acceleration limits (wrist-dominated); needs the tool's size "
                        "(--tool-capsule or a --payload file with a capsule)")
    options.add_checked_payload_arguments(p, "the torque checks include it (with and without it) and "
                                             "its capsule (if any) is the tool's size for the collision "
                                             "checks; the trajectory file records it")
    options.add_tool_capsule_argument(p)
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.excitation.design import HarmonicRateError, ToolSizeError, design
    from urident.model import load_robot

    options.output_path("--out", args.out, args.overwrite)
    spec = load_robot(args.robot)
    payload, payload_source = options.checked_payload(args, spec)
    tool_source = "--tool-capsule" if args.tool_capsule is not None else f"capsule of {args.payload}"
    margins = {"velocity_fraction": args.velocity_fraction, "acceleration_fraction": args.acceleration_fraction,
               "torque_fraction": args.torque_fraction, "position_margin_rad": args.position_margin,
               "position_window_rad": args.position_window, "clearance_m": args.clearance,
               "floor_height_m": args.floor_height}
    progress = None if args.quiet else (lambda message: print(f"urident excite: {message}", file=sys.stderr,
                                                                flush=True))
    try:
        result = design(args.robot, harmonics=args.harmonics, duration_s=args.duration, periods=args.periods,
                        criterion=args.criterion, reduced=args.reduced, seed=args.seed, q0=args.q0,
                        starts=args.starts, iterations=args.iterations, budget_s=args.budget, margins=margins,
                        for_payload=args.for_payload, payload=payload, tool=args.tool_capsule,
                        payload_source=payload_source, tool_source=tool_source,
                        max_velocity_rad_s=args.max_velocity, library=args.library, progress=progress)
    except HarmonicRateError as exc:
        raise ConfigError(exc.message("--")) from None
    except ToolSizeError:
        raise ConfigError("--for-payload needs the tool's size for the collision checks: give "
                          "--tool-capsule RADIUS,LENGTH or a --payload file with a capsule") from None
    result.save(args.out, overwrite=args.overwrite)
    settings, criteria, report, tool = result.settings, result.criteria, result.check, result.tool
    print(f"wrote {args.out}: {result.robot}, L = {settings.harmonics}, {settings.duration_s:g} s, "
          + (f"payload columns cond {result.payload_cond:.4g}, " if settings.for_payload else "")
          + f"cond(Θ̄_B) = {criteria.cond_theta:.4g} (cond Λ = {criteria.cond_lambda:.4g}, "
          f"{criteria.n_base} base parameters), min distance {report.min_distance_m:.4f} m "
          f"({report.min_distance_pair}), {result.wall_s:.1f} s")
    print(f"search: {result.convergence.describe(settings.criterion)}")
    if payload is not None:
        print(f"payload {payload.mass_kg:g} kg ({payload_source}): recorded in the file, the torque checks "
              f"hold with and without it (check-trajectory, run)")
    if tool is not None:
        print(f"tool capsule radius {tool.radius_m:g} m, length {tool.length_m:g} m ({result.tool_source}): "
              f"recorded in the file, part of every check of it (check-trajectory, run)")
    note = spec.nominal_note(("inertia_com", "rotor_inertia", "viscous_friction", "coulomb_friction",
                              "acceleration_limit", "torque_limit"))
    if note:  # the torque and acceleration checks use them
        print(note)
    return 0
