"""Shared command-line options for subcommands that read logs (identify, validate, gap, view).

    add_log_arguments(parser)                     # --format, --columns, --rows, --drop-bad
    rec = load_log_from_args(args.log, args, robot=args.robot)
    paths = expand_log_paths(args.logs, "LOG")   # directories and globs → one path per log
"""

from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path
from typing import TextIO

from urident.cli.options import checked, log_list_file, row_range
from urident.errors import ConfigError

from .foreign import PRESETS, parse_column_map
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
        help="drop corrupt rows (reported) instead of rejecting the log",
    )


def add_logs_from_argument(parser, flag: str = "--logs-from", dest: str = "logs_from",
                           what: str = "logs") -> None:
    """``--logs-from FILE`` (repeatable): a file listing {what}, one path, directory or glob a line."""
    parser.add_argument(flag, dest=dest, metavar="FILE", action="append", default=[], type=log_list_file,
                        help=f"read {what} from FILE, one path, directory or glob a line ('#' comments)")


LOG_SUFFIXES = (".csv",)


def _is_bag(path: Path) -> bool:
    return (path / "metadata.yaml").is_file()   # a rosbag2 directory is one log


def expand_log_paths(items, what: str = "LOG") -> list[str]:
    """Logs named by ``items``: a file as given; a directory → its ``*.csv`` logs in name order (a
    rosbag2 directory, holding ``metadata.yaml``, is one log); a glob → its matches in name order.
    A directory or glob that names no log is an error (ConfigError naming it)."""
    out: list[str] = []
    for item in items:
        text = str(item)
        p = Path(text)
        if p.is_dir() and not _is_bag(p):
            found = sorted(str(c) for c in p.iterdir() if c.suffix in LOG_SUFFIXES and c.is_file()
                           or c.is_dir() and _is_bag(c))
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
    )
    line = describe_dropped(recording)
    if line:
        print(f"urident: warning: {line}", file=report or sys.stderr)
    return recording
