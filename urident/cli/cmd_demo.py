"""``urident demo``: the whole pipeline on the built-in simulated controller."""

from __future__ import annotations

import argparse
from pathlib import Path

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo", help="run the whole pipeline on the built-in simulated controller (no robot)",
        description="Start urident's simulated controller of the robot (default UR5e; realistic "
                    "unmodelled effects), run its identification and validation trajectories from "
                    "experiments/ through "
                    "'urident run', then identify, validate and diagnose the sim-to-real gap. "
                    "Everything is written under logs/demo-<timestamp>/.")
    p.add_argument("--out-root", type=Path, default=Path("logs"), help="parent directory (default logs/)")
    p.add_argument("--quick", action="store_true", help="short generated trajectories (about a minute)")
    p.add_argument("--seed", type=options.seed, default=0, help="seed of the simulated controller's noise")
    p.add_argument("--robot", default=None,
                   help="robot to simulate (urident model --list; default ur5e); uses "
                        "experiments/ROBOT_ident.yaml and ROBOT_valid.yaml")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.cli.demo import run_demo

    options.output_path("--out-root", args.out_root, overwrite=False, directory=True)
    robot = {"robot": args.robot} if args.robot else {}
    run_demo(args.out_root, quick=args.quick, seed=args.seed, **robot)
    return 0
