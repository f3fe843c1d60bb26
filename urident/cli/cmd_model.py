"""``urident model``: the robots urident knows, a robot file's check, and a robot's parameter
counts and base-parameter expressions."""

from __future__ import annotations

import argparse
import json


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("model", help="show a robot's standard and base parameters",
                              description="Print the parameter counts and the base parameters "
                                          "(paper section III-D) as linear combinations of "
                                          "standard parameters.")
    p.add_argument("--robot", help="robot name (see --list) or robot file")
    p.add_argument("--list", action="store_true",
                   help="list every built-in robot with its generation, rate, reach and payload")
    p.add_argument("--check", action="store_true",
                   help="validate the robot file: frames vs its DH table, limits, masses, collision "
                        "capsules; exit 2 with one line per problem")
    p.add_argument("--reduced", action="store_true",
                   help="the paper's reduced model (no products of inertia, one CoM axis per body)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.errors import ConfigError
    from urident.model import load_robot
    from urident.model.base import base_parameters
    from urident.model.parameters import N_PARAMS

    if args.list:
        return _list(args.json)
    if not args.robot:
        raise ConfigError("model: give --robot NAME_OR_FILE (or --list)")
    spec = load_robot(args.robot)
    if args.check:
        return _check(spec)
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
    note = spec.nominal_note()
    if note:
        print(note)
    print(f"standard parameters: {N_PARAMS} ({len(base.modelled)} modelled"
          f"{', paper reduced model' if args.reduced else ''}); base parameters: {base.n_base}")
    width = max(len(n) for n in base.names)
    for k, (name, expr) in enumerate(zip(base.names, expressions), start=1):
        print(f"  {k:2d}  {name:<{width}} = {expr}")
    print("names: m = mass, mrx/mry/mrz = m·ρ (centre of mass), A..F inertia about K_i "
          "(J = [[A,-F,-E],[-F,B,-D],[-E,-D,C]]), IM = i_G²·C_M rotor, fv/fc = viscous/Coulomb friction")
    return 0


def _list(as_json: bool) -> int:
    from urident.model import available_robots, load_robot

    specs = [load_robot(name) for name in available_robots()]
    specs.sort(key=lambda s: (s.generation != "cb3", s.payload_kg or 0.0, s.name))
    rows = [{"robot": s.name, "model": s.model, "generation": s.generation,
             "rate_hz": s.controller_rate_hz, "controller_version": ".".join(map(str, s.controller_version)),
             "reach_m": s.reach_m, "payload_kg": s.payload_kg, "description": s.description}
            for s in specs]
    if as_json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'robot':<7} {'model':<6} {'generation':<10} {'rate':>6} {'version':<8} {'reach':>7} {'payload':>8}")
    for r in rows:
        reach = f"{r['reach_m']:.2f} m" if r["reach_m"] else "-"
        payload = f"{r['payload_kg']:g} kg" if r["payload_kg"] else "-"
        print(f"{r['robot']:<7} {r['model']:<6} {r['generation']:<10} {r['rate_hz']:>4g} Hz "
              f"{r['controller_version']:<8} {reach:>7} {payload:>8}")
    print("reach and payload: datasheet figures; `urident model --robot NAME` for the parameters")
    return 0


def _check(spec) -> int:
    import sys

    from urident.errors import ConfigError
    from urident.model.check import check_robot

    problems = check_robot(spec)
    for line in problems:
        print(line, file=sys.stderr)
    if problems:
        raise ConfigError(f"{spec.source}: {len(problems)} problem{'s' if len(problems) > 1 else ''} "
                          f"found (listed above)")
    print(f"{spec.source}: ok ({spec.description}: frames reproduce the DH table, limits, masses "
          f"and collision capsules plausible)")
    note = spec.nominal_note()
    if note:
        print(note)
    return 0
