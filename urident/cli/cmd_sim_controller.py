"""``urident sim-controller`` (and ``python -m urident.simcontroller``): run the simulated UR
controller (RTDE, dashboard, script ports); :mod:`urident.simcontroller.launch` serves it."""

from __future__ import annotations

import argparse
import sys

from urident.cli import options
from urident.simcontroller.launch import START_NEAR_OFFSET_RAD

DESCRIPTION = (
    "Simulated Universal Robots controller: serves RTDE (30004), the dashboard (29999) and the "
    "script ports (30003, 30002) on one address, so the unmodified ur_rtde client connects to it "
    "as to a real robot. Prints 'listening on HOST' once all ports are bound; stops on SIGINT/SIGTERM.")

FAULT_HELP = (
    "inject a fault (repeatable): drop@T (close all connections), protective_stop@T, "
    "emergency_stop@T, stale@T[:D] (timestamp frozen, default for ever), latency@T[:D] (pause in "
    "sending, default 0.2 s), no_remote (dashboard: not in remote control). T counts seconds from "
    "the first motion command the control script receives; write start+T to count from controller "
    "start.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="ur5e",
                        help="robot name (urident model --list) or robot file; default ur5e")
    parser.add_argument("--host", default="127.0.0.1",
                        help="loopback address to bind (one controller per address; default "
                             "127.0.0.1); another address needs --allow-remote")
    parser.add_argument("--allow-remote", action="store_true",
                        help="allow binding a non-loopback address, reachable from other machines "
                             "(warns on every start)")
    parser.add_argument("--version", dest="controller_version", default=None, metavar="VERSION",
                        type=options.checked(_parse_version),
                        help="controller software version, e.g. 5.11.0 (e-Series, 500 Hz) or 3.15.8 "
                             "(CB3, 125 Hz); default: the robot file's")
    parser.add_argument("--effects", default=None, metavar="FILE",
                        help="unmodelled-effects file (urident.simcontroller.effects)")
    parser.add_argument("--fault", action="append", default=[], metavar="SPEC", help=FAULT_HELP,
                        type=options.checked(_parse_fault))
    parser.add_argument("--seed", type=options.seed, default=0, help="seed of the measurement noise (default 0)")
    parser.add_argument("--no-realtime", action="store_true",
                        help="do not ask for real-time (SCHED_FIFO) scheduling of the controller loop")
    parser.add_argument("--verbose", action="store_true",
                        help="log every recipe and the first use of each script command on stderr")
    start = parser.add_mutually_exclusive_group()
    start.add_argument("--initial-q", type=options.joint_vector, default=None, metavar="Q0,...,Q5",
                       help="initial joint positions [rad], comma-separated (default: a home pose)")
    start.add_argument("--start-near", default=None, metavar="TRAJECTORY",
                       help=f"start the arm {START_NEAR_OFFSET_RAD} rad (each joint) from this "
                            f"trajectory file's start, so `urident run` approaches it")


def _parse_version(text: str):
    from urident.simcontroller.controller import parse_version

    return parse_version(text)


def _parse_fault(text: str):
    from urident.simcontroller.faults import parse_fault

    return parse_fault(text)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "sim-controller", help="run a simulated UR controller that ur_rtde connects to",
        description=DESCRIPTION)
    add_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.simcontroller.launch import serve

    return serve(args)


def main(argv: list[str] | None = None) -> int:
    from urident.errors import UridentError

    parser = options.ArgumentParser(prog="python -m urident.simcontroller", description=DESCRIPTION)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        from urident.simcontroller.launch import serve

        return serve(args)
    except UridentError as exc:
        print(f"urident: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        return 130
