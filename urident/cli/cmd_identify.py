"""``urident identify``: logs → identified parameters (PARAMS.yaml), comparison report, URDF."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from urident.cli import options


#: The --preset names: urident.ident.presets' PRESETS, then its PRESET_ALIASES (spelled out here so
#: that building the parser does not import the identification package; tests/test_presets.py checks).
PRESET_NAMES = ("paper", "auto", "ur10e-2020", "real-robot", "best")
PRESET_HELP = ("named configuration: 'paper' (the paper's method: full base set, tanh friction, plain "
               "least squares); 'auto', also spelled 'real-robot' and '--model best' (reduced base set, "
               "per-joint weighting, a Dahl presliding Coulomb state, each joint's friction terms chosen "
               "from a family of published forms by 5-fold blocked cross-validation on the identification "
               "logs, then the torque's lead over the motion by the same CV; the report lists the terms, "
               "their gains and what was tried); or 'ur10e-2020' (the one fixed set of terms real-robot meant "
               "before, chosen on a real UR10e's 2020 run: reduced base set, per-joint weighting, Dahl "
               "presliding friction state driven by the integrated velocity with its distance chosen by "
               "5-fold blocked cross-validation on the identification data, load-dependent Coulomb, "
               "square-root viscous and Stribeck friction; equivalent to --reduced --weighting joint "
               "--coulomb dahl --dahl-source velocity --dahl-rad auto --friction-extra "
               "load,sqrtvisc,stribeck --stribeck-vs 0.05). Options given explicitly override the "
               "preset's (auto's friction options and weighting are its own)")


def add_model_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("model and estimation")
    g.add_argument("--preset", "--model", dest="preset", choices=PRESET_NAMES,
                   default=None, help=PRESET_HELP)
    g.add_argument("--reduced", action="store_true", default=None,
                   help="the paper's reduced model (33 base parameters) instead of the full one (52)")
    g.add_argument("--full", dest="reduced", action="store_false",
                   help="the full base set (52 parameters; default unless a preset says otherwise)")
    g.add_argument("--friction-eps", type=options.positive_float, default=None, metavar="E",
                   help="tanh(qd/E) slope of the Coulomb friction [rad/s] (default 0.01, the paper's)")
    g.add_argument("--coulomb", choices=("tanh", "dahl", "hold"), default=None,
                   help="Coulomb friction model: tanh (paper, default); hold (tanh in motion, keeps the "
                        "last motion's friction at standstill); dahl (presliding state driven by the "
                        "displacement, see --dahl-source)")
    g.add_argument("--hold-velocity", type=options.positive_float, default=None, metavar="V",
                   help="hold model: |qd| [rad/s] needed to reverse the friction state (default 3e-4, "
                        "about 5x the standstill velocity noise of the UR10e logs)")
    g.add_argument("--dahl-rad", type=_dahl_rad, default=None, metavar="D",
                   help="Dahl presliding distance [rad] (default 0.01), or 'auto': chosen from "
                        "5e-5..5e-4 rad by 5-fold blocked cross-validation on the identification data")
    g.add_argument("--dahl-source", choices=("position", "velocity"), default=None,
                   help="displacement driving the Dahl state: position (logged q, default) or "
                        "velocity (integral of the logged qd, independent of how finely q is stored)")
    g.add_argument("--friction-extra", type=options.name_list(_extra_features, none="none"),
                   default=None, metavar="LIST",
                   help="extra friction features, comma-separated: offset, stribeck, dahl, load "
                        "(load-dependent Coulomb |tau_nominal|*z), sqrtvisc (sign(qd)*sqrt|qd|); "
                        "'none' for no extras")
    g.add_argument("--stribeck-vs", type=options.positive_float, default=None, metavar="V",
                   help="Stribeck velocity [rad/s] (default 0.05)")
    g.add_argument("--weighting", choices=("none", "joint"), default=None,
                   help="none: the paper's plain least squares (default); joint: rows divided by each "
                        "joint's residual std from a first fit")
    g.add_argument("--regularisation", type=options.nonnegative_float, default=None, metavar="L",
                   help="weight of the prior towards the robot file's parameters in the consistent "
                        "method (default 1e-3)")


def add_preprocess_arguments(p: argparse.ArgumentParser, trim_default: bool = True) -> None:
    g = p.add_argument_group("preprocessing")
    g.add_argument("--filter-hz", type=options.positive_float, default=None, metavar="F",
                   help="corner frequency of the acceleration filter [Hz] (default 10, or the parameters "
                        "file's when predicting; identify --preset auto chooses it by blocked CV unless given)")
    g.add_argument("--torque-filter-hz", type=options.positive_float, default=None, metavar="F",
                   help="zero-phase low-pass of the torques [Hz] (default: off)")
    g.add_argument("--decimate", type=options.int_range(1, 1000), default=None, metavar="K",
                   help="keep every K-th sample")
    g.add_argument("--trim-rest", dest="trim_rest", action="store_true", default=None,
                   help="drop leading/trailing samples at rest" + (" (default)" if trim_default else ""))
    g.add_argument("--no-trim-rest", dest="trim_rest", action="store_false",
                   help="keep leading/trailing samples at rest" + ("" if trim_default else " (default)"))
    g.add_argument("--rest-threshold", type=options.nonnegative_float, default=None, metavar="V",
                   help="all |qd| below V [rad/s] counts as rest (default 0.001)")
    g.add_argument("--drive-gains", type=options.drive_gains, default=None, metavar="G1,...,G6|GAINS.yaml",
                   help="joint-side drive gains i_G*k [N·m/A], or a GAINS.yaml of urident drive-gains (default: the robot file's)")


_PREPROCESS_OPTIONS = ("filter_hz", "torque_filter_hz", "decimate", "trim_rest", "rest_threshold")


def preprocess_overrides(args: argparse.Namespace) -> dict:
    """The preprocessing keys given explicitly on the command line."""
    return {key: getattr(args, key) for key in _PREPROCESS_OPTIONS if getattr(args, key, None) is not None}


def preprocess_config(args: argparse.Namespace, trim_default: bool = True):
    """Identification's preprocessing: the defaults, then the explicit options. (Predicting with a
    parameters file follows that file: ``urident.ident.prediction_config``.)"""
    from dataclasses import replace

    from urident.ident import PreprocessConfig

    return replace(PreprocessConfig(trim_rest=trim_default), **preprocess_overrides(args))


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.cli.log_args import add_log_arguments
    from urident.cli.log_args import add_logs_from_argument

    p = subparsers.add_parser(
        "identify", help="identify dynamic parameters from logs",
        description="Identify base parameters (paper eq. 19-21) from one or more logs. With "
                    "--method all, --out receives the consistent estimate and PARAMS.ols.yaml / "
                    "PARAMS.bounded.yaml the others; a comparison table goes to stdout.")
    p.add_argument("logs", nargs="*", metavar="LOG",
                   help="log files (urident, ur_rtde or --format preset), directories of logs or globs")
    p.add_argument("--robot", required=True, help="robot name (urident model --list) or robot file")
    p.add_argument("--out", required=True, metavar="PARAMS.yaml", help="parameters file to write")
    p.add_argument("--method", choices=("ols", "bounded", "consistent", "all"), default="ols",
                   help="estimation method (default ols, the paper's pseudo-inverse)")
    p.add_argument("--urdf", metavar="OUT", default=None,
                   help="also write a URDF of the physically consistent estimate")
    p.add_argument("--report", metavar="FILE", default=None, help="also write the comparison table here")
    p.add_argument("--png", metavar="DIR", default=None,
                   help="write fit plots (measured vs predicted, base parameters) as PNG here")
    p.add_argument("--sessions", action="store_true",
                   help="each log is a session (another day): fit the shared parameters with, per "
                        "session, a torque offset and a friction scale on the joints where blocked "
                        "cross-validation says they pay (the first log is the reference); the report "
                        "lists them, the parameters file holds the shared model")
    options.add_overwrite_argument(p, "existing parameters, URDF, report and plot files")
    add_model_arguments(p)
    add_preprocess_arguments(p, trim_default=True)
    options.add_payload_argument(p, "the logs carry it; its torque is removed and the arm alone identified")
    add_log_arguments(p)
    add_logs_from_argument(p)
    options.add_rerun_arguments(p, "fit")
    p.set_defaults(func=run)


#: The model options' flags: how --preset and the overrides of
#: :func:`urident.ident.presets.resolve_model` are spelled in its errors.
OPTION_FLAGS = {"preset": "--preset", "reduced": "--reduced", "friction_eps": "--friction-eps",
                "coulomb": "--coulomb", "hold_velocity": "--hold-velocity", "dahl_rad": "--dahl-rad",
                "dahl_source": "--dahl-source", "extras": "--friction-extra", "stribeck_vs": "--stribeck-vs",
                "weighting": "--weighting"}


def model_overrides(args: argparse.Namespace) -> dict:
    """The model options given on the command line (None: not given), keyed as
    :func:`urident.ident.presets.resolve_model` takes them."""
    return {key: getattr(args, "friction_extra" if key == "extras" else key, None)
            for key in OPTION_FLAGS if key != "preset"}


def run(args: argparse.Namespace) -> int:
    from urident import api
    from urident.errors import ConfigError
    from urident.cli.log_args import load_log_from_args
    from urident.cli.log_args import logs_from_args
    from urident.model import load_robot
    from urident.progress import progress_iter

    methods = ("ols", "bounded", "consistent") if args.method == "all" else (args.method,)
    if args.urdf and "consistent" not in methods:
        raise ConfigError("--urdf needs physically consistent parameters: use --method consistent or all")
    # every output checked before the heavy work: none exists (unless --overwrite), none is a link
    out = Path(args.out)
    primary = "consistent" if args.method == "all" else args.method
    options.output_path("--out", out, args.overwrite)
    for m in methods:
        if m != primary:
            options.output_path("--out", api.sibling(out, m), args.overwrite)
    options.output_path("--urdf", args.urdf, args.overwrite)
    options.output_path("--report", args.report, args.overwrite)
    options.output_dir_files("--png", args.png, [f"fit_{m}.png" for m in methods] + ["base_parameters.png"],
                             args.overwrite)
    options.check_rerun_args(args)  # a missing viewer or a bad --save fails at once
    paths = logs_from_args(args.logs, args.logs_from)
    spec = load_robot(args.robot)
    result = api.identify(
        (load_log_from_args(path, args, robot=spec.name) for path in progress_iter(paths, "loading logs")),
        spec, args.method, args.preset, overrides=model_overrides(args), option_names=OPTION_FLAGS,
        preprocess=preprocess_config(args), drive_gains=args.drive_gains,
        payload=options.load_payload_arg(args, spec), regularisation=args.regularisation,
        sessions=args.sessions, select_filter_hz=False if args.filter_hz is not None else None)
    written = [str(p) for p in result.save(out, overwrite=args.overwrite)]
    models, data, text = result.models, result.data, result.report
    print(text)
    if args.report:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.report, text + "\n", overwrite=args.overwrite)
    if args.urdf:
        from urident.ident.urdf import write_urdf

        write_urdf(spec, models["consistent"].standard, args.urdf, overwrite=args.overwrite)
        written.append(args.urdf)
    if args.png:
        from urident.fileio import atomic_output
        from urident.ident import validate
        from urident.viz.plots import plot_base_parameters, plot_torques

        png = Path(args.png)
        png.mkdir(parents=True, exist_ok=True)
        for m, mod in models.items():
            with atomic_output(png / f"fit_{m}.png", args.overwrite, "--png") as tmp:
                plot_torques(validate(mod, spec, data), tmp)
            written.append(str(png / f"fit_{m}.png"))
        with atomic_output(png / "base_parameters.png", args.overwrite, "--png") as tmp:
            plot_base_parameters(models, tmp)
        written.append(str(png / "base_parameters.png"))
    written += _to_rerun(args, spec, models, data, text)
    print("wrote " + ", ".join(written), file=sys.stderr)
    return 0


def _to_rerun(args: argparse.Namespace, spec, models, data, report: str) -> list[str]:
    """The fit on the identification data (measured vs predicted per method) and the report."""
    rec = options.open_recording_from_args(args, "urident_identify")
    if rec is None:
        return []
    from urident.ident import validate
    from urident.viz import close_recording, log_torque_results
    from urident.viz.torque_views import log_text

    fits = [(m, validate(mod, spec, data)) for m, mod in models.items()]
    log_torque_results(rec, spec.joint_names, fits, prefix="identify",
                       title="Identification fit (identification data)")
    log_text(rec, "identify/report", "```\n" + report + "\n```")
    close_recording(rec)
    return [args.rerun_save] if args.rerun_save else []


def _dahl_rad(text: str):
    """``--dahl-rad``: a positive distance [rad] or 'auto'."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return options.positive_float(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"must be a positive distance [rad] or 'auto', not {text!r}") from None


def _extra_features() -> tuple[str, ...]:
    from urident.ident.design import EXTRA_FEATURES

    return tuple(EXTRA_FEATURES)
