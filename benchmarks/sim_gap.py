"""Benchmark: the gap of a "downloaded-model-like" MJCF (nominal masses, solid-cylinder inertias,
no armature, damping or frictionloss) against runs of the simulated controller with the
``realistic`` effects (offline, ``urident simulate``). Prints the findings with their final values
beside the simulated truth (the robot file's drive values; an armature is also compared to the
truth as the data show it: rotor inertia plus the share along q̈_j of the torque of the model's
link inertia errors, which gap --sim leaves to armature), the validation RMS per joint before and after
the written model as MuJoCo measures it, and the report's predicted shrink; the last line is one
JSON object.

``--model menagerie`` / ``--model dh``: instead, a model as users have it (tests/sim_model_fixtures.py,
written there): Menagerie's layout (base turned 90° about the vertical, link lengths rounded to the
millimetre, the CB3 UR5's masses, armature 0.1 and damping 200/15 on every joint, no frictionloss,
default classes in an include, meshes absent) or a chain built from the DH table (joint 1 at the
base origin, the robot file's masses, no drive terms). The written model is then measured by MuJoCo on
a held-out run the diagnosis never saw (``--holdout``, default ``experiments/ROBOT_valid.yaml``
with seed + 1): its cut per joint beside the report's predicted one.

The validation run is ``experiments/ur5e_sim_gap.yaml``: four base periods in 20 s, so every joint's
armature torque is above the noise (the identification-style ``ur5e_valid.yaml`` accelerates the
wrist to 0.2 rad/s² RMS, where 0.06 kg·m² of rotor inertia is 0.01 N·m).

    python benchmarks/sim_gap.py [--robot ur5e] [--trajectory FILE] [--seed 0] [--max-effects N]
    python benchmarks/sim_gap.py --model menagerie|dh [--holdout FILE] [--model-file YOUR.xml]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def users_model(kind: str, args) -> None:
    """The Menagerie-style or DH-built case: figures on the diagnosis run and on a held-out run."""
    from sim_model_fixtures import dh_mjcf, menagerie_like_mjcf

    from urident.cli.main import main as urident
    from urident.gap.data import build_set
    from urident.logs import load_log
    from urident.model import load_robot
    from urident.sim.models import load_sim_model

    spec = load_robot(args.robot)
    cb3 = load_robot("ur5").nominal_params if spec.name == "ur5e" else spec.nominal_params
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.model_file is not None:
            model = args.model_file
        elif kind == "menagerie":
            model = menagerie_like_mjcf(spec, cb3, tmp / "menagerie", gripper=False, name=f"{spec.name}.xml")
        else:
            model = dh_mjcf(spec, spec.nominal_params, tmp / f"{spec.name}_dh.xml")
        traj = args.trajectory or next(p for p in (ROOT / "experiments" / f"{spec.name}_{k}.yaml"
                                                   for k in ("sim_gap", "valid")) if p.exists())
        holdout = args.holdout or ROOT / "experiments" / f"{spec.name}_valid.yaml"
        runs = {}
        for key, (trajectory, seed) in {"diagnosis": (traj, args.seed), "holdout": (holdout, args.seed + 1)}.items():
            runs[key] = tmp / f"{key}.csv"
            assert urident(["simulate", "--trajectory", str(trajectory), "--out", str(runs[key]), "--effects",
                            "realistic", "--seed", str(seed)]) == 0
        t0 = time.perf_counter()
        assert urident(["gap", "--robot", spec.name, "--sim", str(model), "--valid", str(runs["diagnosis"]),
                        "--write-sim", str(tmp / "corrected.xml"), "--json-out", str(tmp / "gap.json"),
                        *([] if args.max_effects is None else ["--max-effects", str(args.max_effects)])]) == 0
        wall = time.perf_counter() - t0
        doc = json.loads((tmp / "gap.json").read_text())
        p = build_set([load_log(runs["holdout"])], spec).prepared
        base = p.tau - load_sim_model(model, spec).predict(p.q, p.qd, p.qdd)
        fixed = p.tau - load_sim_model(tmp / "corrected.xml", spec).predict(p.q, p.qd, p.qdd)
    rms = lambda r: np.sqrt(np.mean(r ** 2, axis=0))  # noqa: E731
    before = np.array(doc["baseline"]["rms_nm"])
    predicted = 100 * (1 - np.array(doc["sim_predicted"]["rms_nm"]) / before)
    diag_cut = 100 * (1 - np.array(doc["sim_corrected"]["rms_nm"]) / before)
    hold_before, hold_after = rms(base), rms(fixed)
    hold_cut = 100 * (1 - hold_after / hold_before)
    judged = hold_before > 0.3
    against = doc["baseline"]["sim_model"]["against_robot_file"]
    print(f"\n{kind} {spec.name}: base turned {against['alignment']['yaw_deg']:.2f}°, axis offsets [mm] "
          + " ".join(f"{v:.2f}" for v in against["alignment"]["axis_offset_mm"]))
    print("findings: " + ", ".join(f"{f['effect']} j{f['joint']}" for f in doc["findings"]))
    print("diagnosis run RMS [N·m], model       " + " ".join(f"{v:7.3f}" for v in before))
    print("cut measured by MuJoCo [%]           " + " ".join(f"{v:7.1f}" for v in diag_cut))
    print("cut predicted by the report [%]      " + " ".join(f"{v:7.1f}" for v in predicted))
    print(f"held-out run ({holdout.name}, seed {args.seed + 1}) RMS [N·m], model "
          + " ".join(f"{v:7.3f}" for v in hold_before))
    print("held-out, written model [N·m]        " + " ".join(f"{v:7.3f}" for v in hold_after))
    print("held-out cut measured by MuJoCo [%]  " + " ".join(f"{v:7.1f}" for v in hold_cut))
    ok_cut = bool(np.all(hold_cut[judged] >= 50))
    ok_pred = bool(np.all(np.abs(hold_cut - predicted)[judged] <= 10))
    print(f"joints with held-out RMS > 0.3 N·m: {np.flatnonzero(judged) + 1}; cut >= 50 %: {ok_cut}; "
          f"within 10 points of the prediction: {ok_pred}; gap --sim wall time {wall:.1f} s")
    print(json.dumps({"model": kind, "robot": spec.name, "trajectory": traj.name, "holdout": holdout.name,
                      "seed": args.seed, "findings": [[f["effect"], f["joint"]] for f in doc["findings"]],
                      "alignment": against["alignment"], "baseline_rms_nm": before.round(4).tolist(),
                      "predicted_cut_pct": predicted.round(2).tolist(), "cut_pct": diag_cut.round(2).tolist(),
                      "holdout_baseline_rms_nm": hold_before.round(4).tolist(),
                      "holdout_corrected_rms_nm": hold_after.round(4).tolist(),
                      "holdout_cut_pct": hold_cut.round(2).tolist(), "holdout_cut_ok": ok_cut,
                      "holdout_within_10_points": ok_pred,
                      "max_disagreement_points": float(np.max(np.abs(hold_cut - predicted)[judged], initial=0)),
                      "wall_s": round(wall, 1)}))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robot", default="ur5e")
    ap.add_argument("--trajectory", type=Path, default=None,
                    help="validation trajectory (default experiments/ROBOT_sim_gap.yaml, else ROBOT_valid.yaml)")
    ap.add_argument("--seed", type=int, default=0, help="sensor-noise seed of the simulated run")
    ap.add_argument("--max-effects", type=int, default=None, help="default: gap --sim's")
    ap.add_argument("--model", choices=("downloaded", "menagerie", "dh"), default="downloaded",
                    help="the simulator model: downloaded-like (urident's export), Menagerie-style or DH-built")
    ap.add_argument("--holdout", type=Path, default=None, help="held-out trajectory (menagerie/dh)")
    ap.add_argument("--model-file", type=Path, default=None,
                    help="with --model menagerie/dh: your own file instead of the written one (e.g. Menagerie's "
                         "universal_robots_ur5e/ur5e.xml)")
    args = ap.parse_args()
    if args.model != "downloaded":
        users_model(args.model, args)
        return

    from urident.cli.main import main as urident
    from urident.model import load_robot
    from urident.model.parameters import body_slice
    from urident.sim.mjcf import downloaded_like_standard, write_mjcf

    spec = load_robot(args.robot)
    model_error = spec.nominal_params - downloaded_like_standard(spec)
    truth = {"armature": spec.arrays["rotor_inertia"], "damping": spec.arrays["viscous_friction"],
             "frictionloss": spec.arrays["coulomb_friction"]}
    keys = {"armature": "armature_kg_m2", "damping": "damping_nm_s_per_rad", "frictionloss": "frictionloss_nm"}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        model = write_mjcf(spec, downloaded_like_standard(spec), tmp / "downloaded.xml")
        log = tmp / "valid.csv"
        traj = args.trajectory or next(p for p in (ROOT / "experiments" / f"{spec.name}_{k}.yaml"
                                                   for k in ("sim_gap", "valid")) if p.exists())
        assert urident(["simulate", "--trajectory", str(traj), "--out", str(log), "--effects", "realistic",
                        "--seed", str(args.seed)]) == 0
        t0 = time.perf_counter()
        assert urident(["gap", "--robot", spec.name, "--sim", str(model), "--valid", str(log),
                        "--write-sim", str(tmp / "corrected.xml"), "--json-out", str(tmp / "gap.json"),
                        *([] if args.max_effects is None else ["--max-effects", str(args.max_effects)])]) == 0
        wall = time.perf_counter() - t0
        doc = json.loads((tmp / "gap.json").read_text())
        # the armature's share of the measured torque per joint (the truth's rotor inertia × q̈ on
        # the states gap uses), beside the white-noise torque of the baseline residual
        from urident.gap.data import build_set
        from urident.gap.significance import noise_sigma
        from urident.logs import load_log
        from urident.sim.models import load_sim_model

        prepared = build_set([load_log(log)], spec).prepared
        residual = prepared.tau - load_sim_model(model, spec).predict(prepared.q, prepared.qd, prepared.qdd)
        arm_nm = truth["armature"] * np.sqrt(np.mean(prepared.qdd ** 2, axis=0))
        arm_share = 100 * arm_nm / np.sqrt(np.mean(prepared.tau ** 2, axis=0))
        noise = noise_sigma(residual)
        # what armature holds of the model's link inertia errors on these states: their torque's
        # least-squares share along q̈_j (gap --sim takes link corrections off the armature columns)
        from urident.model import regressor_blocks

        bodies = np.r_[tuple(body_slice(j) for j in range(6))]
        link_error = regressor_blocks(spec, prepared.q, prepared.qd, prepared.qdd)[:, :, bodies] @ model_error[bodies]
        arm_equiv = np.sum(link_error * prepared.qdd, axis=0) / np.sum(prepared.qdd ** 2, axis=0)
    before = np.array(doc["baseline"]["rms_nm"])
    after = np.array(doc["sim_corrected"]["rms_nm"])
    predicted = np.array(doc["sim_predicted"]["rms_nm"])
    rows = []
    print(f"\n{'finding':14s} joint  expressible  final value   truth   error   in the data  error")
    for f in doc["findings"]:
        value = (f.get("final_magnitude") or {}).get(keys.get(f["effect"], ""), None)
        true = truth[f["effect"]][f["joint"] - 1] if f["effect"] in truth else None
        err = None if value is None or true is None or true == 0 else 100 * (value / true - 1)
        row = {"effect": f["effect"], "joint": f["joint"], "expressible": f["expressible"],
               "value": value, "truth": None if true is None else float(true), "error_pct": err}
        extra = ""
        if f["effect"] == "armature":
            seen = true + arm_equiv[f["joint"] - 1]
            row.update(truth_in_data=float(seen), error_in_data_pct=100 * (value / seen - 1),
                       inseparable_link_inertia=f["inseparable_link_inertia"])
            extra = f"   {seen:9.4g}  {row['error_in_data_pct']:+5.1f} %"
        rows.append(row)
        print(f"{f['effect']:14s} {f['joint']:5d}  {str(f['expressible']):11s}  "
              f"{'' if value is None else f'{value:11.4g}'}  {'' if true is None else f'{true:6.3g}'}  "
              f"{'' if err is None else f'{err:+5.1f} %'}{extra}")
    print("armature torque RMS [N·m]       " + " ".join(f"{v:7.3f}" for v in arm_nm))
    print("armature share of torque [%]    " + " ".join(f"{v:7.2f}" for v in arm_share))
    print("white-noise torque [N·m]        " + " ".join(f"{v:7.3f}" for v in noise))
    for d in doc.get("not_identified", []):
        print(f"not identified: {d['effect']} joint {d['joint']} below about {d['limit']:.3g} {d['unit']}")
    cut = 100 * (1 - after / before)
    pred = 100 * (1 - predicted / before)
    print("validation RMS [N·m], baseline  " + " ".join(f"{v:7.3f}" for v in before))
    print("written model (MuJoCo)          " + " ".join(f"{v:7.3f}" for v in after))
    print("cut measured by MuJoCo [%]      " + " ".join(f"{v:7.1f}" for v in cut))
    print("cut predicted by the report [%] " + " ".join(f"{v:7.1f}" for v in pred))
    print(f"gap --sim wall time {wall:.1f} s")
    print(json.dumps({"robot": spec.name, "trajectory": traj.name, "seed": args.seed, "findings": rows,
                      "baseline_rms_nm": before.tolist(), "corrected_rms_nm": after.tolist(),
                      "armature_share_pct": arm_share.round(3).tolist(), "noise_nm": noise.round(4).tolist(),
                      "not_identified": doc.get("not_identified", []), "cut_pct": cut.round(2).tolist(),
                      "predicted_cut_pct": pred.round(2).tolist(),
                      "max_disagreement_points": float(np.max(np.abs(cut - pred))), "wall_s": round(wall, 1)}))


if __name__ == "__main__":
    main()
