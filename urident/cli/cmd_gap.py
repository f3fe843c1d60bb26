"""``urident gap``: diagnose the sim-to-real gap of the paper's baseline model: where the
validation residual lies, which unmodelled effect of the catalogue causes it, how far it shrinks."""

from __future__ import annotations

import argparse
import sys

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "gap", help="diagnose the sim-to-real gap: where, which unmodelled effect, how far it shrinks",
        description="Identify the paper's baseline model (OLS, tanh friction, eps = 0.01 rad/s) on "
                    "the identification logs (or load it with --params), explain its residual on the "
                    "validation logs: where it concentrates (velocity, load, angle, time, "
                    "frequency), which effect of the catalogue explains it (held-out scores with "
                    "block-bootstrap intervals, stepwise selection, confounds: of two "
                    "explanations the data cannot tell apart, the one with fewer coefficients is "
                    "named and the other listed) and how far it shrinks (validation RMS per joint "
                    "and e_N, measured torque = drive gains x raw current). When the logs hold the "
                    "controller's target moment, its agreement with the measured torque and with "
                    "the identified rigid-body model is shown beside.")
    p.add_argument("--robot", required=True, help="robot name or robot file")
    p.add_argument("--ident", nargs="+", default=[], metavar="LOG",
                   help="identification log(s), directories of logs or globs (required unless --sim)")
    p.add_argument("--valid", nargs="+", default=[], metavar="LOG",
                   help="validation log(s), directories of logs or globs")
    p.add_argument("--params", metavar="FILE", default=None,
                   help="baseline parameters (PARAMS.yaml of 'urident identify') instead of "
                        "identifying them on the --ident logs")
    p.add_argument("--sim", metavar="MODEL.xml|MODEL.urdf", default=None,
                   help="baseline: your simulator model as it is (MJCF through MuJoCo's inverse dynamics, "
                        "URDF through Pinocchio and its <dynamics>); candidates add armature, damping, "
                        "frictionloss, per-link mass/CoM, payload and drive-gain corrections")
    p.add_argument("--joint-map", metavar="ROBOT=MODEL,...", type=options.joint_map, default=None,
                   help="with --sim: the model's joint for each of the robot's (shoulder_pan=joint1,...), or the "
                        "model's six joint names in the robot's order (default: its six hinge joints, or those "
                        "named like the robot's)")
    p.add_argument("--write-sim", metavar="OUT.xml|OUT.urdf", default=None,
                   help="with --sim: write the model with every finding its format can express")
    p.add_argument("--json-out", metavar="FILE", default=None, help="write the full report as JSON")
    options.add_overwrite_argument(p, "an existing JSON report or .rrd file")
    p.add_argument("--ident-rows", metavar="FIRST-LAST", type=options.row_range, default=None,
                   help="rows of the identification logs (overrides --rows for them)")
    p.add_argument("--valid-rows", metavar="FIRST-LAST", type=options.row_range, default=None,
                   help="rows of the validation logs (overrides --rows for them)")
    p.add_argument("--check", nargs="+", metavar="LOG", default=None,
                   help="held-out log(s), used neither for identification nor for selection: each "
                        "finding's predicted and checked shrink with a 95 %% interval; a finding "
                        "that does not hold there is marked")
    p.add_argument("--check-rows", metavar="FIRST-LAST", type=options.row_range, default=None,
                   help="rows of the check logs (overrides --rows for them)")
    p.add_argument("--drive-gains", metavar="G1,...,G6|GAINS.yaml", type=options.drive_gains, default=None,
                   help="N·m per A of motor current (default: the parameters file's or robot file's)")
    options.add_payload_argument(p, "every log carries it; its torque is removed from the measured torque")
    p.add_argument("--effects", metavar="NAMES", type=options.name_list(_catalogue), default=None,
                   help="comma-separated subset of the catalogue to test (default: all; names as in "
                        "'urident simulate --list-effects')")
    p.add_argument("--min-shrink", dest="min_shrink_pct", type=options.percentage, default=None, metavar="PCT",
                   help="a finding must shrink its joint's validation RMS by at least this "
                        "(default 3; see docs/gap-calibration.md)")
    p.add_argument("--cv-min-noise", dest="cv_min_noise_ratio", type=options.nonnegative_float,
                   default=0.5,
                   metavar="RATIO",
                   help="a finding fitted inside the validation logs (CV mode) must correct its "
                        "joint by an RMS of at least RATIO x the joint's white-noise torque "
                        "(default 0.5; 0 turns the floor off)")
    p.add_argument("--max-effects", type=options.int_range(1, 40), default=None, metavar="N",
                   help="at most this many effects (stepwise selection, default 3; 30 with --sim)")
    p.add_argument("--seed", type=options.seed, default=0, help="bootstrap seed (default 0)")
    options.add_rerun_arguments(p, "residual maps and comparison")
    from urident.cli.log_args import add_log_arguments
    from urident.cli.log_args import add_logs_from_argument

    add_log_arguments(p)
    add_logs_from_argument(p, "--ident-from", "ident_from", "identification logs")
    add_logs_from_argument(p, "--valid-from", "valid_from", "validation logs")
    p.set_defaults(func=run)


def _load_all(paths, args, rows_text, robot, what):
    from urident.cli.log_args import load_log_from_args
    from urident.progress import progress_iter

    return [load_log_from_args(path, args, robot=robot, rows=rows_text, say_signal=True)
            for path in progress_iter(paths, f"loading {what} logs")]


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from urident.gap import GapConfig, diagnose, format_report
    from urident.gap.report import logs_used
    from urident.errors import ConfigError
    from urident.gap.candidates import EFFECTS
    from urident.cli.log_args import expand_log_paths, logs_from_args
    from urident.model import load_robot
    from urident.progress import Working

    options.check_rerun_args(args)
    options.output_path("--json-out", args.json_out, args.overwrite)
    options.distinct_outputs(("--json-out", args.json_out), ("--write-sim", args.write_sim),
                             ("--save", getattr(args, "rerun_save", None)))
    if args.check_rows is not None and not args.check:
        raise ConfigError("--check-rows needs --check LOG")
    if args.sim and args.check:
        raise ConfigError("--check is not available with --sim (the held-out check tests the paper "
                          "baseline's findings); leave one out")
    if args.sim or args.write_sim or args.joint_map:
        from urident.cli.gap_sim import run_sim

        return run_sim(args, _load_all)
    if not args.ident and not args.ident_from:
        raise ConfigError("--ident LOG is required (or --sim MODEL for a simulator model's gap)")
    effects = args.effects or EFFECTS
    floor = {} if args.min_shrink_pct is None else {"min_shrink_pct": args.min_shrink_pct}
    config = GapConfig(effects=effects, **floor, cv_min_noise_ratio=args.cv_min_noise_ratio,
                       max_effects=args.max_effects or 3, seed=args.seed)
    spec = load_robot(args.robot)
    params = None
    if args.params:
        from urident.ident import load_params

        params = load_params(args.params)
    drive_gains = None if args.drive_gains is None else np.array(args.drive_gains)
    ident_paths = logs_from_args(args.ident, args.ident_from, "--ident")
    valid_paths = logs_from_args(args.valid, args.valid_from, "--valid")
    if args.check:
        _refuse_reused(args, ident_paths, valid_paths)
    ident = _load_all(ident_paths, args, args.ident_rows, spec.name, "identification")
    valid = _load_all(valid_paths, args, args.valid_rows, spec.name, "validation")
    if args.check:
        check_logs = _load_all(expand_log_paths(args.check, "--check"), args, args.check_rows, spec.name, "check")
    with Working("gap: diagnosis"):
        result = diagnose(ident, valid, spec, params=params, drive_gains=drive_gains, config=config,
                          payload=options.load_payload_arg(args, spec))
    print(format_report(result))
    if args.check:
        from dataclasses import replace

        from urident.gap.check import check_findings, format_check

        result = replace(result, check=check_findings(result, check_logs, spec, drive_gains=drive_gains,
                                                      params=params))
        print()
        print(format_check(result.check))
    print(logs_used(ident, "identification logs used"))
    print(logs_used(valid, "validation logs used"))
    note = spec.nominal_note(None if drive_gains is None else ("inertia_com", "rotor_inertia",
                                                              "viscous_friction", "coulomb_friction"))
    if note:
        print(note)
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, result.to_json(), fsync=False, overwrite=args.overwrite)
        print(f"\nreport written to {args.json_out}")
    rec = options.open_recording_from_args(args, "urident_gap")
    if rec is not None:
        from urident.viz.gap_view import log_gap_result

        log_gap_result(rec, result, spec)
        print(f"residual maps {options.rerun_destination(args)}", file=sys.stdout)
    return 0


def _refuse_reused(args, ident_paths, valid_paths) -> None:
    """A check log must be held out: the same data (content, by hash, and rows) as an
    identification or validation log is refused (another row range of the same file is fine)."""
    from urident.cli.log_args import expand_log_paths, refuse_same_logs

    rows = lambda r: r if r is not None else getattr(args, "log_rows", None)   # noqa: E731
    used = [(f"--ident {p}", p, rows(args.ident_rows)) for p in ident_paths]
    used += [(f"--valid {p}", p, rows(args.valid_rows)) for p in valid_paths]
    check = [(f"--check {p}", p, rows(args.check_rows)) for p in expand_log_paths(args.check, "--check")]
    refuse_same_logs(check, used, "a check log must be held out (give another log or another --check-rows range)")


def _catalogue() -> tuple[str, ...]:
    from urident.gap.candidates import EFFECTS

    return tuple(EFFECTS)
