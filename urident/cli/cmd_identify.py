"""``urident identify``: logs → identified parameters (PARAMS.yaml), comparison report, URDF."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


PRESET_HELP = ("named configuration: 'paper' (the paper's method: full base set, tanh friction, plain "
               "least squares) or 'real-robot' (urident's best on real UR logs: reduced base set, "
               "per-joint weighting, Dahl presliding friction state driven by the integrated "
               "velocity with its distance chosen by 5-fold blocked cross-validation on the "
               "identification data, load-dependent Coulomb, square-root viscous and Stribeck friction; "
               "equivalent to --reduced --weighting joint --coulomb dahl --dahl-source velocity "
               "--dahl-rad auto --friction-extra load,sqrtvisc,stribeck --stribeck-vs 0.05). Options given explicitly override "
               "the preset's")


def add_model_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("model and estimation")
    g.add_argument("--preset", "--model", dest="preset", choices=("paper", "real-robot", "best"),
                   default=None, help=PRESET_HELP + " ('--model best' is an alias of real-robot)")
    g.add_argument("--reduced", action="store_true", default=None,
                   help="the paper's reduced model (33 base parameters) instead of the full one (52)")
    g.add_argument("--full", dest="reduced", action="store_false",
                   help="the full base set (52 parameters; default unless a preset says otherwise)")
    g.add_argument("--friction-eps", type=float, default=None, metavar="E",
                   help="tanh(qd/E) slope of the Coulomb friction [rad/s] (default 0.01, the paper's)")
    g.add_argument("--coulomb", choices=("tanh", "dahl", "hold"), default=None,
                   help="Coulomb friction model: tanh (paper, default); hold (tanh in motion, keeps the "
                        "last motion's friction at standstill); dahl (presliding state driven by the "
                        "displacement, see --dahl-source)")
    g.add_argument("--hold-velocity", type=float, default=None, metavar="V",
                   help="hold model: |qd| [rad/s] needed to reverse the friction state (default 3e-4, "
                        "about 5x the standstill velocity noise of the UR10e logs)")
    g.add_argument("--dahl-rad", default=None, metavar="D",
                   help="Dahl presliding distance [rad] (default 0.01), or 'auto': chosen from "
                        "5e-5..5e-4 rad by 5-fold blocked cross-validation on the identification data")
    g.add_argument("--dahl-source", choices=("position", "velocity"), default=None,
                   help="displacement driving the Dahl state: position (logged q, default) or "
                        "velocity (integral of the logged qd, independent of how finely q is stored)")
    g.add_argument("--friction-extra", default=None, metavar="LIST",
                   help="extra friction features, comma-separated: offset, stribeck, dahl, load "
                        "(load-dependent Coulomb |tau_nominal|*z), sqrtvisc (sign(qd)*sqrt|qd|); "
                        "'none' for no extras")
    g.add_argument("--stribeck-vs", type=float, default=None, metavar="V",
                   help="Stribeck velocity [rad/s] (default 0.05)")
    g.add_argument("--weighting", choices=("none", "joint"), default=None,
                   help="none: the paper's plain least squares (default); joint: rows divided by each "
                        "joint's residual std from a first fit")
    g.add_argument("--regularisation", type=float, default=None, metavar="L",
                   help="weight of the prior towards the robot file's parameters in the consistent "
                        "method (default 1e-3)")


def add_preprocess_arguments(p: argparse.ArgumentParser, trim_default: bool = True) -> None:
    g = p.add_argument_group("preprocessing")
    g.add_argument("--filter-hz", type=float, default=None, metavar="F",
                   help="corner frequency of the acceleration filter [Hz] (default 10)")
    g.add_argument("--torque-filter-hz", type=float, default=None, metavar="F",
                   help="zero-phase low-pass of the torques [Hz] (default: off)")
    g.add_argument("--decimate", type=int, default=None, metavar="K", help="keep every K-th sample")
    g.add_argument("--trim-rest", dest="trim_rest", action="store_true", default=None,
                   help="drop leading/trailing samples at rest" + (" (default)" if trim_default else ""))
    g.add_argument("--no-trim-rest", dest="trim_rest", action="store_false",
                   help="keep leading/trailing samples at rest" + ("" if trim_default else " (default)"))
    g.add_argument("--rest-threshold", type=float, default=None, metavar="V",
                   help="all |qd| below V [rad/s] counts as rest (default 0.001)")
    g.add_argument("--drive-gains", default=None, metavar="G1,...,G6",
                   help="joint-side drive gains i_G*k [N·m/A] (default: the robot file's)")


def preprocess_config(args: argparse.Namespace, base=None, trim_default: bool = True):
    from dataclasses import replace

    from urident.ident import PreprocessConfig

    cfg = base or PreprocessConfig(trim_rest=trim_default)
    changes = {}
    for attr, key in (("filter_hz", "filter_hz"), ("torque_filter_hz", "torque_filter_hz"),
                      ("decimate", "decimate"), ("trim_rest", "trim_rest"),
                      ("rest_threshold", "rest_threshold")):
        value = getattr(args, attr, None)
        if value is not None:
            changes[key] = value
    if base is not None:
        # validating: the acceleration filter follows the parameters file, but the torques are the
        # raw measured ones, every sample is used and rest is kept unless asked otherwise
        for key, default in (("trim_rest", trim_default), ("torque_filter_hz", None), ("decimate", 1)):
            if getattr(args, key, None) is None:
                changes[key] = default
    return replace(cfg, **changes)


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.logs import add_log_arguments

    p = subparsers.add_parser(
        "identify", help="identify dynamic parameters from logs",
        description="Identify base parameters (paper eq. 19-21) from one or more logs. With "
                    "--method all, --out receives the consistent estimate and PARAMS.ols.yaml / "
                    "PARAMS.bounded.yaml the others; a comparison table goes to stdout.")
    p.add_argument("logs", nargs="+", metavar="LOG", help="log files (urident, ur_rtde or --format preset)")
    p.add_argument("--robot", required=True, help="robot name (urident model --list) or robot file")
    p.add_argument("--out", required=True, metavar="PARAMS.yaml", help="parameters file to write")
    p.add_argument("--method", choices=("ols", "bounded", "consistent", "all"), default="ols",
                   help="estimation method (default ols, the paper's pseudo-inverse)")
    p.add_argument("--urdf", metavar="OUT", default=None,
                   help="also write a URDF of the physically consistent estimate")
    p.add_argument("--report", metavar="FILE", default=None, help="also write the comparison table here")
    p.add_argument("--png", metavar="DIR", default=None,
                   help="write fit plots (measured vs predicted, base parameters) as PNG here")
    add_model_arguments(p)
    add_preprocess_arguments(p, trim_default=True)
    add_log_arguments(p)
    from urident.viz.cli_args import add_rerun_arguments

    add_rerun_arguments(p)
    p.set_defaults(func=run)


def preset_name(args: argparse.Namespace) -> str | None:
    name = getattr(args, "preset", None)
    return "real-robot" if name == "best" else name


def model_config(args: argparse.Namespace):
    """(ModelConfig, weighting, select_dahl_rad) from the preset (if any) and explicit options."""
    from dataclasses import replace

    from urident.errors import ConfigError
    from urident.ident import ModelConfig
    from urident.ident.presets import get_preset

    name = preset_name(args)
    preset = get_preset(name) if name else None
    base = preset.model if preset else ModelConfig()
    weighting = args.weighting or (preset.weighting if preset else "none")
    select = bool(preset and preset.select_dahl_rad)
    changes = {}
    for attr in ("reduced", "friction_eps", "coulomb", "hold_velocity", "dahl_source", "stribeck_vs"):
        value = getattr(args, attr, None)
        if value is not None:
            changes[attr] = value
    if args.dahl_rad is not None:
        if str(args.dahl_rad).strip().lower() == "auto":
            select = True
        else:
            try:
                changes["dahl_rad"] = float(args.dahl_rad)
            except ValueError:
                raise ConfigError(f"--dahl-rad {args.dahl_rad!r}: expected a distance [rad] or 'auto'") from None
            select = False
    if args.friction_extra is not None:
        text = args.friction_extra.strip()
        changes["extras"] = () if text.lower() == "none" else tuple(
            x.strip() for x in text.split(",") if x.strip())
    model = replace(base, **changes)
    uses_dahl = model.coulomb == "dahl" or "dahl" in model.extras
    if select and not uses_dahl:
        if str(args.dahl_rad or "").strip().lower() == "auto":
            raise ConfigError("--dahl-rad auto needs a Dahl state: --coulomb dahl or --friction-extra dahl")
        select = False   # the preset's δ selection is moot once the Dahl state is overridden
    return model, weighting, select


def sibling(path: Path, method: str) -> Path:
    return path.with_name(f"{path.stem}.{method}{path.suffix or '.yaml'}")


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.ident import identify_all, prepare, save_params
    from urident.ident.estimate_consistent import DEFAULT_REGULARISATION
    from urident.ident.report import comparison_report
    from urident.ident.torque import resolve_drive_gains
    from urident.logs import load_log_from_args
    from urident.model import load_robot

    from urident.viz.cli_args import check_rerun_args

    check_rerun_args(args)  # before the heavy work: a missing viewer fails at once
    spec = load_robot(args.robot)
    model, weighting, select = model_config(args)
    config = preprocess_config(args)
    gains = resolve_drive_gains(spec, args.drive_gains)
    recordings = [load_log_from_args(path, args, robot=spec.name) for path in args.logs]
    data = prepare(recordings, spec, config, gains)
    cv_text = ""
    if select:
        from urident.ident.crossval import select_dahl_rad
        from urident.ident.presets import CV_FOLDS, DAHL_GRID

        model, scores = select_dahl_rad(spec, data, model, DAHL_GRID, weighting, "ols", CV_FOLDS)
        cv_text = (f"dahl_rad selected by {CV_FOLDS}-fold blocked CV on the identification data: "
                   f"{model.dahl_rad:g} rad (mean held-out RMS [N·m] per distance: "
                   + ", ".join(f"{s.model.dahl_rad:g}: {s.mean_rms_nm:.3f}" for s in scores) + ")")
    methods = ("ols", "bounded", "consistent") if args.method == "all" else (args.method,)
    if args.urdf and "consistent" not in methods:
        raise ConfigError("--urdf needs physically consistent parameters: use --method consistent or all")
    reg = DEFAULT_REGULARISATION if args.regularisation is None else args.regularisation
    models = identify_all(spec, data, methods, model, weighting, reg, config)
    out = Path(args.out)
    primary = "consistent" if args.method == "all" else args.method
    save_params(models[primary], out)
    written = [str(out)]
    for m in methods:
        if m != primary:
            save_params(models[m], sibling(out, m))
            written.append(str(sibling(out, m)))
    text = comparison_report(models)
    if preset_name(args):
        text = f"preset {preset_name(args)}\n" + text
    if cv_text:
        text = cv_text + "\n" + text
    priors = ("inertia_com", "rotor_inertia", "viscous_friction", "coulomb_friction")
    note = spec.nominal_note(priors + (("torque_constant", "gear_ratio") if args.drive_gains is None else ()))
    if note:  # torques from currents use the file's torque constants; priors and bounds its values
        text = text + "\n" + note
    print(text)
    if args.report:
        Path(args.report).write_text(text + "\n")
    if args.urdf:
        from urident.ident.urdf import write_urdf

        write_urdf(spec, models["consistent"].standard, args.urdf)
        written.append(args.urdf)
    if args.png:
        from urident.ident import validate
        from urident.viz.plots import plot_base_parameters, plot_torques

        png = Path(args.png)
        png.mkdir(parents=True, exist_ok=True)
        for m, mod in models.items():
            written.append(str(plot_torques(validate(mod, spec, data), png / f"fit_{m}.png")))
        written.append(str(plot_base_parameters(models, png / "base_parameters.png")))
    written += _to_rerun(args, spec, models, data, text)
    print("wrote " + ", ".join(written), file=sys.stderr)
    return 0


def _to_rerun(args: argparse.Namespace, spec, models, data, report: str) -> list[str]:
    """The fit on the identification data (measured vs predicted per method) and the report."""
    from urident.viz.cli_args import open_recording_from_args

    rec = open_recording_from_args(args, "urident_identify")
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
