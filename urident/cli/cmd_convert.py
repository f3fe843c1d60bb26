"""``urident convert``: write a log (any format urident reads) as a rosbag2 bag, so that a
urident or simulated run can be replayed in ROS tools (and read back by every urident command)."""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "convert", help="write a log as a rosbag2 bag (MCAP or SQLite)",
        description="Write LOG as a rosbag2 bag directory: one sensor_msgs/JointState per sample "
                    "on /joint_states (stamp = log time, UR's joint names, effort = motor "
                    "current as UR's driver publishes it), and the log's safety and robot modes "
                    "on /io_and_status_controller/safety_mode and robot_mode.")
    p.add_argument("log", metavar="LOG", help="log to convert (urident, ur_rtde, mapped CSV or bag)")
    p.add_argument("--bag", metavar="OUT", required=True,
                   help="bag directory to create (rosbag2 layout: OUT/metadata.yaml + storage file)")
    p.add_argument("--robot", default=None,
                   help="robot name or file (default: the robot named in the log's sidecar)")
    p.add_argument("--storage", default="mcap", choices=("mcap", "sqlite3"),
                   help="storage plugin of the bag (default mcap)")
    p.add_argument("--bag-effort", dest="bag_effort", default="current",
                   choices=("current", "torque", "compensated"),
                   help="what JointState effort carries (docs/signals.md): motor current [A] "
                        "(default, as UR's released drivers), full joint torque [N·m] (the log's, "
                        "else current x drive gains), or UR's gravity-compensated torque [N·m] "
                        "(the log's actual_current_as_torque, else current x drive gains less the "
                        "nominal model's gravity and the declared payload's, as the driver with "
                        "use_currents_as_efforts false publishes it)")
    p.add_argument("--tf-prefix", dest="tf_prefix", default=None, type=options.tf_prefix,
                   help="prefix of the joint names, as the driver's tf_prefix (e.g. ur_)")
    options.add_overwrite_argument(p, "an existing bag directory")
    from urident.cli.log_args import add_log_arguments

    add_log_arguments(p)
    p.set_defaults(func=run)


def check_bag_output(path: str | Path, overwrite: bool) -> Path:
    """``--bag OUT`` before any work: a new directory in an existing one, or (``--overwrite``) an
    existing bag, never a symbolic link or some other directory or file."""
    from urident.errors import OutputError
    from urident.fileio import check_output
    from urident.logs import is_bag

    path = Path(path)
    if path.is_symlink():
        raise OutputError(f"--bag {path}: is a symbolic link; refusing to write through it")
    if path.exists():
        if not (path.is_dir() and is_bag(path)):
            raise OutputError(f"--bag {path}: exists and is not a rosbag2 bag")
        if not overwrite:
            raise OutputError(f"--bag {path}: exists; pass --overwrite to replace it")
        return path
    return check_output(path, "--bag", overwrite=False)


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.ident.torque import effort_values
    from urident.logs import write_bag
    from urident.cli.log_args import load_log_from_args
    from urident.model import load_robot

    out = check_bag_output(args.bag, args.overwrite)
    recording = load_log_from_args(args.log, args, robot=args.robot)
    robot = args.robot or recording.robot
    if robot is None:
        raise ConfigError(f"{args.log}: the log names no robot; pass --robot")
    spec = load_robot(robot)
    # written beside the target, then moved into place: a failed write leaves nothing behind
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        values, how = effort_values(recording, spec, args.bag_effort)
        write_bag(recording, tmp / out.name, spec.joint_names, effort=args.bag_effort,
                  storage=args.storage, tf_prefix=args.tf_prefix or "", values=values)
        if out.exists():
            os.rename(out, tmp / "replaced")
        os.rename(tmp / out.name, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"wrote {out} ({len(recording)} JointState messages, {args.storage}, "
          f"effort = {args.bag_effort}: {how})")
    return 0
