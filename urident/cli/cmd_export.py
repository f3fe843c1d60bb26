"""``urident export``: identified parameters → a simulator model (MJCF for MuJoCo, URDF)."""

from __future__ import annotations

import argparse

from urident.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    from urident.cli.log_args import add_log_arguments

    p = subparsers.add_parser(
        "export", help="write identified parameters as a MuJoCo (MJCF) or URDF model",
        description="Write the physically consistent estimate of PARAMS.yaml as a simulator model: link "
                    "inertials, rotor inertia as joint armature (MJCF only), viscous friction as damping, "
                    "Coulomb friction as frictionloss (MJCF) or <dynamics friction> (URDF), joint limits, "
                    "capsule collision geometry and, with --payload, the payload as a body on the flange. The identified terms the format cannot express are "
                    "listed in the file's header and here, with their share of the torque of the "
                    "--valid logs.")
    p.add_argument("params", metavar="PARAMS.yaml", nargs="?", default=None,
                   help="parameters file (urident identify --method consistent or all)")
    p.add_argument("--nominal", action="store_true",
                   help="instead of PARAMS.yaml: the robot file's nominal values (needs --robot)")
    p.add_argument("--mjcf", metavar="OUT.xml", default=None, help="write an MJCF (MuJoCo) model")
    p.add_argument("--urdf", metavar="OUT.urdf", default=None, help="write a URDF model")
    p.add_argument("--valid", nargs="+", metavar="LOG", default=None,
                   help="validation logs: the share of their torque each inexpressible term carries")
    p.add_argument("--robot", default=None, help="robot (default: the parameters file's)")
    p.add_argument("--name", default=None, help="model name in the files (default ROBOT_identified)")
    options.add_payload_argument(p, "written as a body 'payload' on the flange")
    options.add_overwrite_argument(p, "existing model files")
    add_log_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.ident import load_params, predict_recordings
    from urident.ident.identify import check_compatible
    from urident.ident.urdf import check_exportable, write_urdf
    from urident.cli.log_args import load_log_from_args
    from urident.model import load_robot
    from urident.sim.mjcf import write_mjcf
    from urident.sim.terms import inexpressible_terms

    if not args.mjcf and not args.urdf:
        raise ConfigError("export: give --mjcf OUT.xml and/or --urdf OUT.urdf")
    if bool(args.params) == bool(args.nominal):
        raise ConfigError("export: give PARAMS.yaml or --nominal --robot R")
    options.distinct_outputs(("--mjcf", args.mjcf), ("--urdf", args.urdf),
                             inputs=(("PARAMS.yaml", args.params), ("--payload", args.payload),
                                     *options.log_inputs("--valid", args.valid)))
    options.output_path("--mjcf", args.mjcf, args.overwrite)
    options.output_path("--urdf", args.urdf, args.overwrite)
    if args.nominal:
        return _nominal(args)
    params = load_params(args.params)
    spec = load_robot(args.robot or params.robot)
    if params.robot != spec.name:
        raise ConfigError(f"{args.params}: parameters are for robot {params.robot!r}, not {spec.name!r}")
    check_compatible(params, spec, str(args.params))
    if params.standard is None:
        raise ConfigError(f"{args.params}: no physically consistent estimate (standard_parameters is null): "
                          "identify with --method consistent or all")
    try:
        check_exportable(params.standard, "export")
    except ConfigError as exc:
        raise ConfigError(f"{args.params}: {exc}") from None
    payload = options.load_payload_arg(args, spec)
    data = None
    if args.valid:
        recordings = [load_log_from_args(path, args, robot=spec.name, say_signal=True) for path in args.valid]
        data = predict_recordings(params, recordings, spec, payload=payload).data
    header = [f"exported by urident from {args.params} (robot {spec.name}, method {params.method}, "
              f"Coulomb model {params.model.coulomb_text()}, tanh eps {params.model.friction_eps:g} rad/s)"]
    header += _payload_note(args, payload)
    if data is not None:
        header.append("shares: RMS of the term's torque / RMS of the measured torque on "
                      + ", ".join(str(v) for v in args.valid))
    for fmt, path, write in (("mjcf", args.mjcf, write_mjcf), ("urdf", args.urdf, write_urdf)):
        if not path:
            continue
        terms = inexpressible_terms(params, spec, fmt, data)
        notes = header + [t.line() for t in terms]
        if not terms:
            notes.append("every identified term is expressed")
        kwargs = {"friction_eps": params.model.friction_eps} if fmt == "mjcf" else {}
        write(spec, params.standard, path, name=args.name, notes=notes, overwrite=args.overwrite,
              payload=payload, **kwargs)
        print(f"wrote {path} ({fmt.upper()})")
        for t in terms:
            print(f"  {t.line()}")
        if not terms:
            print("  every identified term is expressed")
    return 0


def _nominal(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.ident.urdf import write_urdf
    from urident.model import load_robot
    from urident.sim.mjcf import write_mjcf

    if not args.robot:
        raise ConfigError("--nominal needs --robot R")
    if args.valid:
        raise ConfigError("--valid: shares are of identified terms; --nominal has none")
    spec = load_robot(args.robot)
    notes = [f"the robot file {spec.source.name}'s nominal values, exported by urident"]
    note = spec.nominal_note()
    if note:
        notes.append(note)
    payload = options.load_payload_arg(args, spec)
    notes += _payload_note(args, payload)
    name = args.name or f"{spec.name}_nominal"
    if args.mjcf:
        write_mjcf(spec, spec.nominal_params, args.mjcf, name=name, notes=notes, overwrite=args.overwrite,
                   payload=payload)
        print(f"wrote {args.mjcf} (MJCF)")
    if args.urdf:
        write_urdf(spec, spec.nominal_params, args.urdf, name=name, notes=notes, overwrite=args.overwrite,
                   payload=payload)
        print(f"wrote {args.urdf} (URDF)")
    return 0


def _payload_note(args: argparse.Namespace, payload) -> list[str]:
    """The header line of ``--payload`` (none without one)."""
    if payload is None:
        return []
    return [f"payload {args.payload} on the flange (body/link 'payload'): {payload.describe()}"]
