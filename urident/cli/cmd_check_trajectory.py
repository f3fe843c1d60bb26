"""``urident check-trajectory``: re-check a trajectory file densely before it is run."""

from __future__ import annotations

import argparse
import json

from urident.cli import options
from urident.cli.options import positive_float


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "check-trajectory", help="check a trajectory file against every limit, densely",
        description="Load a trajectory file and check position, velocity, acceleration, nominal "
                    "torque, collision (Pinocchio/coal capsule distances) and rest at both ends at "
                    "every controller tick. Prints the tightest margin per constraint and joint; exits "
                    "non-zero naming the joint, time and margin of a violation.")
    p.add_argument("file", help="trajectory file (YAML)")
    p.add_argument("--rate", type=positive_float, default=None,
                   help="check rate [Hz] (default: the robot's controller rate)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    options.add_checked_payload_arguments(p, "check the torques with this load instead of the one the "
                                             "file records")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from urident.excitation.check import JOINT_CONSTRAINTS, UNITS, check_trajectory
    from urident.excitation.files import load_trajectory

    loaded = load_trajectory(args.file)
    payload, source = options.checked_payload(args, loaded.spec, loaded.payload, f"{args.file}: payload")
    report = check_trajectory(loaded.spec, loaded.trajectory, rate_hz=args.rate, limits=loaded.limits,
                              payload=payload)
    if args.json:
        tool = loaded.tool.as_dict() if loaded.tool is not None else None
        print(json.dumps({"file": str(args.file), "tool_capsule": tool, "payload_source": source,
                          **report.as_dict()}))
    else:
        traj = loaded.trajectory
        print(f"{args.file}: {loaded.spec.description}, L = {traj.harmonics}, {traj.duration:g} s, "
              f"{report.n_samples} samples at {report.rate_hz:g} Hz")
        if loaded.tool is not None:
            print(f"  tool capsule on the flange (from the file): radius {loaded.tool.radius_m:g} m, "
                  f"length {loaded.tool.length_m:g} m, checked against every link and the floor")
        if payload is not None:
            print(f"  payload in the torque check ({source}): {payload.describe()}; checked with and without it")
        else:
            print("  torque check with the empty flange (no payload recorded or given)")
        width = max(len(n) for n in report.joint_names)
        units = {**UNITS, "rest": "rad/s, rad/s^2"}
        print(f"  {'tightest margin':<28}" + "".join(f"{n:>{width + 2}}" for n in report.joint_names))
        for c in JOINT_CONSTRAINTS:
            print(f"  {c + ' [' + units[c] + ']':<28}"
                  + "".join(f"{m:>{width + 2}.4g}" for m in report.margins[c]))
        print(f"  min distance {report.min_distance_m:.4f} m ({report.min_distance_pair}), "
              f"collision margin {report.collision_margin_m:.4f} m "
              f"(clearance {report.limits.clearance_m:g} m)")
        print("  ok" if report.ok else f"  {len(report.violations)} violation(s)")
    report.raise_if_unsafe(str(args.file))
    return 0
