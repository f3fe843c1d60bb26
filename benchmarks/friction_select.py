"""Benchmark: ``--preset auto`` (each joint's friction chosen by blocked CV) against the paper's model
and the fixed ``ur10e-2020`` preset (what ``real-robot`` meant before it named ``auto``), on
simulated CB3 arms at 125 Hz whose friction lies outside the candidate family; and the selection's
time on a 60 s, 500 Hz log.

Per robot, the identification and validation trajectories of ``experiments/`` run through the
simulated controller offline (``urident simulate``, ``realistic`` effects: Stribeck, load friction,
warm-up drift, gear ripple, current delay and offset, elastic joints). Each scenario then adds,
to both runs' currents (τ / drive gain, after the simulation: the motion does not depend on it), a
friction torque of a form the family does not hold exactly, scaled by each joint's Coulomb
friction f_c of the robot file:

* ``none``: the realistic effects only;
* ``asymmetric``: a·f_c·|sign(q̇)| (Coulomb levels differing by direction), a per joint in ±0.2..0.35;
* ``gaz``: Gaz et al.'s sigmoid with offset φ1/(1 + e^{−φ2(q̇+φ3)}) − φ1/(1 + e^{−φ2 φ3}),
  φ1 = 0.8·f_c, φ2 = 25 s/rad, φ3 per joint in ±0.01..0.04 rad/s (exact, not linearised);
* ``lugre``: a LuGre state, dz/dt = q̇ − σ0|q̇|z/g(q̇), F = σ0·z, g = 0.4 f_c + 0.4 f_c·e^{−(q̇/0.03)²},
  σ0 = 0.4 f_c / 1e-4 rad (exact exponential step per sample; no σ1 damping).

Identification on the identification run, RMS [N·m] on the validation run (every sample). Prints
one line per robot, scenario and model, the terms auto chose, and the timing; the last line is one
JSON object.

    python benchmarks/friction_select.py [--robots ur10,ur5] [--scenarios none,asymmetric,gaz,lugre] [--no-timing]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASYM = np.array([0.3, -0.25, 0.2, -0.3, 0.35, -0.2])
GAZ_PHI3 = np.array([0.02, -0.03, 0.01, 0.04, -0.02, 0.03])   # [rad/s]


def extra_torque(name: str, t, qd, fc) -> np.ndarray:
    if name == "none":
        return np.zeros_like(qd)
    if name == "asymmetric":
        return ASYM * fc * np.abs(np.tanh(qd / 0.01))
    if name == "gaz":
        s = lambda x: 1.0 / (1.0 + np.exp(-x))  # noqa: E731
        phi1, phi2 = 0.8 * fc, 25.0
        return phi1 * s(phi2 * (qd + GAZ_PHI3)) - phi1 * s(phi2 * GAZ_PHI3)
    if name == "lugre":
        sigma0 = 0.4 * fc / 1e-4
        z = np.zeros(6)
        out = np.zeros_like(qd)
        dt = np.r_[0.0, np.diff(t)]
        for k in range(len(t)):
            v = qd[k]
            g = 0.4 * fc + 0.4 * fc * np.exp(-(v / 0.03) ** 2)
            zss = np.sign(v) * g / sigma0
            z = zss + (z - zss) * np.exp(-sigma0 * np.abs(v) * dt[k] / g)
            out[k] = sigma0 * z
        return out
    raise ValueError(name)


def with_extra(rec, spec, name: str):
    from urident.model.parameters import COULOMB

    fc = spec.nominal_params[COULOMB]
    tau = extra_torque(name, rec.t, rec.qd, fc)
    return replace(rec, current=rec.current + tau / spec.drive_gains)


def fit_and_score(spec, ident, valid, preset: str | None):
    from urident.ident import ModelConfig, PreprocessConfig, identify, prepare, resolve_preset, validate

    data = prepare([ident], spec, PreprocessConfig())
    vdata = prepare([valid], spec, PreprocessConfig(trim_rest=False))
    t0, c0 = time.perf_counter(), time.process_time()
    if preset is None:
        model, weighting, choice = ModelConfig(), "none", None
    else:
        choice = resolve_preset(spec, data, preset)
        model, weighting = choice.model, choice.weighting
        if choice.data is not None:   # auto's torque lead and acceleration corner, on both runs
            data = choice.data
            vdata = prepare([valid], spec, choice.preprocess_config(PreprocessConfig(trim_rest=False)))
    m = identify(spec, data, "ols", model, weighting)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return validate(m, spec, vdata), choice, wall, cpu


def timing() -> dict:
    """select_friction on a 60 s, 500 Hz synthetic UR5e log (the paper's model + current noise)."""
    from urident.ident import ModelConfig, prepare
    from urident.ident.design import base_for
    from urident.ident.friction_select import select_friction
    from urident.ident.synthetic import synthetic_recording
    from urident.model import load_robot

    spec = load_robot("ur5e")
    base_for(spec, True)
    rec, _, _ = synthetic_recording(spec, 60.0, 500.0, current_noise_a=0.03, seed=1)
    data = prepare([rec], spec)
    t0, c0 = time.perf_counter(), time.process_time()
    select_friction(spec, data, ModelConfig(reduced=True))
    return {"samples": len(data), "wall_s": round(time.perf_counter() - t0, 2),
            "cpu_s": round(time.process_time() - c0, 2)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", default="ur10,ur5")
    ap.add_argument("--scenarios", default="none,asymmetric,gaz,lugre")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-timing", action="store_true")
    args = ap.parse_args()

    from urident.cli.main import main as urident
    from urident.logs import load_log
    from urident.model import load_robot

    out: dict = {"runs": {}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for robot in args.robots.split(","):
            spec = load_robot(robot)
            logs = {}
            for kind in ("ident", "valid"):
                path = tmp / f"{robot}_{kind}.csv"
                assert urident(["simulate", "--trajectory", str(ROOT / "experiments" / f"{robot}_{kind}.yaml"),
                                "--out", str(path), "--effects", "realistic",
                                "--seed", str(args.seed + (kind == "valid"))]) == 0
                logs[kind] = load_log(path)
            for scenario in args.scenarios.split(","):
                ident, valid = (with_extra(logs[k], spec, scenario) for k in ("ident", "valid"))
                row = {}
                for label, preset in (("paper", None), ("ur10e-2020", "ur10e-2020"), ("auto", "auto")):
                    res, choice, wall, cpu = fit_and_score(spec, ident, valid, preset)
                    row[label] = {"rms_nm": [round(float(v), 3) for v in res.rms_nm],
                                  "mean_rms_nm": round(float(res.mean_rms_nm), 3),
                                  "fit_wall_s": round(wall, 2), "fit_cpu_s": round(cpu, 2)}
                    print(f"{robot} {scenario:<10} {label:<10} RMS " + " ".join(f"{v:.3f}" for v in res.rms_nm)
                          + f"  mean {res.mean_rms_nm:.3f}  (fit {wall:.1f} s wall, {cpu:.1f} s CPU)", flush=True)
                    if choice is not None and choice.selection is not None:
                        sel = choice.selection
                        row[label]["coulomb"] = list(sel.model.joint_coulomb)
                        row[label]["terms"] = [list(t) for t in sel.model.joint_extras]
                        row[label]["cv_rms_nm"] = [round(j.rms, 3) for j in sel.joints]
                        print("    auto: " + "; ".join(f"J{j + 1} {c} {'+'.join(t) or '-'}" for j, (c, t) in
                                                   enumerate(zip(sel.model.joint_coulomb, sel.model.joint_extras))))
                out["runs"][f"{robot}/{scenario}"] = row
    if not args.no_timing:
        out["timing_60s_500hz"] = timing()
        print(f"selection on a 60 s, 500 Hz log: {out['timing_60s_500hz']}")
    wins = [r["auto"]["mean_rms_nm"] <= min(r["paper"]["mean_rms_nm"], r["ur10e-2020"]["mean_rms_nm"])
            for r in out["runs"].values()]
    out["auto_best_mean_in"] = f"{sum(wins)}/{len(wins)}"
    print(json.dumps(out))


if __name__ == "__main__":
    main()
