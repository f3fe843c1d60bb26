"""Shared ``--rerun`` / ``--save`` options for commands that can send results to Rerun
(``identify``, ``validate``, ``gap``). Importing this module does not import ``rerun``.

    add_rerun_arguments(parser)
    ...
    check_rerun_args(args)                    # early: fails fast on a headless --rerun
    rec = open_recording_from_args(args, "urident_validate", blueprint=torque_blueprint())
    if rec is not None:                        # neither option given: nothing asked for
        log_torque_comparison(rec, ...)
        close_recording(rec)
"""

from __future__ import annotations

import argparse
from typing import Any


def add_rerun_arguments(parser: argparse.ArgumentParser, save_flag: str = "--save") -> None:
    """``--rerun [URL]`` (spawn a viewer, or connect to URL) and ``save_flag OUT.rrd``."""
    group = parser.add_argument_group("Rerun output")
    sink = group.add_mutually_exclusive_group()
    sink.add_argument("--rerun", dest="rerun", metavar="URL", nargs="?", const="spawn",
                      default=None,
                      help="show results in a Rerun viewer: spawn one, or connect to URL "
                           "(e.g. rerun+http://127.0.0.1:9876/proxy)")
    sink.add_argument(save_flag, dest="rerun_save", metavar="OUT.rrd", default=None,
                      help="write the Rerun recording to a file (works headless)")


def check_rerun_args(args: argparse.Namespace) -> None:
    """Raise :class:`~urident.viz.recording.ViewerUnavailable` now if ``--rerun`` cannot work."""
    from urident.viz.recording import check_sink

    target = getattr(args, "rerun", None)
    if target is not None:
        check_sink(spawn=target == "spawn", connect=None if target == "spawn" else target)


def open_recording_from_args(args: argparse.Namespace, app_id: str, blueprint: Any = None):
    """The recording the options ask for, or None when neither was given."""
    from urident.viz.recording import open_recording

    save = getattr(args, "rerun_save", None)
    target = getattr(args, "rerun", None)
    if save is None and target is None:
        return None
    if save is not None:
        return open_recording(app_id, save=save, blueprint=blueprint)
    if target == "spawn":
        return open_recording(app_id, spawn=True, blueprint=blueprint)
    return open_recording(app_id, connect=target, blueprint=blueprint)
