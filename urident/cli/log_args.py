"""Shared command-line options for subcommands that read logs (identify, validate, gap, view).

    add_log_arguments(parser)   # --format, --columns, --rows, --drop-bad, --topic, --effort, --signal,
                                # --allow-aborted, --allow-gaps
    rec = load_log_from_args(args.log, args, robot=args.robot)   # refuses aborted/gapped logs unless allowed
    paths = expand_log_paths(args.logs, "LOG")   # directories and globs → one path per log
"""

from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path
from typing import TextIO

from urident.cli.options import checked, log_list_file, ros_topic, row_range
from urident.errors import ConfigError, LogFormatError

from urident.logs.foreign import PRESETS, parse_column_map
from urident.logs.gaps import describe_gaps, recording_gaps
from urident.logs.reader import describe_dropped, load_log
from urident.logs.rosbag import is_bag
from urident.logs.sidecar import describe_declared_payload
from urident.logs.recording import Recording


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
        choices=("current", "torque", "compensated"),
        help="rosbag2 input: JointState effort holds motor currents [A] (UR's released drivers), "
        "full joint torques [N·m], or UR's gravity-compensated torques [N·m] (the driver with "
        "use_currents_as_efforts false; its main branch's default); default: detected from the "
        "effort at standstill (docs/signals.md), asked for when the bag cannot tell",
    )
    group.add_argument(
        "--signal",
        dest="log_signal",
        default=None,
        choices=("current", "torque", "compensated"),
        help="torques from current x drive gains, the log's full joint torques, or its "
        "gravity-compensated ones with the nominal model's gravity added back (no gravity terms "
        "identified); default: the full torques when the log carries valid ones, else the "
        "current (docs/signals.md)",
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


def add_logs_from_argument(parser, flag: str = "--logs-from", dest: str = "logs_from",
                           what: str = "logs") -> None:
    """``--logs-from FILE`` (repeatable): a file listing {what}, one path, directory or glob a line."""
    parser.add_argument(flag, dest=dest, metavar="FILE", action="append", default=[], type=log_list_file,
                        help=f"read {what} from FILE, one path, directory or glob a line ('#' comments)")


LOG_SUFFIXES = (".csv",)


def expand_log_paths(items, what: str = "LOG") -> list[str]:
    """Logs named by ``items``: a file as given; a directory → its ``*.csv`` logs in name order (a
    rosbag2 directory, holding ``metadata.yaml``, is one log); a glob → its matches in name order.
    a rosbag2 ``.mcap``/``.db3`` file is one log too. A directory or glob that names no log is an error (ConfigError naming it)."""
    out: list[str] = []
    for item in items:
        text = str(item)
        p = Path(text)
        if p.is_dir() and not is_bag(p):
            found = sorted(str(c) for c in p.iterdir() if c.is_file() and (c.suffix in LOG_SUFFIXES or is_bag(c))
                           or c.is_dir() and is_bag(c))
            if not found:
                raise ConfigError(f"{what} {text}: directory holds no log (*.csv or rosbag2 directory)")
            out += found
        elif glob.has_magic(text) and not p.exists():
            found = sorted(glob.glob(text))
            if not found:
                raise ConfigError(f"{what} {text}: no log matches")
            out += found
        else:
            out.append(text)
    return out


def logs_from_args(positional, lists, what: str = "LOG") -> list[str]:
    """Expanded logs of a positional list plus every ``--logs-from`` list; at least one."""
    items = list(positional or []) + [x for lst in (lists or []) for x in lst]
    if not items:
        raise ConfigError(f"no {what} given (name logs, a directory, a glob or --logs-from FILE)")
    return expand_log_paths(items, what)


def load_log_from_args(
    path: str | Path,
    args: argparse.Namespace,
    robot: str | None = None,
    report: TextIO | None = None,
    rows: tuple[int, int] | None = None,
    say_signal: bool = False,
) -> Recording:
    """``load_log`` with the options of :func:`add_log_arguments`; prints the drop report
    (to stderr by default) when rows were dropped. ``rows`` overrides ``--rows`` (a command's
    rows for one group of its logs: ``gap --ident-rows``, ``payload --unloaded-rows``).
    ``say_signal``: print which signal gives the torques (to ``report`` or stdout; commands that
    fit or compare them)."""
    recording = load_log(
        path,
        robot=robot,
        rows=getattr(args, "log_rows", None) if rows is None else rows,
        drop_bad=getattr(args, "log_drop_bad", False),
        column_map=getattr(args, "log_columns", None),
        format=getattr(args, "log_format", None),
        topic=getattr(args, "log_topic", None),
        effort=getattr(args, "log_effort", None),
        signal=getattr(args, "log_signal", None),
    )
    line = describe_dropped(recording)
    if line:
        print(f"urident: warning: {line}", file=report or sys.stderr)
    declared = describe_declared_payload(recording.metadata)
    if declared:  # every report that loads the log says what the controller was told
        print(f"{path}: {declared}", file=report or sys.stderr)
    if say_signal:  # and which signal gives its torques, with the correction applied
        from urident.ident.torque import describe_signal

        try:
            line = describe_signal(recording)
        except ConfigError as exc:
            raise LogFormatError(str(exc)) from None
        print(line, file=report or sys.stdout)  # a report line: stderr stays for warnings and errors
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
    # stretches a loader excluded on purpose (a bag's protective stops) are reported, not gaps
    excluded = recording.metadata.get("excluded") or []
    gaps = [g for g in recording_gaps(recording)
            if not any(g.t_before < e["start_s"] and e["end_s"] < g.t_after for e in excluded)]
    if gaps and not allow_gaps:
        raise LogFormatError(f"{where}: {describe_gaps(gaps)}; pass --allow-gaps to use it "
                             f"(the pieces between gaps are then processed separately)")


def log_identity(path: str | Path, rows: tuple[int, int] | None) -> tuple[str, tuple[int, int] | None]:
    """(content hash, rows) of a log as a command reads it: two names of one content (a copy, a
    link) with the same rows are the same data."""
    from urident.logs.sidecar import sha256_file

    p = Path(path)
    try:
        return sha256_file(p), rows
    except OSError:      # unreadable: the loader names it; here the name stands for the content
        return f"path:{p.resolve()}", rows


def refuse_same_logs(these, others, why: str) -> None:
    """ConfigError when a log of ``these`` holds the same data (content and rows,
    :func:`log_identity`) as one of ``others``; both are sequences of (label, path, rows), the
    label naming the flag and path; ``why`` says what the two groups must be."""
    seen = {log_identity(path, rows): label for label, path, rows in others}
    for label, path, rows in these:
        other = seen.get(log_identity(path, rows))
        if other is not None:
            shown_rows = f" rows {rows[0]}-{rows[1]}" if rows else ""
            raise ConfigError(f"{label}: the same data as {other}{shown_rows} (identical content): {why}")
