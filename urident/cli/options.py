"""Command-line conventions shared by every subcommand, in one place.

* :class:`ArgumentParser`: a bad flag value, a missing or unknown option ends in ONE line
  ``urident: error: argument --harmonics: must be an integer from 2 to 100, not '1' (see ...)``,
  exit 2.
* Validators for ``type=``: they run at parse time, so a bad value never reaches the
  (possibly slow, possibly moving) command, and argparse prefixes the flag's own name.
* The Rerun options, spelled one way on every command that can show results:
  ``--rerun [URL]`` (spawn a viewer, or connect to URL) and ``--save OUT.rrd`` (write a file).
* :func:`output_path`: an output flag's value checked before any heavy work
  (:func:`urident.fileio.check_output`), naming the flag.

The library raises errors naming keys (``FILE: key.path: message``); these name flags.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import Any, Callable

from urident.errors import shown

N_JOINTS = 6


class ArgumentParser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block) and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        text = " ".join(message.split())
        self.exit(2, f"urident: error: {text} (see '{self.prog} --help')\n")


def _fail(what: str, text: str) -> argparse.ArgumentTypeError:
    return argparse.ArgumentTypeError(f"must be {what}, not {shown(text)!r}")


def _float(text: str, what: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise _fail(what, text) from None
    if not math.isfinite(value):
        raise _fail(what, text)
    return value


def finite_float(text: str) -> float:
    """Any finite number."""
    return _float(text, "a finite number")


def positive_float(text: str) -> float:
    value = _float(text, "a positive number")
    if value <= 0:
        raise _fail("a positive number", text)
    return value


def nonnegative_float(text: str) -> float:
    value = _float(text, "a non-negative number")
    if value < 0:
        raise _fail("a non-negative number", text)
    return value


def fraction(text: str) -> float:
    """A number in (0, 1]."""
    value = _float(text, "a number in (0, 1]")
    if not 0 < value <= 1:
        raise _fail("a number in (0, 1]", text)
    return value


def percentage(text: str) -> float:
    """A number in [0, 100]."""
    value = _float(text, "a percentage in [0, 100]")
    if not 0 <= value <= 100:
        raise _fail("a percentage in [0, 100]", text)
    return value


def int_range(low: int | None = None, high: int | None = None) -> Callable[[str], int]:
    """An integer in [low, high] (either bound may be open)."""
    if low is not None and high is not None:
        what = f"an integer from {low} to {high}"
    elif low is not None:
        what = "a positive integer" if low == 1 else f"an integer >= {low}"
    elif high is not None:
        what = f"an integer <= {high}"
    else:
        what = "an integer"

    def parse(text: str) -> int:
        try:
            value = int(str(text).strip())
        except (TypeError, ValueError):
            raise _fail(what, text) from None
        if (low is not None and value < low) or (high is not None and value > high):
            raise _fail(what, text)
        return value

    parse.__name__ = "integer"
    parse.bounds = (low, high)  # type: ignore[attr-defined]
    return parse


positive_int = int_range(1)
nonnegative_int = int_range(0)
seed = int_range(0, 2**32 - 1)  # numpy's seed range


def parse_numbers(text: str, n: int = N_JOINTS, positive: bool = False) -> tuple[float, ...]:
    """The one parser of "N comma-separated numbers" (joint vectors, drive gains). Raises
    ValueError with a message fit to follow a flag or key name."""
    what = f"{n} comma-separated {'positive' if positive else 'finite'} numbers"
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise ValueError(f"must be {what}, not {shown(text)!r}") from None
    if len(values) != n:
        raise ValueError(f"must be {what}, not {len(values)} values")
    if not all(math.isfinite(v) and (v > 0 or not positive) for v in values):
        raise ValueError(f"must be {what}, not {shown(text)!r}")
    return values


def joint_vector(text: str) -> tuple[float, ...]:
    """Six finite numbers, one per joint (``--q0``, ``--initial-q``)."""
    try:
        return parse_numbers(text, N_JOINTS)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def drive_gains(text: str) -> tuple[float, ...]:
    """Six positive joint-side drive gains i_G·k [N·m/A] (``--drive-gains``): a comma list or a
    GAINS.yaml of ``urident drive-gains`` (read now: a bad file fails at parse time)."""
    if "," not in str(text) and str(text).strip().lower().endswith((".yaml", ".yml")):
        from urident.errors import ConfigError
        from urident.ident.gains_file import load_gains

        try:
            return tuple(float(g) for g in load_gains(text)[1])
        except ConfigError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    try:
        return parse_numbers(text, N_JOINTS, positive=True)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def row_range(text: str) -> tuple[int, int]:
    """``FIRST-LAST`` data rows, 1-based and inclusive (``--rows``, ``--ident-rows``, ...)."""
    from urident.logs.reader import parse_row_range

    try:
        return parse_row_range(text)
    except (ValueError, argparse.ArgumentTypeError) as exc:
        raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1] if ": " in str(exc) else str(exc)) \
            from None


_ROS_TOPIC = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$")


def ros_topic(text: str) -> str:
    """A fully qualified ROS 2 topic name (``/joint_states``, ``/ur/joint_states``): a bag
    records topics with their namespace."""
    if not _ROS_TOPIC.match(text):
        raise _fail("a fully qualified ROS 2 topic name such as /joint_states", text)
    return text


_TF_PREFIX = re.compile(r"^[A-Za-z][A-Za-z0-9_/]*[_/]$")


def tf_prefix(text: str) -> str:
    """A tf_prefix of UR's driver (``ur_``, ``left/``): prepended to the joint names."""
    if not _TF_PREFIX.match(text):
        raise _fail("a tf_prefix ending in _ or / such as ur_", text)
    return text


def joint_map(text: str) -> dict[str, str]:
    """``ROBOT=MODEL,...`` (the robot file's joint names to a model's) or six model joint names in
    the robot's joint order (keys "0" … "5")."""
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise _fail("six joint names, or ROBOT=MODEL pairs", text)
    if all("=" not in s for s in items):
        if len(items) != N_JOINTS:
            raise _fail(f"{N_JOINTS} joint names in the robot's order (got {len(items)}), or ROBOT=MODEL pairs", text)
        out = {str(i): s for i, s in enumerate(items)}
    else:
        out = {}
        for s in items:
            key, sep, value = s.partition("=")
            if not sep or not key.strip() or not value.strip() or key.strip() in out:
                raise _fail("ROBOT=MODEL pairs, each robot joint once", text)
            out[key.strip()] = value.strip()
    if len(set(out.values())) != len(out):
        raise _fail("pairs naming each model joint once", text)
    return out


def checked(parse: Callable[[str], Any]) -> Callable[[str], str]:
    """A validator from a library parser (raising ValueError/ConfigError): the text is checked at
    parse time and kept as given."""

    def check(text: str) -> str:
        try:
            parse(text)
        except (ValueError, TypeError) as exc:
            message = re.sub(r"^--[\w-]+ ('[^']*': )", r"\1", " ".join(str(exc).split()))  # argparse names the flag
            raise argparse.ArgumentTypeError(message) from None
        return text

    check.__name__ = getattr(parse, "__name__", "value")
    return check


def name_list(choices: Callable[[], tuple[str, ...]] | tuple[str, ...],
              none: str | None = None) -> Callable[[str], tuple[str, ...]]:
    """Comma-separated names, each one of ``choices`` (a tuple, or a function returning one so
    that the heavy module defining them is imported only when the flag is given); ``none``: a
    word meaning the empty list."""

    def parse(text: str) -> tuple[str, ...]:
        known = tuple(choices() if callable(choices) else choices)
        if none is not None and text.strip().lower() == none:
            return ()
        names = tuple(x.strip() for x in text.split(",") if x.strip())
        if not names:
            raise argparse.ArgumentTypeError(f"must name at least one of {', '.join(known)}")
        for name in names:
            if name not in known:
                raise argparse.ArgumentTypeError(
                    f"unknown name {shown(name)!r}; choose from {', '.join(known)}"
                    + (f" or '{none}'" if none else ""))
        if len(set(names)) != len(names):
            raise argparse.ArgumentTypeError(f"lists a name twice: {shown(text)!r}")
        return names

    parse.__name__ = "names"
    parse.choices = choices  # type: ignore[attr-defined]
    return parse


def float_range(low: float, high: float) -> Callable[[str], float]:
    """A number in (low, high]."""
    what = f"a number in ({low:g}, {high:g}]"

    def parse(text: str) -> float:
        value = _float(text, what)
        if not low < value <= high:
            raise _fail(what, text)
        return value

    parse.__name__ = "number"
    parse.bounds = (low, high)  # type: ignore[attr-defined]
    return parse


# -- outputs ------------------------------------------------------------------------------------

def output_path(flag: str, path: str | Path | None, overwrite: bool, suffix: str | None = None,
                directory: bool = False) -> Path | None:
    """Check an output flag's target now, before any work: see :func:`urident.fileio.check_output`
    (``directory``: the flag names a directory to create or fill, e.g. ``--png DIR``)."""
    if path is None:
        return None
    from urident.fileio import check_output, check_output_dir

    if directory:
        return check_output_dir(path, flag)
    path = Path(path)
    if suffix is not None and path.suffix != suffix:
        from urident.errors import ConfigError

        raise ConfigError(f"{flag} {path}: must end in {suffix}")
    return check_output(path, flag, overwrite)


def distinct_outputs(*outputs: tuple[str, str | Path | None],
                     inputs: tuple[tuple[str, str | Path | None], ...] = ()) -> None:
    """``(flag, path)`` outputs of one command: refused now when two name one file, or one names an
    input (:func:`urident.fileio.check_distinct_outputs`)."""
    from urident.fileio import check_distinct_outputs

    check_distinct_outputs(outputs, inputs)


def log_inputs(flag: str, paths) -> tuple[tuple[str, Path], ...]:
    """Input logs for :func:`distinct_outputs`: each path and, for a CSV log, its sidecar."""
    from urident.logs.schema import sidecar_path

    out = []
    for p in paths or ():
        out.append((flag, Path(p)))
        if Path(p).suffix == ".csv":
            out.append((flag, sidecar_path(Path(p))))
    return tuple(out)


def output_dir_files(flag: str, directory: str | Path | None, names, overwrite: bool) -> None:
    """``--png DIR``-style outputs: the directory (created later if missing) and, if it exists,
    each of the files ``names`` the command will write into it."""
    if directory is None:
        return
    output_path(flag, directory, overwrite, directory=True)
    if Path(directory).is_dir():
        for name in names:
            output_path(flag, Path(directory) / name, overwrite)


def log_output(flag: str, path: str | Path | None, overwrite: bool) -> Path | None:
    """A log to write (``LOG.csv`` + ``LOG.yaml``; ``.csv`` is added when missing): both files
    checked now, before any motion or simulation."""
    if path is None:
        return None
    from urident.fileio import check_output
    from urident.logs.schema import sidecar_path

    path = Path(path)
    if path.is_dir() or path.is_symlink():
        check_output(path, flag, overwrite)  # says which
    if path.suffix != ".csv":
        path = path.with_suffix(".csv")
    check_output(path, flag, overwrite)
    check_output(sidecar_path(path), flag, overwrite)
    return path


def add_overwrite_argument(parser: argparse.ArgumentParser, what: str = "existing outputs") -> None:
    parser.add_argument("--overwrite", action="store_true", help=f"replace {what} (default: refuse)")


# -- Rerun --------------------------------------------------------------------------------------

def add_rerun_arguments(parser: argparse.ArgumentParser, what: str = "results") -> None:
    """``--rerun [URL]`` and ``--save OUT.rrd``, mutually exclusive, on every command."""
    group = parser.add_argument_group("Rerun output")
    sink = group.add_mutually_exclusive_group()
    sink.add_argument("--rerun", dest="rerun", metavar="URL", nargs="?", const="spawn", default=None,
                      help=f"show the {what} in a Rerun viewer: spawn one, or connect to URL "
                           "(e.g. rerun+http://127.0.0.1:9876/proxy)")
    sink.add_argument("--save", dest="rerun_save", metavar="OUT.rrd", default=None,
                      help=f"write the {what} to a Rerun recording file (works headless)")


def rerun_sink(args: argparse.Namespace, default_spawn: bool = False) -> dict[str, Any] | None:
    """``{save, spawn, connect}`` for :func:`urident.viz.recording.open_recording`, or None when
    neither option was given (and ``default_spawn`` is false)."""
    save = getattr(args, "rerun_save", None)
    target = getattr(args, "rerun", None)
    if save is not None:
        return {"save": save, "spawn": False, "connect": None}
    if target is None:
        return {"save": None, "spawn": True, "connect": None} if default_spawn else None
    if target == "spawn":
        return {"save": None, "spawn": True, "connect": None}
    return {"save": None, "spawn": False, "connect": target}


def check_rerun_args(args: argparse.Namespace, default_spawn: bool = False) -> None:
    """Fail now (one line) if the Rerun sink asked for cannot work: a viewer that cannot be
    spawned or reached, or a ``--save`` target that is not a writable new ``.rrd`` file."""
    sink = rerun_sink(args, default_spawn)
    if sink is None:
        return
    if sink["save"] is not None:
        output_path("--save", sink["save"], getattr(args, "overwrite", False), suffix=".rrd")
        return
    from urident.viz.recording import check_sink

    check_sink(spawn=sink["spawn"], connect=sink["connect"])


def open_recording_from_args(args: argparse.Namespace, app_id: str, blueprint: Any = None,
                             default_spawn: bool = False):
    """The recording the options ask for, or None when none was asked for."""
    sink = rerun_sink(args, default_spawn)
    if sink is None:
        return None
    from urident.viz.recording import open_recording

    return open_recording(app_id, blueprint=blueprint, overwrite=getattr(args, "overwrite", False),
                          **sink)


def rerun_destination(args: argparse.Namespace) -> str:
    save = getattr(args, "rerun_save", None)
    return f"saved to {save}" if save else "sent to the viewer"


# -- payload ------------------------------------------------------------------------------------

def add_payload_argument(parser: argparse.ArgumentParser, what: str = "predict with it") -> None:
    """``--payload PAYLOAD.yaml`` (from ``urident payload``): a tool on the flange."""
    parser.add_argument("--payload", metavar="PAYLOAD.yaml", default=None,
                        help=f"a tool mounted on the flange (file of 'urident payload'): {what}")


def load_payload_arg(args: argparse.Namespace, spec):
    """The ``--payload`` file for robot ``spec``, or None; one-line error naming the file."""
    path = getattr(args, "payload", None)
    if path is None:
        return None
    from urident.ident.payload_file import load_payload

    payload = load_payload(path, spec)
    print(f"payload {path}: {payload.describe()}", file=sys.stderr)
    return payload


def payload_com(text: str) -> tuple[float, ...]:
    """``--payload-com x,y,z`` [m]: a load's centre of mass in the tool flange frame."""
    try:
        return parse_numbers(text, 3)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_payload_mass_arguments(parser: argparse.ArgumentParser, required: bool = False,
                               what: str = "a point mass on the flange") -> None:
    """``--payload-mass KG [--payload-com X,Y,Z]``: a load known by its mass and centre of mass."""
    parser.add_argument("--payload-mass", type=positive_float, required=required, metavar="KG",
                        help=f"the load's mass [kg]: {what}")
    parser.add_argument("--payload-com", type=payload_com, default=None, metavar="X,Y,Z",
                        help="its centre of mass in the tool flange frame [m] (default 0,0,0)")


def point_payload(args: argparse.Namespace, spec):
    """The ``--payload-mass``/``--payload-com`` load as a point mass, or None without a mass."""
    if getattr(args, "payload_mass", None) is None:
        if getattr(args, "payload_com", None) is not None:
            from urident.errors import ConfigError

            raise ConfigError("--payload-com needs --payload-mass")
        return None
    import numpy as np

    from urident.model.payload import Payload

    com = (0.0, 0.0, 0.0) if args.payload_com is None else args.payload_com
    spec.check_rated_payload(args.payload_mass, "--payload-mass")
    spec.check_tool_com(com, "--payload-com")
    return Payload(spec.name, args.payload_mass, com, np.zeros((3, 3)))


def add_checked_payload_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--payload PAYLOAD.yaml`` or ``--payload-mass KG [--payload-com X,Y,Z]``: the load the
    dense torque check includes (``excite``, ``check-trajectory``, ``run``)."""
    add_payload_argument(parser, what)
    add_payload_mass_arguments(parser, what="the torque checks include it, as --payload does")


def checked_payload(args: argparse.Namespace, spec, recorded=None, recorded_source: str = ""):
    """(payload, source) for the torque checks: ``--payload`` or ``--payload-mass`` (exclusive),
    else ``recorded`` (a trajectory file's), else (None, "empty flange"); ConfigError above the
    robot's rated payload."""
    from urident.errors import ConfigError

    if getattr(args, "payload", None) is not None and getattr(args, "payload_mass", None) is not None:
        raise ConfigError("--payload and --payload-mass are exclusive: give the load once")
    payload, source = load_payload_arg(args, spec), f"--payload {getattr(args, 'payload', None)}"
    if payload is None:
        payload, source = point_payload(args, spec), "--payload-mass"
    if payload is None:
        payload, source = recorded, recorded_source
    if payload is None:
        return None, "empty flange"
    spec.check_rated_payload(payload.mass_kg, source)
    return payload, source


def tool_capsule(text: str):
    """``--tool-capsule RADIUS,LENGTH`` [m]: a tool's bounding capsule on the flange, its axis from
    the flange centre LENGTH out along the flange z axis (:class:`urident.model.robot.ToolCapsule`);
    RADIUS > 0, LENGTH ≥ 0."""
    from urident.model.robot import ToolCapsule

    parts = [p.strip() for p in str(text).split(",")]
    try:
        radius, length = (float(p) for p in parts)
        return ToolCapsule(radius, length)
    except ValueError as exc:
        detail = str(exc) if str(exc).startswith("tool capsule") else f"not {shown(text)!r}"
        raise argparse.ArgumentTypeError(f"must be RADIUS,LENGTH in metres (radius > 0, length >= 0): "
                                         f"{detail}") from None


def add_tool_capsule_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tool-capsule", type=tool_capsule, default=None, metavar="RADIUS,LENGTH",
                        help="a tool on the flange for the collision checks: a capsule of RADIUS [m] "
                             "whose axis runs LENGTH [m] from the flange centre along the flange z "
                             "axis (default: the --payload file's capsule, if any)")


def log_list_file(text: str) -> tuple[str, ...]:
    """``--logs-from FILE``: the logs listed in FILE, one path (or directory, or glob) a line;
    blank lines and ``#`` comments skipped, relative paths taken from FILE's directory."""
    path = Path(text)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise argparse.ArgumentTypeError(f"no such file: {shown(text)!r}") from None
    except IsADirectoryError:
        raise argparse.ArgumentTypeError(f"{shown(text)!r} is a directory, not a list of logs") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise argparse.ArgumentTypeError(f"cannot read {shown(text)!r}: {exc}") from None
    out = []
    for line in lines:
        item = line.split("#", 1)[0].strip()
        if item:
            out.append(item if Path(item).is_absolute() else str(path.parent / item))
    if not out:
        raise argparse.ArgumentTypeError(f"{shown(text)!r} lists no log")
    return tuple(out)
