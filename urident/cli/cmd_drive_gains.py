"""``urident drive-gains``: the six joint drive gains from a run without and a run with a known load."""

from __future__ import annotations

import argparse
import json
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


METHOD = ("joint least squares of the arm's base parameters, a constant torque per joint and six gains on both runs (payload "
          "torque known, point mass unless an inertia is given), refined by two instrumental-"
          "variable iterations (instruments: the currents the first fit predicts)")


#: A joint counts as calibrated when its gain's relative σ is at most this [%]: the load's torque
#: on it is well above the noise (a load on the flange axis gives joint 6 none, for one).
CALIBRATED_PCT = 1.0


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from urident.errors import ConfigError
    from urident.ident import PreprocessConfig, prepare
    from urident.ident.gains_file import save_gains
    from urident.ident.payload import check_wrist_motion
    from urident.ident.torque import DriveGainError, estimate_drive_gains, gain_problem
    from urident.cli.log_args import load_log_from_args
    from urident.cli.log_args import refuse_same_logs
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
    runs = []
    for what, paths in (("--without", args.without), ("--with", args.with_)):
        recs = [load_log_from_args(p, args, robot=spec.name, say_signal=True) for p in paths]
        data = prepare(recs, spec, PreprocessConfig(), np.ones(6))   # tau = current [A]
        runs.append((data.q, data.qd, data.qdd, data.tau))
    check_wrist_motion(runs[1][0], "--with logs")
    try:
        est = estimate_drive_gains(spec, runs[0], runs[1], payload.body_params(spec), reduced=args.reduced,
                                   offset=True)
    except DriveGainError as exc:
        hint = ": are --with and --without swapped?" if exc.swapped else ""
        raise ConfigError(f"--with {' '.join(args.with_)}: {exc}{hint}") from None
    rel = 100 * est.sigma / np.abs(est.gains)
    calibrated = [bool(r <= CALIBRATED_PCT) for r in rel]
    kept = []          # joints the runs do not calibrate whose estimate is no drive's: robot file's value
    for j in range(6):
        problem = gain_problem(est.gains, spec.drive_gains, joints=[j])
        if problem and calibrated[j]:
            raise ConfigError(f"--with {' '.join(args.with_)}: {problem}: "
                              "are --with and --without swapped, the load and its --payload-mass/--payload-com "
                              "as given?")
        if problem:
            kept.append(j)
    gains = np.array([spec.drive_gains[j] if j in kept else g for j, g in enumerate(est.gains)])
    data = {"without": list(args.without), "with": list(args.with_), "payload_mass_kg": args.payload_mass,
            "payload_com_m": [float(v) for v in payload.com_m],
            "robot_file_gains": [float(g) for g in spec.drive_gains], "robot_file_gain_kept": [j + 1 for j in kept]}
    save_gains(args.out, spec.name, gains, est.sigma, METHOD, data, overwrite=args.overwrite)
    data["calibrated"] = calibrated
    print(f"drive gains on {spec.name} [N·m/A] (robot file: "
          + ", ".join(f"{g:.4g}" for g in spec.drive_gains) + ")")
    for j, (g, s, r, g0) in enumerate(zip(est.gains, est.sigma, rel, spec.drive_gains)):
        verdict = "" if calibrated[j] else f"  NOT calibrated (σ > {CALIBRATED_PCT:g} %): keep another value"
        if j in kept:
            verdict = (f"  NOT calibrated (σ > {CALIBRATED_PCT:g} %) and no drive's gain: the robot file's "
                       f"{g0:.4g} written")
        print(f"  joint {j + 1}: {g:9.4f} ± {s:.4f} ({r:.2f} %), {100 * (g / g0 - 1):+.1f} % vs the "
              f"robot file{verdict}")
    print(f"  method: {METHOD}")
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, json.dumps({"drive_gains": [float(g) for g in gains],
                                                     "sigma": [float(s) for s in est.sigma],
                                                     "method": METHOD, "robot": spec.name, **data},
                                                    indent=2) + "\n", overwrite=args.overwrite)
    print(f"wrote {args.out}" + (f", {args.json_out}" if args.json_out else ""), file=sys.stderr)
    return 0
