"""``urident model``: parameter counts and base-parameter expressions of a robot."""

from __future__ import annotations

import argparse
import json


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("model", help="show a robot's standard and base parameters",
                              description="Print the parameter counts and the base parameters "
                                          "(paper section III-D) as linear combinations of "
                                          "standard parameters.")
    p.add_argument("--robot", required=True, help="robot name (ur5, ur5e, ur10e) or robot file")
    p.add_argument("--reduced", action="store_true",
                   help="the paper's reduced model (no products of inertia, one CoM axis per body)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.model import load_robot
    from urident.model.base import base_parameters
    from urident.model.parameters import N_PARAMS

    spec = load_robot(args.robot)
    base = base_parameters(spec, reduced=args.reduced)
    expressions = base.expressions()
    if args.json:
        print(json.dumps({
            "robot": spec.name,
            "reduced": bool(args.reduced),
            "n_params": N_PARAMS,
            "n_modelled": int(len(base.modelled)),
            "n_base": base.n_base,
            "base_parameters": [{"name": n, "expression": e} for n, e in zip(base.names, expressions)],
        }, indent=2))
        return 0
    print(f"{spec.description}: {spec.controller_rate_hz:g} Hz controller")
    print(f"standard parameters: {N_PARAMS} ({len(base.modelled)} modelled"
          f"{', paper reduced model' if args.reduced else ''}); base parameters: {base.n_base}")
    width = max(len(n) for n in base.names)
    for k, (name, expr) in enumerate(zip(base.names, expressions), start=1):
        print(f"  {k:2d}  {name:<{width}} = {expr}")
    print("names: m = mass, mrx/mry/mrz = m·ρ (centre of mass), A..F inertia about K_i "
          "(J = [[A,-F,-E],[-F,B,-D],[-E,-D,C]]), IM = i_G²·C_M rotor, fv/fc = viscous/Coulomb friction")
    return 0
