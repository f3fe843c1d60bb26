"""``urident payload``: a tool's ten inertial parameters from logs, the arm's parameters fixed."""

from __future__ import annotations

import argparse
import json
import sys

from urident.cli import options

POLYSCOPE_NOTE = ("the inertia argument: UR's script manual for software 10.6 (PolyScope X; "
                  "manuals/EN/HTML/SW10_6/Content/prod-scriptmanual/G5/set_target_payload.htm) documents set_target_payload(m, cog, inertia=[0, 0, 0, 0, 0, 0], "
                  "transition_time=0), inertia about the centre of mass with flange axes, Ixx..Izz >= 0; "
                  "ur_rtde 1.6.5's control script sends set_target_payload(mass, cog, inertia) only to "
                  "e-Series controllers of software 5.10 or later (its lines tagged $5.10) and "
                  "set_payload(mass, cog), which takes no inertia, to older ones: on PolyScope 5 before "
                  "5.10 and on CB3 (3.x, no evidence found) use set_payload(m, [cx, cy, cz])")


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
    from urident.errors import ConfigError
    from urident.ident import load_params, predict_recordings
    from urident.ident.identify import check_compatible
    from urident.ident.payload import check_same_motion, check_wrist_motion, estimate_payload, since_first_row
    from urident.ident.payload_file import save_payload
    from urident.cli.log_args import load_log_from_args
    from urident.model import load_robot

    options.distinct_outputs(("--out", args.out), ("--json-out", args.json_out),
                             inputs=(("--params", args.params), *options.log_inputs("LOG", args.logs),
                                     *options.log_inputs("--unloaded", args.unloaded)))
    options.output_path("--out", args.out, args.overwrite)
    options.output_path("--json-out", args.json_out, args.overwrite)
    arm = load_params(args.params)
    spec = load_robot(args.robot or arm.robot)
    if arm.robot != spec.name:
        raise ConfigError(f"{args.params}: parameters are for robot {arm.robot!r}, not {spec.name!r}")
    check_compatible(arm, spec, str(args.params))
    if args.mass_range is not None:
        spec.check_rated_payload(args.mass_range[0], f"--mass-range {args.mass_range[0]:g},{args.mass_range[1]:g}")
    recordings = [load_log_from_args(p, args, robot=spec.name, say_signal=True) for p in args.logs]
    prediction = predict_recordings(arm, recordings, spec, drive_gains=args.drive_gains or None)
    unloaded = None
    if args.unloaded_rows is not None and not args.unloaded:
        raise ConfigError("--unloaded-rows needs --unloaded LOG")
    if args.unloaded:
        rows = args.unloaded_rows or getattr(args, "log_rows", None)
        from urident.cli.log_args import refuse_same_logs

        refuse_same_logs([(f"--unloaded {p}", p, rows) for p in args.unloaded],
                         [(f"LOG {p}", p, getattr(args, "log_rows", None)) for p in args.logs],
                         "a tare is a run without the tool")
        tare = [load_log_from_args(p, args, robot=spec.name, rows=args.unloaded_rows, say_signal=True)
                for p in args.unloaded]
        shown_rows = f" rows {rows[0]}-{rows[1]}" if rows else ""
        flag = (f" (--unloaded-rows {rows[0]}-{rows[1]})" if args.unloaded_rows else
                f" (--rows {rows[0]}-{rows[1]})" if rows else "")
        for p, rec in zip(args.unloaded, tare):   # the clearer message first: a still wrist is no tare
            check_wrist_motion(rec.q, f"--unloaded {p}{flag}")
        check_same_motion([(str(p), r.t, r.q) for p, r in zip(args.logs, recordings)],
                          [(f"--unloaded {p}{shown_rows}", r.t, r.q) for p, r in zip(args.unloaded, tare)])
        unloaded = since_first_row(predict_recordings(arm, tare, spec, drive_gains=args.drive_gains or None), tare)
    data = since_first_row(prediction, recordings) if unloaded is not None else prediction.data
    est = estimate_payload(arm, spec, data, args.mass_range, unloaded=unloaded)
    gains = prediction.data.drive_gains
    fit = {"n_samples": est.n_samples, "e_n_arm_alone": float(est.train_e_n_arm),
           "e_n_with_payload": float(est.train_e_n),
           "rms_nm_arm_alone": [float(v) for v in est.train_rms_arm],
           "rms_nm_with_payload": [float(v) for v in est.train_rms],
           "drive_gains": [float(g) for g in gains], "params": str(args.params),
           "unloaded_logs": [str(p) for p in args.unloaded or []]}
    save_payload(est.consistent, args.out, overwrite=args.overwrite, fit=fit)
    bound = est.consistent.info.get("mass_bound_kg")
    fixed = [n for n in _fields() if n not in est.consistent.identifiable and not (bound is not None and n == "m")]
    lines = [f"payload on {spec.name} from {len(args.logs)} log(s), {est.n_samples} samples, arm {args.params}"
             + (f", tare: {len(args.unloaded)} unloaded log(s) of {len(unloaded)} samples, subtracted sample by "
                f"sample from {est.ols.info['tared_samples']} loaded samples (every error of the arm model on "
                "that motion removed)" if unloaded is not None else ""),
             f"  least squares:        {est.ols.describe()}",
             f"  physically consistent: {est.consistent.describe()}",
             f"  sigma: mass {est.ols.sigma['mass_kg']:.4f} kg, centre of mass "
             f"[{', '.join(_mm(v) for v in est.ols.sigma['com_m'])}] mm",
             f"  identifiable: {', '.join(est.consistent.identifiable)}",
             ("  not identifiable (fixed: first moments 0, inertia a point mass's): " + ", ".join(fixed))
             if fixed else "  every parameter identifiable",
             *([] if unloaded is not None else
               ["  (the inertia needs --unloaded, a run of the same trajectory without the tool: the arm "
                "model's own last-body error is of the order of a tool's inertia)"]),
             "  fit rms_nm arm alone   " + " ".join(f"{v:6.2f}" for v in est.train_rms_arm)
             + f"  e_N {est.train_e_n_arm:.4f}",
             "  fit rms_nm with payload " + " ".join(f"{v:6.2f}" for v in est.train_rms)
             + f"  e_N {est.train_e_n:.4f}",
             "  drive gains [N·m/A] " + ", ".join(f"{g:.4g}" for g in gains)
             + (" (given)" if args.drive_gains else " (the parameters file's)"),
             *([est.consistent.urscript(), f"  ({POLYSCOPE_NOTE})"] if bound is None else
               [f"  mass NOT identified: on the --mass-range bound {bound:g} kg (active: the bound, not the "
                f"logs, sets it; least squares {est.ols.mass_kg:.4g} kg); no set_target_payload line: "
                "widen --mass-range or leave it out"])]
    if est.train_e_n > est.train_e_n_arm:
        lines.insert(-1, f"  the payload makes the fit worse than the arm alone (e_N {est.train_e_n:.4f} vs "
                         f"{est.train_e_n_arm:.4f}): do the logs carry this tool?")
    print("\n".join(lines))
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, json.dumps(to_json(est, fit), indent=2) + "\n",
                          overwrite=args.overwrite)
    print(f"wrote {args.out}" + (f", {args.json_out}" if args.json_out else ""), file=sys.stderr)
    return 0


def _fields():
    from urident.ident.payload import PAYLOAD_FIELDS

    return PAYLOAD_FIELDS


def _mm(v: float) -> str:
    return "fixed" if v != v else f"{1000 * v:.1f}"


def _payload_json(p) -> dict:
    from urident.ident.payload_file import to_dict

    d = to_dict(p)
    return {k: d[k] for k in ("mass_kg", "com_m", "inertia_kg_m2", "sigma", "identifiable", "urscript")}


def to_json(est, fit: dict) -> dict:
    out = dict(_payload_json(est.consistent), method="consistent")
    out["least_squares"] = _payload_json(est.ols)
    out["fit"] = fit
    return out
