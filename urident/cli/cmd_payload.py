"""``urident payload``: a tool's ten inertial parameters from logs, the arm's parameters fixed."""

from __future__ import annotations

import argparse
import sys

from urident.cli import options

def mass_range(text: str) -> tuple[float, float]:
    """``LOW,HIGH`` [kg], 0 < LOW < HIGH (``--mass-range``)."""
    try:
        low, high = options.parse_numbers(text, 2, positive=True)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if not low < high:
        raise argparse.ArgumentTypeError(f"must be LOW,HIGH with LOW < HIGH, not {text!r}")
    return low, high


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.cli.log_args import add_log_arguments

    p = subparsers.add_parser(
        "payload", help="identify a tool's mass, centre of mass and inertia on an identified arm",
        description="With the arm's parameters (PARAMS.yaml from urident identify) fixed, estimate "
                    "the payload's ten inertial parameters (mass, centre of mass in UR's tool "
                    "flange frame, inertia about the centre of mass) by least squares and by a "
                    "physically consistent estimate; report which the logs excite, the fit, and the "
                    "URScript set_target_payload line.")
    p.add_argument("logs", nargs="+", metavar="LOG", help="logs recorded with the tool mounted")
    p.add_argument("--params", required=True, metavar="ARM.yaml", help="the arm's parameters file")
    p.add_argument("--unloaded", nargs="+", metavar="LOG", default=None,
                   help="runs of the same trajectory without the tool (a tare): the arm model's own "
                        "errors on that motion (its last body, friction, offsets) are fit on both and "
                        "removed, which small tools and the inertia need; refused unless each is the "
                        "motion of a loaded log over the selected rows (joints within 0.05 rad)")
    p.add_argument("--unloaded-rows", metavar="FIRST-LAST", type=options.row_range, default=None,
                   help="rows of the --unloaded logs (overrides --rows for them): a tare for a part of "
                        "a loaded run, from a run whose motion starts at another row")
    p.add_argument("--robot", default=None, help="robot (default: the parameters file's)")
    p.add_argument("--out", required=True, metavar="PAYLOAD.yaml", help="payload file to write")
    p.add_argument("--json-out", metavar="FILE", default=None, help="also write the result as JSON")
    p.add_argument("--mass-range", type=mass_range, default=None, metavar="LOW,HIGH",
                   help="bounds on the mass [kg] for the consistent estimate")
    p.add_argument("--drive-gains", type=options.drive_gains, default=None, metavar="G1,...,G6|GAINS.yaml",
                   help="joint-side drive gains [N·m/A] (default: the parameters file's)")
    options.add_overwrite_argument(p, "existing payload and JSON files")
    add_log_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.api import identify_payload
    from urident.cli.log_args import load_log_from_args, refuse_same_logs
    from urident.errors import ConfigError
    from urident.ident import load_params
    from urident.model import load_robot

    options.distinct_outputs(("--out", args.out), ("--json-out", args.json_out),
                             inputs=(("--params", args.params), *options.log_inputs("LOG", args.logs),
                                     *options.log_inputs("--unloaded", args.unloaded)))
    options.output_path("--out", args.out, args.overwrite)
    options.output_path("--json-out", args.json_out, args.overwrite)
    arm = load_params(args.params)
    spec = load_robot(args.robot or arm.robot)
    if args.unloaded_rows is not None and not args.unloaded:
        raise ConfigError("--unloaded-rows needs --unloaded LOG")
    rows = args.unloaded_rows or getattr(args, "log_rows", None)
    if args.unloaded:
        refuse_same_logs([(f"--unloaded {p}", p, rows) for p in args.unloaded],
                         [(f"LOG {p}", p, getattr(args, "log_rows", None)) for p in args.logs],
                         "a tare is a run without the tool")
    loaded = [load_log_from_args(p, args, robot=spec.name, say_signal=True) for p in args.logs]
    tare = [load_log_from_args(p, args, robot=spec.name, rows=args.unloaded_rows, say_signal=True)
            for p in args.unloaded or []]
    shown_rows = f" rows {rows[0]}-{rows[1]}" if rows else ""
    flag = (f" (--unloaded-rows {rows[0]}-{rows[1]})" if args.unloaded_rows else
            f" (--rows {rows[0]}-{rows[1]})" if rows else "")
    result = identify_payload(loaded, arm, spec, unloaded=tare or None, mass_range=args.mass_range,
                              drive_gains=args.drive_gains or None, params_label=str(args.params),
                              unloaded_labels=[f"--unloaded {p}{shown_rows}" for p in args.unloaded or []],
                              unloaded_wrist_labels=[f"--unloaded {p}{flag}" for p in args.unloaded or []])
    result.save(args.out, overwrite=args.overwrite)
    print(result.text())
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, result.to_json() + "\n", overwrite=args.overwrite)
    print(f"wrote {args.out}" + (f", {args.json_out}" if args.json_out else ""), file=sys.stderr)
    return 0
