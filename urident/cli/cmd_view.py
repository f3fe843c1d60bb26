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
                    "tracking error, and the robot moving in 3-D. The prediction is urident "
                    "validate's: preprocessing and drive gains follow the parameters file. Spawns a "
                    "viewer unless --save OUT.rrd or --rerun URL is given.")
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
    from urident.cli.cmd_identify import add_preprocess_arguments
    from urident.cli.log_args import add_log_arguments

    add_preprocess_arguments(p, trim_default=False)
    options.add_payload_argument(p, "its torque adds to the arm's prediction")
    p.add_argument("--cutoff", dest="filter_hz", type=options.positive_float, default=None,
                   help=argparse.SUPPRESS)
    add_log_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.cli.cmd_identify import preprocess_overrides
    from urident.errors import ConfigError
    from urident.ident import (load_prediction_params, nominal_parameters, predict_recordings,
                               prediction_config)
    from urident.cli.log_args import load_log_from_args
    from urident.model import load_robot
    from urident.viz.blueprint import torque_blueprint
    from urident.viz.recording import close_recording
    from urident.viz.replay import log_prediction

    options.check_rerun_args(args, default_spawn=True)  # fail before the (slow) loading
    recording = load_log_from_args(args.log, args, robot=args.robot)
    robot = args.robot or recording.robot
    if robot is None:
        raise ConfigError(f"{args.log}: the log names no robot; pass --robot")
    spec = load_robot(robot)
    params = load_prediction_params(args.params, spec) if args.params else nominal_parameters(spec)
    config = prediction_config(params, **preprocess_overrides(args))
    prediction = predict_recordings(params, [recording], spec, config=config,
                                    payload=options.load_payload_arg(args, spec),
                                    drive_gains=args.drive_gains or None)  # errors before a viewer opens
    rec = options.open_recording_from_args(args, "urident_view", default_spawn=True,
                                           blueprint=torque_blueprint(joint_names=spec.joint_names))
    result = log_prediction(rec, spec, recording, prediction,
                            f"{spec.name}: measured vs {'identified' if args.params else 'nominal'} model",
                            pose_rate_hz=args.pose_rate_hz or None)
    close_recording(rec)
    rms = ", ".join(f"{v:.3g}" for v in result.rms_nm)
    where = options.rerun_destination(args)
    print(f"{result.n_samples} samples, e_N = {result.e_n:.4f}, RMS residual [N m] = [{rms}]; {where}",
          file=sys.stdout)
    return 0
