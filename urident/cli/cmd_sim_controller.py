"""``urident sim-controller``: run the simulated UR controller (RTDE, dashboard, script ports)."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.simcontroller.launch import DESCRIPTION, add_arguments

    parser = subparsers.add_parser(
        "sim-controller", help="run a simulated UR controller that ur_rtde connects to",
        description=DESCRIPTION)
    add_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.simcontroller.launch import serve

    return serve(args)
