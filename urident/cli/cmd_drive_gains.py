"""``urident drive-gains``: the six joint drive gains from a run without and a run with a known load."""

from __future__ import annotations

import argparse
import sys

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.cli.log_args import add_log_arguments

    p = subparsers.add_parser(
        "drive-gains", help="estimate the joint drive gains [N·m/A] from runs without and with a known load",
        description="Estimate the six joint-side drive gains i_G·k [N·m per A] from a run without "
                    "and a run with a payload of known mass (and centre of mass) on the flange: the "
                    "arm's base parameters and the gains are fitted together, the payload's known "
                    "torque fixing their scale (least squares refined by instrumental variables, "
                    "urident.ident.torque). The gains file is accepted by every --drive-gains option.")
    p.add_argument("--robot", required=True, help="robot name or robot file")
    p.add_argument("--without", required=True, nargs="+", metavar="LOG", help="log(s) without the load")
    p.add_argument("--with", dest="with_", required=True, nargs="+", metavar="LOG", help="log(s) with the load")
    options.add_payload_mass_arguments(p, required=True, what="the known load in the --with runs")
    p.add_argument("--out", required=True, metavar="GAINS.yaml", help="drive-gains file to write")
    p.add_argument("--json-out", metavar="FILE", default=None, help="also write the result as JSON")
    p.add_argument("--reduced", action="store_true", help="the reduced base set for the arm")
    options.add_overwrite_argument(p, "existing gains and JSON files")
    add_log_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.api import calibrate_drive_gains
    from urident.cli.log_args import load_log_from_args, refuse_same_logs
    from urident.errors import ConfigError
    from urident.model import load_robot

    options.distinct_outputs(("--out", args.out), ("--json-out", args.json_out),
                             inputs=options.log_inputs("--without", args.without)
                             + options.log_inputs("--with", args.with_))
    options.output_path("--out", args.out, args.overwrite)
    options.output_path("--json-out", args.json_out, args.overwrite)

    rows = getattr(args, "log_rows", None)
    refuse_same_logs([(f"--with {p}", p, rows) for p in args.with_],
                     [(f"--without {p}", p, rows) for p in args.without],
                     "the loaded and the unloaded runs must be two recordings")
    spec = load_robot(args.robot)
    payload = options.point_payload(args, spec)
    if args.log_signal not in (None, "current"):
        raise ConfigError(f"--signal {args.log_signal}: drive gains are estimated from the motor "
                          "currents; leave --signal out or pass --signal current")
    args.log_signal = "current"  # the motor currents, whatever torques the logs also carry
    without, with_ = ([load_log_from_args(p, args, robot=spec.name, say_signal=True) for p in paths]
                      for paths in (args.without, args.with_))
    result = calibrate_drive_gains(without, with_, spec, payload, reduced=args.reduced)
    result.save(args.out, overwrite=args.overwrite)
    print(result.text())
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, result.to_json() + "\n", overwrite=args.overwrite)
    print(f"wrote {args.out}" + (f", {args.json_out}" if args.json_out else ""), file=sys.stderr)
    return 0
