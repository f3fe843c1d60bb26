"""The ``urident`` console script: dispatches to one module per subcommand."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings

from urident.version import __version__
from urident.cli.options import ArgumentParser
from urident.errors import UridentError

# Subcommand modules, in the order `urident --help` lists them (operator's path first).
COMMANDS = (
    "demo",
    "model",
    "excite",
    "check_trajectory",
    "run",
    "identify",
    "payload",
    "drive_gains",
    "validate",
    "gap",
    "export",
    "view",
    "convert",
    "simulate",
    "sim_controller",
)


def get_argument_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog="urident",
        description="Dynamic parameter identification for Universal Robots arms.",
    )
    parser.add_argument("--version", action="version", version=f"urident {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module_name = f"urident.cli.cmd_{name}"
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:  # subcommand not built yet
                continue
            raise
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = get_argument_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a bad option (one line printed, code 2)
        return exc.code if isinstance(exc.code, int) else 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 1
    try:
        with warnings.catch_warnings():
            if not os.environ.get("URIDENT_DEBUG"):   # numpy's floating-point notes: urident's checks name bad values
                warnings.simplefilter("ignore", RuntimeWarning)
            return int(args.func(args) or 0)
    except UridentError as exc:
        print(f"urident: error: {' '.join(str(exc).split())}", file=sys.stderr)   # one line, whatever a library said
        return exc.exit_code
    except KeyboardInterrupt:
        print("urident: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug, not bad input: still one line by default
        if os.environ.get("URIDENT_DEBUG"):
            raise
        print(f"urident: internal error: {type(exc).__name__}: {' '.join(str(exc).split())} "
              f"(run with URIDENT_DEBUG=1 for the traceback, and please report it)", file=sys.stderr)
        return 70


def console() -> None:
    """The ``urident`` console script: :func:`main`, then exit. When a robot link broke during
    the run, ur_rtde's clients must not be destroyed (their destructors can crash the process
    after every file was closed), so the process then ends with ``os._exit``."""
    code = main()
    rtde_io = sys.modules.get("urident.session.rtde_io")
    if rtde_io is not None and rtde_io.links_abandoned():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    console()
