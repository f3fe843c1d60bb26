"""Benchmark: payload and drive-gain identification on offline simulations (``urident simulate``)
with the realistic preset of unmodelled effects on.

Per seed: the arm is identified (``urident identify``, paper model plus offset, load-friction and
Stribeck columns) on the robot's identification trajectory without a load; then each payload
(0.3, 1, 1.5, 2, 3 and 10 kg, off-axis centre of mass, a full inertia) rides the payload excitation trajectory
(``experiments/ROBOT_payload.yaml``, from ``urident excite --for-payload``) and ``urident payload``
estimates it with that arm and a tare: the same trajectory run without the tool (``--unloaded``;
``--no-tare`` to leave it out). Drive gains: ``torque_constant_error`` on, the payload trajectory
(``--gains-trajectory``) without and with a known 5 kg load, ``urident drive-gains``; scored on the
joints it reports as calibrated. Principal inertias are scored where the estimate reports the
inertia identifiable. ``--repeats N``: each case rides the trajectory N times (and the tare N
times), each run with its own noise seed, all passed to one ``urident payload``; the inertia's σ
should then fall as 1/√N. Prints one line per case; the last line is one JSON object.

    python benchmarks/payload.py [--robot ur10e] [--seeds 1,2,3] [--trajectory FILE] [--no-tare]
                                 [--gains-trajectory FILE] [--payloads 0,3] [--no-gains | --gains-only]
                                 [--inertia-sigma] [--repeats N]
"""

from __future__ import annotations

import argparse
import io
import json
import tempfile
import time
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
PAYLOADS = [  # mass [kg], centre of mass [m] (flange), [Ixx, Iyy, Izz], [Ixy, Ixz, Iyz] about it
    (0.3, [0.0, 0.01, 0.03], [4e-4, 4e-4, 2e-4], [0.0, 0.0, 0.0]),
    (1.0, [0.02, -0.01, 0.06], [3e-3, 4e-3, 2e-3], [2e-4, 0.0, -1e-4]),
    (1.5, [0.02, 0.01, 0.07], [6e-3, 8e-3, 4e-3], [3e-4, -2e-4, 1e-4]),
    (2.0, [0.025, -0.015, 0.075], [0.01, 0.013, 0.007], [5e-4, -1e-3, 2e-4]),
    (3.0, [0.03, 0.02, 0.08], [0.02, 0.025, 0.015], [1e-3, -2e-3, 5e-4]),
    (10.0, [0.0, 0.05, 0.10], [0.08, 0.06, 0.05], [0.0, 5e-3, 0.0]),
]
GAINS_FACTORS = [1.05, 0.97, 1.08, 1.02, 0.95, 1.10]


def _quiet(argv):
    from urident.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(argv)
    if code != 0:
        raise SystemExit(f"{' '.join(argv[:2])} failed ({code}): {err.getvalue().strip()}")
    return out.getvalue()


def _effects(path: Path, extra: list[dict]) -> Path:
    realistic = yaml.safe_load((ROOT / "urident/simcontroller/presets/realistic.yaml").read_text())
    path.write_text(yaml.safe_dump({"effects": realistic["effects"] + extra}))
    return path


def _inertia_sigma(spec, arm_path: Path, logs: list[Path], tare_logs: list[Path], true_i: np.ndarray) -> dict:
    """The case refit with the inertia kept free (its tolerance rule off): the largest σ of the
    inertia entries, as a multiple of the rule's tolerance at the true inertia (15 % of the
    smallest principal inertia over ``INERTIA_SIGMAS``)."""
    import urident.ident.payload as payload_module
    from urident.ident import load_params, predict_recordings
    from urident.logs import load_log

    arm = load_params(arm_path)
    tare_runs, runs = [load_log(p) for p in tare_logs], [load_log(p) for p in logs]
    tare = payload_module.since_first_row(predict_recordings(arm, tare_runs, spec), tare_runs) if tare_logs else None
    data = predict_recordings(arm, runs, spec)
    data = payload_module.since_first_row(data, runs) if tare_logs else data.data
    saved = dict(payload_module.TOLERANCES)
    payload_module.TOLERANCES.update(inertia_rel=np.inf, inertia_abs=np.inf)   # the σ rule off
    try:
        est = payload_module.estimate_payload(arm, spec, data, unloaded=tare)
    finally:
        payload_module.TOLERANCES.update(saved)
    sigma = float(np.nanmax(np.array(est.ols.sigma["inertia_kg_m2"], dtype=float)))
    free = np.linalg.eigvalsh(est.ols.inertia_kg_m2)
    rule = payload_module.TOLERANCES["inertia_rel"] * true_i.min() / payload_module.INERTIA_SIGMAS
    return {"inertia_sigma_kg_m2": sigma, "inertia_sigma_ratio": sigma / rule,
            "free_principal_err_pct": [float(v) for v in 100 * (free / true_i - 1)]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robot", default="ur10e")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--trajectory", default=None,
                    help="loaded runs' trajectory (default: experiments/ROBOT_payload.yaml)")
    ap.add_argument("--payloads", default=None, help="indices into PAYLOADS to run (default: all)")
    ap.add_argument("--no-gains", action="store_true", help="skip the drive-gain runs")
    ap.add_argument("--gains-only", action="store_true", help="only the drive-gain runs")
    ap.add_argument("--gains-trajectory", default=None,
                    help="the with/without pair's trajectory (default: the payload trajectory)")
    ap.add_argument("--no-tare", dest="tare", action="store_false",
                    help="no unloaded run of the payload trajectory (urident payload without --unloaded)")
    ap.add_argument("--workdir", default=None, help="keep the runs in this directory (default: a temporary one)")
    ap.add_argument("--inertia-sigma", action="store_true",
                    help="also fit each case with the inertia kept free and print its σ against the 15 %% rule")
    ap.add_argument("--repeats", type=int, default=1, metavar="N",
                    help="runs of the loaded (and of the tare) trajectory per case, each with its own noise seed")
    args = ap.parse_args()
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    from urident.model.payload import Payload
    from urident.model import load_robot

    spec = load_robot(args.robot)
    ident_traj = ROOT / "experiments" / f"{args.robot}_ident.yaml"
    load_traj = Path(args.trajectory) if args.trajectory else ROOT / "experiments" / f"{args.robot}_payload.yaml"
    chosen = [int(k) for k in args.payloads.split(",")] if args.payloads else range(len(PAYLOADS))
    if args.gains_only:
        chosen = []
    gains_traj = Path(args.gains_trajectory) if args.gains_trajectory else load_traj
    seeds = [int(s) for s in args.seeds.split(",")]
    cases, gains_cases = [], []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(args.workdir or tmp)
        d.mkdir(parents=True, exist_ok=True)
        for seed in seeds:
            arm_log, arm = d / f"arm{seed}.csv", d / f"arm{seed}_params.yaml"
            if chosen:
                _quiet(["simulate", "--trajectory", str(ident_traj), "--out", str(arm_log), "--seed", str(seed),
                        "--effects", str(_effects(d / f"e_arm{seed}.txt", []))])
                _quiet(["identify", str(arm_log), "--robot", args.robot, "--out", str(arm),
                        "--friction-extra", "offset,load,stribeck"])
            tare_logs = []
            if args.tare and chosen:  # the payload trajectory without the tool (each run its own noise seed)
                for r in range(args.repeats):
                    tare_logs.append(d / f"unloaded{seed}" f"{f'_r{r}' if r else ''}.csv")
                    _quiet(["simulate", "--trajectory", str(load_traj), "--out", str(tare_logs[-1]), "--seed",
                            str(300 + seed + 1000 * r), "--effects", str(_effects(d / f"e_tare{seed}.txt", []))])
            tare = ["--unloaded", *map(str, tare_logs)] if tare_logs else []
            for k in chosen:
                mass, com, diag, prod = PAYLOADS[k]
                eff = _effects(d / f"e_{seed}_{k}.txt", [{"name": "payload_error", "mass_kg": mass, "offset_m": com,
                                                           "inertia_kg_m2": diag, "inertia_products_kg_m2": prod}])
                logs, out = [d / f"load{seed}_{k}" f"{f'_r{r}' if r else ''}.csv" for r in range(args.repeats)], \
                    d / f"p{seed}_{k}.json"
                for r, log in enumerate(logs):  # repeat r > 0 gets its own noise seed; r = 0 is the single run's
                    _quiet(["simulate", "--trajectory", str(load_traj), "--out", str(log), "--seed",
                            str(100 + seed + 1000 * r), "--effects", str(eff)])
                _quiet(["payload", *map(str, logs), "--params", str(arm), "--out", str(d / f"p{seed}_{k}_payload.yaml"),
                        "--json-out", str(out), *tare])
                est = json.loads(out.read_text())
                from urident.simcontroller.effects.dynamics import inertia_matrix

                true_i = np.linalg.eigvalsh(inertia_matrix(diag, prod))
                est_i = np.linalg.eigvalsh(np.array(est["inertia_kg_m2"]))
                inertia_ok = {"Jxx", "Jyy", "Jzz"} <= set(est["identifiable"])
                case = {"seed": seed, "mass_kg": mass, "repeats": args.repeats, "mass_err_pct": 100 * (est["mass_kg"] / mass - 1),
                        "com_err_mm": 1000 * float(np.max(np.abs(np.array(est["com_m"]) - com))),
                        "inertia_identifiable": inertia_ok,
                        "principal_inertia_err_pct": [float(v) for v in 100 * (est_i / true_i - 1)],
                        "identifiable": est["identifiable"]}
                if args.inertia_sigma:
                    case.update(_inertia_sigma(spec, arm, logs, tare_logs, true_i))
                cases.append(case)
                print(f"seed {seed}, {mass:5.1f} kg" + (f" ×{args.repeats}" if args.repeats > 1 else "") + f": mass {case['mass_err_pct']:+.2f} %, CoM {case['com_err_mm']:.2f} mm, "
                      f"inertia {'identified' if inertia_ok else 'not identifiable'}"
                      + (f" (of it: {', '.join(n for n in est['identifiable'] if n.startswith('J')) or 'none'})"
                         if not inertia_ok else "")
                      + (f" ({', '.join(f'{v:+.0f}' for v in case['principal_inertia_err_pct'])} %)" if inertia_ok else "")
                      + (f"; free inertia: σ {case['inertia_sigma_kg_m2']:.2e} kg·m² = {case['inertia_sigma_ratio']:.2f} × "
                         f"the rule, principal {', '.join(f'{v:+.0f}' for v in case['free_principal_err_pct'])} %"
                         if args.inertia_sigma else ""),
                      flush=True)
            if args.no_gains:
                continue
            # drive gains: torque_constant_error on, a known 5 kg load with an off-axis CoM
            tk = {"name": "torque_constant_error", "gain_factor": GAINS_FACTORS}
            load = {"name": "payload_error", "mass_kg": 5.0, "offset_m": [0.05, 0.0, 0.08]}
            runs = []
            for name, extra in (("without", [tk]), ("with", [tk, load])):
                log = d / f"g_{name}{seed}.csv"
                _quiet(["simulate", "--trajectory", str(gains_traj), "--out", str(log), "--seed", str(200 + seed),
                        "--effects", str(_effects(d / f"e_g{name}{seed}.txt", extra))])
                runs.append(str(log))
            gj = d / f"g{seed}.json"
            _quiet(["drive-gains", "--robot", args.robot, "--without", runs[0], "--with", runs[1],
                    "--payload-mass", "5", "--payload-com", "0.05,0,0.08", "--out", str(d / f"g{seed}_gains.yaml"),
                    "--json-out", str(gj)])
            g = json.loads(gj.read_text())
            true = np.array(spec.drive_gains) * GAINS_FACTORS
            err = 100 * (np.array(g["drive_gains"]) / true - 1)
            gains_cases.append({"seed": seed, "err_pct": [float(v) for v in err], "calibrated": g["calibrated"]})
            print(f"seed {seed}, drive gains error %: " + " ".join(f"{v:+.2f}" for v in err)
                  + "  calibrated: " + "".join("y" if c else "n" for c in g["calibrated"]), flush=True)
    mass_err = max((abs(c["mass_err_pct"]) for c in cases), default=None)
    com_err = max((c["com_err_mm"] for c in cases), default=None)
    with_inertia = [c for c in cases if c["inertia_identifiable"]]
    inertia_err = max((max(abs(v) for v in c["principal_inertia_err_pct"]) for c in with_inertia), default=None)
    gains_err = max((abs(e) for c in gains_cases for e, ok in zip(c["err_pct"], c["calibrated"]) if ok), default=None)
    summary = {"robot": args.robot, "seeds": seeds, "payload_trajectory": str(load_traj.name), "tare": args.tare,
               "repeats": args.repeats,
               "gains_trajectory": str(gains_traj.name),
               "max_mass_err_pct": mass_err, "max_com_err_mm": com_err,
               "inertia_identified_cases": len(with_inertia), "cases": len(cases),
               "inertia_identified_by_mass": {f"{m:g}": sum(c["inertia_identifiable"] for c in cases if c["mass_kg"] == m)
                                              for m in sorted({c["mass_kg"] for c in cases})},
               "max_principal_inertia_err_pct": inertia_err,
               "max_calibrated_drive_gain_err_pct": gains_err,
               "calibrated_joints": [c["calibrated"] for c in gains_cases],
               "wall_s": time.perf_counter() - t0}
    print((f"max mass error {mass_err:.2f} %, max CoM error {com_err:.2f} mm, inertia identified in "
           f"{len(with_inertia)}/{len(cases)} cases" if cases else "no payload cases")
          + (f" (max principal error {inertia_err:.1f} %)" if with_inertia else "")
          + (f", max drive-gain error on calibrated joints {gains_err:.2f} %" if gains_err is not None else ""))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
