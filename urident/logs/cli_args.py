"""Shared command-line options for subcommands that read logs (identify, validate, gap, view).

    add_log_arguments(parser)   # --format, --columns, --rows, --drop-bad, --topic, --effort, --signal,
                                # --allow-aborted, --allow-gaps
    rec = load_log_from_args(args.log, args, robot=args.robot)   # refuses aborted/gapped logs unless allowed
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import TextIO

from urident.cli.options import checked, ros_topic, row_range
from urident.errors import LogFormatError

from .foreign import PRESETS, parse_column_map
from .gaps import describe_gaps, recording_gaps
from .reader import describe_dropped, load_log
from .recording import Recording


def add_log_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the log-reading options to a subcommand parser."""
    group = parser.add_argument_group("log input")
    presets = ", ".join(f"{k} ({v[1]})" for k, v in PRESETS.items())
    group.add_argument(
        "--format",
        dest="log_format",
        metavar="NAME",
        default=None,
        choices=("urident", "ur_rtde", "columns", *PRESETS),
        help="log format: urident, ur_rtde (auto-detected) or a preset for headerless CSVs: "
        + presets,
    )
    group.add_argument(
        "--columns",
        dest="log_columns",
        metavar="MAP",
        default=None,
        type=checked(parse_column_map),
        help="column map of a headerless CSV, 0-based, stop excluded: "
        "'t=0,q=1:7,qd=7:13,current=13:19' or a layout 't,q,qd,i'",
    )
    group.add_argument(
        "--rows",
        dest="log_rows",
        metavar="FIRST-LAST",
        default=None,
        type=row_range,
        help="use data rows FIRST..LAST only (1-based, inclusive, header not counted)",
    )
    group.add_argument(
        "--drop-bad",
        dest="log_drop_bad",
        action="store_true",
        help="drop corrupt rows or bag messages (reported) instead of rejecting the log",
    )
    group.add_argument(
        "--topic",
        dest="log_topic",
        metavar="TOPIC",
        default=None,
        type=ros_topic,
        help="rosbag2 input: the sensor_msgs/JointState topic (default /joint_states)",
    )
    group.add_argument(
        "--effort",
        dest="log_effort",
        default=None,
        choices=("current", "torque"),
        help="rosbag2 input: JointState effort holds motor currents (default, UR's driver) or "
        "joint torques",
    )
    group.add_argument(
        "--signal",
        dest="log_signal",
        default=None,
        choices=("torque", "current"),
        help="torques from the log's joint torques or from current x drive gains (default: the "
        "joint torques when the log carries valid ones, else the current)",
    )
    group.add_argument(
        "--allow-aborted",
        dest="log_allow_aborted",
        action="store_true",
        help="use a log whose run was aborted (or whose writer died) instead of refusing it",
    )
    group.add_argument(
        "--allow-gaps",
        dest="log_allow_gaps",
        action="store_true",
        help="use a log with missing samples instead of refusing it; the pieces between gaps "
        "are then processed separately",
    )


def load_log_from_args(
    path: str | Path,
    args: argparse.Namespace,
    robot: str | None = None,
    report: TextIO | None = None,
) -> Recording:
    """``load_log`` with the options of :func:`add_log_arguments`; prints the drop report
    (to stderr by default) when rows were dropped."""
    recording = load_log(
        path,
        robot=robot,
        rows=getattr(args, "log_rows", None),
        drop_bad=getattr(args, "log_drop_bad", False),
        column_map=getattr(args, "log_columns", None),
        format=getattr(args, "log_format", None),
        topic=getattr(args, "log_topic", None),
        effort=getattr(args, "log_effort", None),
    )
    signal = getattr(args, "log_signal", None)
    if signal is not None:  # read by urident.ident.torque.torque_signal
        metadata = {**recording.metadata, "signal": signal}
        if signal == "current":
            recording = dataclasses.replace(recording, tau=None, metadata=metadata)
        elif recording.tau is None:
            raise LogFormatError(f"{path}: --signal torque: the log carries no joint torque "
                                 "(actual_current_as_torque, or a bag read with --effort torque)")
        else:
            recording = dataclasses.replace(recording, metadata=metadata)
    line = describe_dropped(recording)
    if line:
        print(f"urident: warning: {line}", file=report or sys.stderr)
    check_log_usable(recording, allow_aborted=getattr(args, "log_allow_aborted", False),
                     allow_gaps=getattr(args, "log_allow_gaps", False))
    for note in recording.metadata.get("notes") or ():  # what a bag loader decided (time source, stops)
        print(f"urident: note: {note}", file=report or sys.stderr)
    return recording


def check_log_usable(recording: Recording, allow_aborted: bool = False,
                     allow_gaps: bool = False) -> None:
    """Refuse (one line) a log whose run did not complete or that misses samples, unless allowed."""
    where = recording.source or "log"
    status = recording.status
    if status in ("aborted", "running") and not allow_aborted:
        why = recording.metadata.get("abort_reason") if status == "aborted" else None
        what = f"the run was aborted ({why})" if why else (
            "the run was aborted" if status == "aborted" else
            "its writer never closed it (status: running)")
        raise LogFormatError(f"{where}: {what}; pass --allow-aborted to use it anyway")
    gaps = recording_gaps(recording)
    if gaps and not allow_gaps:
        raise LogFormatError(f"{where}: {describe_gaps(gaps)}; pass --allow-gaps to use it "
                             f"(the pieces between gaps are then processed separately)")
