"""``urident run``: execute a trajectory on a robot, URSim or urident's simulated controller."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "run", help="run a checked trajectory on a robot over RTDE and record a log",
        description="Check the controller, the robot state, the trajectory (at the controller's "
                    "rate) and the approach; then moveJ to the start, run the trajectory with "
                    "servoJ under monitors, and record every controller sample. servoStop and "
                    "stopScript always end the session.")
    p.add_argument("--robot", required=True, help="robot name (urident model --list) or robot file")
    p.add_argument("--host", required=True, help="controller address (robot, URSim or sim-controller)")
    p.add_argument("--trajectory", required=True, type=Path, help="trajectory file (urident excite)")
    p.add_argument("--out", type=Path, help="log to write (LOG.csv + LOG.yaml); required unless --check-only")
    p.add_argument("--config", type=Path, help="experiment configuration YAML (servo, approach, monitors)")
    options.add_overwrite_argument(p, "an existing log (and .rrd file)")
    p.add_argument("--repeat", type=options.int_range(1, 1000), default=1,
                   help="run the trajectory N times back to back")
    p.add_argument("--yes", action="store_true", help="do not ask before moving")
    p.add_argument("--check-only", action="store_true", help="do every check, move nothing")
    options.add_rerun_arguments(p, "run live")
    p.add_argument("--record-periods", action="store_true",
                   help="also save every control period [s] to LOG.periods.npy (timing analysis)")
    options.add_checked_payload_arguments(p, "the load mounted for this run: the trajectory's torques are "
                                             "checked with it (default: the load the trajectory file "
                                             "records); a heavier payload declared to the controller is "
                                             "refused")
    p.add_argument("--params", type=Path,
                   help="parameters for the live predicted torque (urident identify output; default nominal)")
    p.set_defaults(func=run)


def _confirm(question: str) -> bool:
    if not sys.stdin.isatty():
        return False
    answer = input(f"{question} [y/N] ").strip().lower()
    return answer in ("y", "yes")


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError

    if args.out is None and not args.check_only:
        raise ConfigError("--out LOG is required (or pass --check-only)")
    # outputs checked before connecting: nothing moves if the log could not be written
    out = None if args.check_only else options.log_output("--out", args.out, args.overwrite)
    if not args.check_only:  # the viewer itself is best effort (the live view falls back to LOG.rrd)
        options.output_path("--save", args.rerun_save, args.overwrite, suffix=".rrd")
        if args.record_periods:
            options.output_path("--record-periods", out.with_suffix(".periods.npy"), args.overwrite)
    from urident.excitation import load_trajectory
    from urident.model import load_robot

    spec = load_robot(args.robot)  # input files read before connecting: a bad one contacts nothing
    load_trajectory(args.trajectory)
    payload, _ = options.checked_payload(args, spec)
    from urident.session import load_experiment_config

    config = load_experiment_config(args.config)   # before the live viewer starts
    live = None
    if options.rerun_sink(args) is not None and not args.check_only:
        live = _live_streamer(args)
    from urident.api import run_trajectory

    result = run_trajectory(args.trajectory, args.host, out or Path("unused.csv"), args.robot, config=config,
                            repeat=args.repeat, check_only=args.check_only, assume_yes=args.yes, confirm=_confirm,
                            payload=payload, record_periods=args.record_periods, live=live)
    if result.status == "checked":
        print("check only: every check passed; nothing was moved")
    return 0


def _live_streamer(args: argparse.Namespace):
    """A Rerun streamer fed by the control loop (its own process; never blocks the loop).
    Predicted torques use ``--params`` (identified) or the robot file's nominal parameters."""
    from urident.model import load_robot
    from urident.viz import LiveStreamer

    spec = load_robot(args.robot)
    params = None
    if args.params is not None:
        from urident.ident import load_prediction_params

        params = load_prediction_params(args.params, spec)
    return LiveStreamer(spec, params, **options.rerun_sink(args),
                        fallback_save=args.out.with_suffix(".rrd") if args.out else None)
