"""``urident validate``: predict the torques of other logs with identified parameters."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.cli.cmd_identify import add_preprocess_arguments
    from urident.cli.log_args import add_log_arguments

    p = subparsers.add_parser(
        "validate", help="validate identified parameters on other logs",
        description="Predict the joint torques of LOG(s) with PARAMS.yaml and report the paper's "
                    "normalised error e_N (eq. 22), per-joint RMS [N·m] and relative error rre [%]. "
                    "Preprocessing follows the parameters file (rest trimming off unless asked); "
                    "give --params several times to compare methods.")
    p.add_argument("logs", nargs="+", metavar="LOG")
    p.add_argument("--params", action="append", required=True, metavar="PARAMS.yaml",
                   help="parameters file from urident identify (repeatable)")
    p.add_argument("--robot", default=None, help="robot (default: the parameters file's)")
    p.add_argument("--json-out", metavar="FILE", default=None, help="write the metrics as JSON")
    p.add_argument("--png", metavar="DIR", default=None, help="write measured-vs-predicted plots here")
    p.add_argument("--session-shift", action="store_true",
                   help="also fit, per joint, a torque offset and a friction scale on the logs' residual "
                        "and say how much of the error such a shift of the session explains")
    options.add_overwrite_argument(p, "existing JSON and plot files")
    add_preprocess_arguments(p, trim_default=False)
    options.add_payload_argument(p, "its torque adds to the arm's prediction")
    add_log_arguments(p)
    options.add_rerun_arguments(p, "comparison")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident import api
    from urident.cli.cmd_identify import preprocess_overrides
    from urident.ident import load_params
    from urident.cli.log_args import load_log_from_args
    from urident.model import load_robot
    from urident.progress import progress_iter

    options.output_path("--json-out", args.json_out, args.overwrite)
    options.output_dir_files("--png", args.png, [_png_name(p) for p in args.params], args.overwrite)
    options.check_rerun_args(args)  # before the heavy work: a missing viewer fails at once
    models = [(path, load_params(path)) for path in args.params]
    spec = load_robot(args.robot or models[0][1].robot)
    payload = options.load_payload_arg(args, spec)
    recordings = (load_log_from_args(p, args, robot=spec.name, say_signal=True)
                  for p in progress_iter(args.logs, "loading logs"))
    validation = api.validate([m for _, m in models], recordings, spec, payload=payload,
                              drive_gains=args.drive_gains or None, names=list(args.params),
                              payload_name=args.payload, session_shift=args.session_shift, **preprocess_overrides(args))
    results = list(zip(args.params, validation.results))
    for (path, r), shift in zip(results, validation.shifts):
        print(f"{path} ({r.method}, {r.n_samples} samples): e_N = {r.e_n:.4f}, "
              f"mean RMS {r.mean_rms_nm:.3f} N·m")
        print("  rms_nm  " + " ".join(f"{v:6.2f}" for v in r.rms_nm))
        print("  rre_pct " + " ".join(f"{v:6.1f}" for v in r.rre_pct))
        if shift is not None:
            print(shift.text())
    if not args.drive_gains and any(list(m.drive_gains) == list(spec.drive_gains) for _, m in models):
        note = spec.nominal_note(("torque_constant", "gear_ratio"))
        if note:  # measured torques = the robot file's drive gains × current
            print(note)
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, validation.to_json() + "\n", overwrite=args.overwrite)
    _to_rerun(args, spec, results)
    if args.png:
        from urident.viz.plots import plot_torques

        out = Path(args.png)
        out.mkdir(parents=True, exist_ok=True)
        from urident.fileio import atomic_output

        for k, (path, r) in enumerate(results):
            png = out / _png_name(path)
            with atomic_output(png, args.overwrite, "--png") as tmp:
                plot_torques(r, tmp, title=f"{Path(path).name} ({r.method}): e_N = {r.e_n:.4f}, "
                                           f"mean RMS {r.mean_rms_nm:.2f} N·m")
            print(f"wrote {png}", file=sys.stderr)
    return 0


def _to_rerun(args: argparse.Namespace, spec, results) -> None:
    rec = options.open_recording_from_args(args, "urident_validate")
    if rec is None:
        return
    from urident.viz import close_recording, log_torque_results

    log_torque_results(rec, spec.joint_names, [(Path(p).stem.replace(".", "_"), r) for p, r in results],
                       prefix="validate", title="Validation: measured vs predicted torque")
    close_recording(rec)
    print(f"Rerun recording {options.rerun_destination(args)}", file=sys.stderr)


def _png_name(params_path) -> str:
    return f"validation_{Path(params_path).stem}.png"
