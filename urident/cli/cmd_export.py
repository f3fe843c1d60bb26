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
    from urident.api import export_model
    from urident.cli.log_args import load_log_from_args
    from urident.errors import ConfigError
    from urident.ident import load_params
    from urident.model import load_robot
    from urident.sim.export import exportable

    if not args.mjcf and not args.urdf:
        raise ConfigError("export: give --mjcf OUT.xml and/or --urdf OUT.urdf")
    if bool(args.params) == bool(args.nominal):
        raise ConfigError("export: give PARAMS.yaml or --nominal --robot R")
    options.distinct_outputs(("--mjcf", args.mjcf), ("--urdf", args.urdf),
                             inputs=(("PARAMS.yaml", args.params), ("--payload", args.payload),
                                     *options.log_inputs("--valid", args.valid)))
    options.output_path("--mjcf", args.mjcf, args.overwrite)
    options.output_path("--urdf", args.urdf, args.overwrite)
    outputs = [(fmt, path) for fmt, path in (("mjcf", args.mjcf), ("urdf", args.urdf)) if path]
    if args.nominal:
        if not args.robot:
            raise ConfigError("--nominal needs --robot R")
        if args.valid:
            raise ConfigError("--valid: shares are of identified terms; --nominal has none")
        spec = load_robot(args.robot)
        payload = options.load_payload_arg(args, spec)
        for fmt, path in outputs:
            done = export_model(None, path, format=fmt, robot=spec, name=args.name, payload=payload,
                                payload_label=args.payload, overwrite=args.overwrite)
            print(done.lines()[0])
        return 0
    params = load_params(args.params)
    spec = load_robot(args.robot or params.robot)
    exportable(params, spec, str(args.params))
    payload = options.load_payload_arg(args, spec)
    recordings = [load_log_from_args(path, args, robot=spec.name, say_signal=True) for path in args.valid or ()]
    for fmt, path in outputs:
        done = export_model(params, path, format=fmt, robot=spec, name=args.name, payload=payload,
                            valid_logs=recordings, overwrite=args.overwrite, label=str(args.params),
                            payload_label=args.payload, valid_labels=[str(v) for v in args.valid or ()])
        print("\n".join(done.lines()))
    return 0
