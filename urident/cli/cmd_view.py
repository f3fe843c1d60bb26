"""``urident view``: replay a log in Rerun (measured vs predicted torque, residual, metrics, robot
in 3-D), in a viewer or to an ``.rrd`` file."""

from __future__ import annotations

import argparse
import sys

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "view", help="show a log in Rerun: measured vs predicted torque, robot in 3-D",
        description="Replay a log in the Rerun viewer: one plot per joint of measured (drive gains "
                    "x current) vs predicted torque and their residual, e_N and per-joint RMS, "
                    "tracking error, and the robot moving in 3-D. Spawns a viewer unless --save "
                    "OUT.rrd or --rerun URL is given.")
    p.add_argument("log", metavar="LOG", help="log CSV (urident, ur_rtde or foreign format)")
    p.add_argument("--robot", default=None,
                   help="robot name or file (default: the robot named in the log's sidecar)")
    p.add_argument("--params", metavar="FILE", default=None,
                   help="parameters to predict with: a PARAMS.yaml from 'urident identify', or 78 "
                        "standard / base parameters (.npy, .txt, .csv, .json, .yaml); default: the "
                        "robot file's nominal parameters")
    options.add_rerun_arguments(p, "replay (default: spawn a viewer)")
    options.add_overwrite_argument(p, "an existing .rrd file")
    p.add_argument("--pose-rate", dest="pose_rate_hz", type=options.nonnegative_float, default=30.0,
                   metavar="HZ", help="rate of the 3-D robot poses (default 30 Hz; 0 = every sample)")
    p.add_argument("--cutoff", dest="cutoff_hz", type=options.positive_float, default=10.0, metavar="HZ",
                   help="low-pass cutoff of the zero-phase acceleration estimate (default 10 Hz)")
    from urident.logs import add_log_arguments

    add_log_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.logs import load_log_from_args
    from urident.model import load_robot
    from urident.viz.blueprint import torque_blueprint
    from urident.viz.prediction import load_prediction_params, recording_predictor
    from urident.viz.recording import close_recording
    from urident.viz.replay import log_recording_comparison

    options.check_rerun_args(args, default_spawn=True)  # fail before the (slow) loading
    recording = load_log_from_args(args.log, args, robot=args.robot)
    robot = args.robot or recording.robot
    if robot is None:
        raise ConfigError(f"{args.log}: the log names no robot; pass --robot")
    spec = load_robot(robot)
    params = load_prediction_params(args.params, spec) if args.params else None
    predictor = recording_predictor(spec, params, cutoff_hz=args.cutoff_hz)
    tau_predicted = predictor(recording)  # before opening a viewer: errors come first

    rec = options.open_recording_from_args(args, "urident_view", default_spawn=True,
                                           blueprint=torque_blueprint(joint_names=spec.joint_names))
    metrics = log_recording_comparison(
        rec, spec, recording, tau_predicted=tau_predicted,
        title=f"{spec.name}: measured vs {'identified' if params is not None else 'nominal'} model",
        pose_rate_hz=args.pose_rate_hz or None)
    close_recording(rec)
    rms = ", ".join(f"{metrics[f'rms/{j}']:.3g}" for j in spec.joint_names)
    where = options.rerun_destination(args)
    print(f"{len(recording)} samples, e_N = {metrics['e_N']:.4f}, RMS residual [N m] = [{rms}]; {where}",
          file=sys.stdout)
    return 0
