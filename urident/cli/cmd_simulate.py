"""``urident simulate``: a log of a trajectory on the simulated arm, much faster than real time."""

from __future__ import annotations

import argparse

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "simulate", help="simulate a trajectory offline and write a log",
        description="Run a trajectory file through the simulated controller's physics (servoJ "
                    "tracking, torque model, unmodelled effects, sensor noise) without networking "
                    "and write a log in the format of `urident run`, with the simulation's ground "
                    "truth (effects, seed) in the sidecar's 'extra'.")
    p.add_argument("--robot", help="robot name (urident model --list) or robot file; default: the "
                                   "trajectory file's robot")
    p.add_argument("--trajectory", metavar="FILE", help="trajectory file (urident excite)")
    p.add_argument("--out", metavar="LOG", help="log to write (LOG.csv + LOG.yaml)")
    p.add_argument("--effects", metavar="FILE|PRESET", default=None,
                   help="unmodelled-effects file or preset (realistic, none); default: none")
    p.add_argument("--seed", type=options.seed, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--rate", type=options.float_range(0, 10000), default=None, metavar="HZ",
                   help="controller rate (default: the robot's, 125 Hz CB3, 500 Hz e-Series)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing log")
    p.add_argument("--list-effects", action="store_true",
                   help="print the effects catalogue (names, models, parameters) and exit")
    p.set_defaults(func=run)


def _load_trajectory(path: str):
    from pathlib import Path

    from urident.errors import ConfigError

    if not Path(path).is_file():
        raise ConfigError(f"{path}: trajectory file not found")
    try:
        from urident.excitation import load_trajectory
    except ImportError:
        raise ConfigError(f"{path}: reading trajectory files needs urident.excitation."
                          "load_trajectory, which is not installed") from None
    return load_trajectory(path)


def run(args: argparse.Namespace) -> int:
    import time

    from urident.errors import ConfigError
    from urident.simcontroller.effects import available_presets, format_catalogue

    if args.list_effects:
        print(format_catalogue())
        print(f"presets: {', '.join(available_presets())}")
        return 0
    for option in ("trajectory", "out"):
        if not getattr(args, option):
            raise ConfigError(f"--{option} is required (or give --list-effects)")

    from urident.model import load_robot
    from urident.simcontroller.offline import simulate

    options.log_output("--out", args.out, args.overwrite)  # before the simulation
    started = time.perf_counter()
    trajectory = _load_trajectory(args.trajectory)
    file_spec = getattr(trajectory, "spec", None)
    file_robot = getattr(trajectory, "robot", None)
    if args.robot is not None:
        spec = load_robot(args.robot)
    elif file_spec is not None:
        spec = file_spec
    elif file_robot is not None:
        spec = load_robot(str(file_robot))
    else:
        raise ConfigError(f"{args.trajectory}: the trajectory names no robot; give --robot")
    file_name = file_spec.name if file_spec is not None else file_robot
    if file_name is not None and str(file_name) != spec.name:
        raise ConfigError(f"{args.trajectory}: trajectory is for robot '{file_name}', "
                          f"not --robot {args.robot}")
    result = simulate(spec, trajectory, rate_hz=args.rate, effects=args.effects, seed=args.seed,
                      out=args.out, trajectory_file=args.trajectory, overwrite=args.overwrite)
    elapsed = time.perf_counter() - started
    names = ", ".join(result.effects.names) or "none"
    print(f"wrote {result.source}: {len(result)} samples, {result.duration:g} s at "
          f"{result.rate_hz:g} Hz, robot {spec.name}, effects: {names}, seed {args.seed} "
          f"({elapsed:.2f} s)")
    return 0
