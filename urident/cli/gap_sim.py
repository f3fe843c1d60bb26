"""``urident gap --sim MODEL [--write-sim OUT]``: the gap of the user's simulator model (MJCF or
URDF); see :mod:`urident.gap.sim_baseline`. Called by :mod:`urident.cli.cmd_gap`."""

from __future__ import annotations

import argparse
import json

from urident.cli import options

#: --max-effects default with --sim: a downloaded model lacks three drive terms on six joints (18),
#: and what the data show beyond them (offsets, delay, link corrections) takes a few more
SIM_MAX_EFFECTS = 30


def run_sim(args: argparse.Namespace, load_all, json_default) -> int:
    """``load_all(paths, args, rows, robot, what)`` and ``json_default``: cmd_gap's log loader and JSON
    encoder hook."""
    import numpy as np

    from urident.errors import ConfigError
    from urident.gap import GapConfig, format_report
    from urident.gap.candidates import EFFECTS
    from urident.gap.results import e_n, rms
    from urident.gap.sim_baseline import (corrections, detection_limits, diagnose_sim, expressible,
                                          expressible_fit, link_inertia_columns, unwritable)
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
    joint_map = args.joint_map
    sim = load_sim_model(args.sim, spec, joint_map=joint_map)
    floor = {} if args.min_shrink_pct is None else {"min_shrink_pct": args.min_shrink_pct}
    config = GapConfig(effects=args.effects or EFFECTS, **floor, cv_min_noise_ratio=args.cv_min_noise_ratio,
                       max_effects=args.max_effects or SIM_MAX_EFFECTS, seed=args.seed)
    drive_gains = None if args.drive_gains is None else np.array(args.drive_gains)
    from urident.cli.log_args import logs_from_args

    valid = load_all(logs_from_args(args.valid, args.valid_from, "--valid"), args, args.valid_rows,
                     spec.name, "validation")
    if args.ident:
        print("note: --ident logs are not used with --sim (the simulator model is the baseline, not refitted)")
    result = diagnose_sim(valid, spec, sim, drive_gains=drive_gains, config=config)
    print(format_report(result))
    print("")
    from urident.sim.compare import format_model_against_robot, model_against_robot

    states = result.valid.data.prepared
    against = model_against_robot(sim, spec, states.q, states.qd, states.qdd)
    print("\n".join(format_model_against_robot(against, spec, fmt)))
    print("")
    print(f"Simulator model {args.sim} ({fmt.upper()}): which findings the format can express")
    final_fit = {(c.effect, c.joint): c.magnitude(beta, spec) for c, beta in result.fit.coefficients().items()}
    for f in result.findings:
        yes = expressible(fmt, f.effect)
        value = final_fit.get((f.effect, None if f.effect == "payload_error" else f.joint - 1), {})
        shown = ", ".join(f"{k} = {v:.4g}" for k, v in value.items() if isinstance(v, float))
        print(f"  {f.effect:22s} joint {f.joint}  {'expressible' if yes else 'NOT expressible':16s} "
              f"{f.shrink_pct:5.1f} % shrink  {shown}")
        if f.effect == "armature":
            aliased = link_inertia_columns(spec, result.valid, f.joint - 1)[1]
            if aliased:
                print(f"    (holds rotor inertia plus the error of link {f.joint}'s inertia {', '.join(aliased)} about "
                      f"K_{f.joint}: they act alike on these states and in the simulator, nothing tells them apart)")
    limits = detection_limits(result)
    if limits:
        print("  not found: on these states, on top of the findings, a term below this is within the noise "
              "(not identifiable, not shown absent):")
        col = {"armature": "q̈", "damping": "q̇", "frictionloss": "tanh(q̇/ε)"}
        for d in limits:
            print(f"  {d['effect']:22s} joint {d['joint']}  below about {d['limit']:.3g} {d['unit']} "
                  f"({d['below_nm']:.3f} N·m at {col[d['effect']]} RMS {d['column_rms']:.3g})")
    doc = result.as_dict()
    doc["not_identified"] = limits
    final = final_fit
    for fd, f in zip(doc.get("findings", []), result.findings):
        fd["expressible"] = expressible(fmt, f.effect)
        # the value to put into the model: all chosen corrections fitted together
        fd["final_magnitude"] = final.get((f.effect, None if f.effect == "payload_error" else f.joint - 1))
        if f.effect == "armature":
            # link inertia fields the armature value also holds (inseparable from it)
            fd["inseparable_link_inertia"] = list(link_inertia_columns(spec, result.valid, f.joint - 1)[1])
    doc["baseline"]["sim_model"] = {"path": str(args.sim), "format": fmt, "joints": list(sim.joint_names),
                                    "against_robot_file": against}
    r0 = result.valid.residual
    chosen, fit = expressible_fit(result)
    from urident.sim.correct import unrealisable_links

    all_changes = corrections(result)
    bad = unwritable(chosen, set(unrealisable_links(sim, spec, all_changes)), all_changes)
    for c in bad:
        print(f"  {c.name}: not a real mass distribution (the inertia about the new centre of mass "
              "would not be positive): not written")
    written = [c for c in chosen if c not in bad]
    if len(written) != len(chosen):
        fit = result.correction(written)
    predicted = r0 - fit.change(result.valid) if written else r0
    # the value written: the expressible findings refitted without the rest (the format's
    # equivalent, e.g. a frictionloss that also carries a Stribeck term's average), beside the
    # final joint fit's value of the term itself
    kept = {(c.effect, c.joint): c.magnitude(beta, spec) for c, beta in fit.coefficients().items()} if written else {}
    written_arm = corrections(result, written)["armature"] if written else np.zeros(6)
    for (effect, j), value in kept.items():
        if effect == "armature":      # with what the link corrections hand to it (off_armature)
            value["armature_kg_m2"] = float(written_arm[j])
    for fd, f in zip(doc.get("findings", []), result.findings):
        fd["written_magnitude"] = kept.get((f.effect, None if f.effect == "payload_error" else f.joint - 1))
    inexpressible = [c for c in result.chosen() if not expressible(fmt, c.effect)]
    shrink = lambda before, after: 100.0 * (1 - after / np.where(before > 0, before, np.inf))  # noqa: E731
    print("  shrink of the validation RMS per joint [%]:")
    print("    expressible findings, predicted   " + " ".join(f"{v:6.1f}" for v in shrink(rms(r0), rms(predicted))))
    if inexpressible:
        rest = r0 - result.correction(inexpressible).change(result.valid)
        print("    inexpressible findings, predicted " + " ".join(f"{v:6.1f}" for v in shrink(rms(r0), rms(rest))))
    doc["sim_predicted"] = {"e_n": float(e_n(predicted)), "rms_nm": [float(v) for v in rms(predicted)]}
    if args.write_sim:
        from urident.sim.correct import write_corrected

        changes = corrections(result, written)
        notes = [f"corrected by urident gap from {args.sim} on {', '.join(map(str, args.valid))}"]
        notes += [f"not expressible here: {c.name}" for c in inexpressible]
        path = write_corrected(sim, spec, changes, args.write_sim, notes=notes, overwrite=args.overwrite)
        corrected = load_sim_model(path, spec, joint_map=joint_map)
        p = result.valid.data.prepared
        r1 = p.tau - corrected.predict(p.q, p.qd, p.qdd)
        doc["sim_corrected"] = {"e_n": float(e_n(r1)), "rms_nm": [float(v) for v in rms(r1)], "path": str(path)}
        print("    written model, measured by " + ("MuJoCo" if fmt == "mjcf" else "Pinocchio") + "    "
              + " ".join(f"{v:6.1f}" for v in shrink(rms(r0), rms(r1))))
        before, after = sim.drive(), corrected.drive()
        masses = model_against_robot(corrected, spec)["link_mass_kg"]
        doc["sim_corrected"]["values"] = {**{k: after[k].tolist() for k in after}, "link_mass_kg": masses}
        print("  written values (model → written), joints 1-6:")
        for key, unit in (("armature", "kg·m²"), ("damping", "N·m·s/rad"), ("frictionloss", "N·m")):
            if fmt == "mjcf" or key != "armature":
                print(f"    {key + ' [' + unit + ']':28s} " + "  ".join(
                    f"{a:.4g}→{b:.4g}" for a, b in zip(before[key], after[key])))
        print(f"    {'link mass [kg]':28s} " + "  ".join(
            f"{a:.4g}→{b:.4g}" for a, b in zip(against["link_mass_kg"], masses)))
        print(f"wrote {path}")
    if args.json_out:
        from urident.fileio import write_text_atomic
        from urident.gap.results import json_safe

        text = json.dumps(json_safe(doc), indent=1, allow_nan=False, default=json_default)
        write_text_atomic(args.json_out, text, fsync=False, overwrite=args.overwrite)
        print(f"\nreport written to {args.json_out}")
    return 0
