"""``urident gap --sim MODEL [--write-sim OUT]``: the gap of the user's simulator model (MJCF or
URDF); the analysis is :func:`urident.api.diagnose_sim` (:mod:`urident.gap.sim_report`). Called by
:mod:`urident.cli.cmd_gap`."""

from __future__ import annotations

import argparse

from urident.cli import options


def run_sim(args: argparse.Namespace, load_all) -> int:
    """``load_all(paths, args, rows, robot, what)``: cmd_gap's log loader."""
    import numpy as np

    from urident.api import diagnose_sim
    from urident.errors import ConfigError
    from urident.gap.candidates import EFFECTS
    from urident.gap.sim_report import SIM_MAX_EFFECTS
    from urident.model import load_robot
    from urident.sim.models import load_sim_model, model_format

    if not args.sim:
        raise ConfigError(("--write-sim" if args.write_sim else "--joint-map") + " needs --sim MODEL")
    if args.params:
        raise ConfigError("--params and --sim are two baselines: give one")
    fmt = model_format(args.sim)
    if args.write_sim:
        if model_format(args.write_sim) != fmt:
            raise ConfigError(f"--write-sim {args.write_sim}: must be {fmt.upper()} like --sim {args.sim}")
        options.output_path("--write-sim", args.write_sim, args.overwrite)
    spec = load_robot(args.robot)
    sim = load_sim_model(args.sim, spec, joint_map=args.joint_map)
    floor = {} if args.min_shrink_pct is None else {"min_shrink_pct": args.min_shrink_pct}
    from urident.cli.log_args import logs_from_args

    valid = load_all(logs_from_args(args.valid, args.valid_from, "--valid"), args, args.valid_rows,
                     spec.name, "validation")
    if args.ident:
        print("note: --ident logs are not used with --sim (the simulator model is the baseline, not refitted)")
    report = diagnose_sim(sim, valid, spec, model_label=args.sim, joint_map=args.joint_map,
                          drive_gains=None if args.drive_gains is None else np.array(args.drive_gains),
                          write_sim=args.write_sim, overwrite=args.overwrite,
                          valid_labels=[str(v) for v in args.valid or ()], effects=args.effects or EFFECTS,
                          **floor, cv_min_noise_ratio=args.cv_min_noise_ratio,
                          max_effects=args.max_effects or SIM_MAX_EFFECTS, seed=args.seed)
    print("\n".join(report.lines()))
    if args.json_out:
        from urident.fileio import write_text_atomic

        write_text_atomic(args.json_out, report.to_json(), fsync=False, overwrite=args.overwrite)
        print(f"\nreport written to {args.json_out}")
    return 0
