"""Blind benchmark of the sim-to-real gap diagnosis (``urident.gap``) on withheld effects.

Each scenario draws, with its own seed, a hidden truth: no effect, one effect of the catalogue,
or two (different effects on different joints), each on a random joint (payload_error: on all
joints) with a realistic random magnitude (see ``draw_effect``). Three runs are simulated offline
(:func:`urident.simcontroller.offline.simulate`) on a UR10e at ``--rate`` Hz with the robot file's
parameters and the simulator's sensor noise:

* identification: a random Fourier trajectory (paper eq. 25, rest at both ends);
* validation: a random point-to-point run with stops and slow moves (like the source project's
  validation run);
* sealed: another random point-to-point run the diagnosis never sees.

``payload_error`` is a payload added after the identification run: it is present in the
validation and sealed runs only (a payload present in every run is absorbed exactly by the base
parameters and leaves no gap). Every other effect acts in all three runs.

The diagnosis (:func:`urident.gap.diagnose`) gets the identification and validation
*Recordings* (ground-truth arrays and the sidecar's metadata stripped) and the robot spec, nothing
else. Scoring, per scenario:

* top-1 effect: the first finding's effect is one of the true effects (effect-free scenarios are
  scored by the false-alarm count instead);
* joint: the first finding's joint is that true effect's joint (payload_error: the joint whose
  validation RMS the true payload torque affects most, i.e. with the largest RMS of the injected
  torque);
* false alarm: an effect-free scenario with any finding;
* visible: a scenario whose true effect(s) shrink the sealed run's RMS on their joint by at
  least 3 % once added as below (an effect too small to matter cannot be diagnosed; accuracies
  are printed over all scenarios and over the visible ones);
* shrink error, per true effect: |predicted − actual| in percentage points, where
  *predicted* = the diagnosis' validation shrink of that effect's joint, 100·(1 − RMS_final/RMS_baseline)
  (0 when nothing was found), and *actual* = 100·(1 − RMS'/RMS) on the sealed run for the same
  joint, RMS the baseline's residual and RMS' the residual once the true effect(s) are added to the
  baseline with the magnitude the diagnosis fitted: the diagnosis' own columns for the true
  (effect, joint) (the variant it scored best), fitted on the diagnosis' identification/validation
  data exactly as a selection would be (:meth:`GapResult.correction`), applied to the sealed run.
  Both measured against the unfiltered measured torque (drive gains × raw current).

Usage: ``python benchmarks/gap_blind.py [--scenarios 40] [--seed 1] [--rate 200] [--duration 30]``.
The last line printed is one JSON object.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from dataclasses import dataclass

import numpy as np

ROBOT = "ur10e"
HOME = np.array([0.0, -1.7, 1.6, -1.5, -1.57, 0.0])
EFFECT_NAMES = ("stribeck", "load_friction", "thermal_drift", "position_ripple", "current_delay",
                "torque_constant_error", "current_offset", "payload_error", "joint_elasticity")
BETWEEN_RUNS = ("payload_error",)
VISIBLE_PCT = 3.0     # an effect is "visible" when adding it shrinks the sealed RMS by this much      # present in the validation and sealed runs only


# ----------------------------------------------------------------------------- trajectories
@dataclass(frozen=True)
class PointToPoint:
    """Moves between poses with a smooth (1 − cos) velocity profile and dwells: ``evaluate(t)``."""

    times: np.ndarray      # (M+1,) segment boundaries [s]
    poses: np.ndarray      # (M+1, 6) pose at each boundary (dwell: equal consecutive poses)
    duration: float

    def evaluate(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        t0, t1 = self.times[k], self.times[k + 1]
        T = (t1 - t0)[:, None]
        s = ((t - t0)[:, None]) / T
        dq = self.poses[k + 1] - self.poses[k]
        # position profile with velocity ∝ 1 − cos(2πs)
        pos = s - np.sin(2 * np.pi * s) / (2 * np.pi)
        vel = (1 - np.cos(2 * np.pi * s)) / T
        acc = 2 * np.pi * np.sin(2 * np.pi * s) / T ** 2
        return self.poses[k] + dq * pos, dq * vel, dq * acc


def random_ptp(rng, duration: float) -> PointToPoint:
    times, poses = [0.0], [HOME + rng.uniform(-0.3, 0.3, 6)]
    while times[-1] < duration:
        goal = HOME + rng.uniform(-0.9, 0.9, 6)
        speed = rng.choice([rng.uniform(0.03, 0.12), rng.uniform(0.2, 0.7)])     # slow or normal
        dist = np.max(np.abs(goal - poses[-1]))
        move = max(2.0 * dist / speed, 0.8)
        times.append(times[-1] + move)
        poses.append(goal)
        dwell = rng.uniform(0.4, 1.5)
        times.append(times[-1] + dwell)
        poses.append(goal)
    return PointToPoint(np.array(times), np.array(poses), float(times[-1]))


def random_fourier(rng, duration: float, harmonics: int = 5, period: float = 10.0):
    from urident.excitation.fourier import FourierTrajectory

    omega = 2 * np.pi / period
    a = rng.normal(size=(6, harmonics))
    b = rng.normal(size=(6, harmonics))
    ls = np.arange(1, harmonics + 1)
    a[:, 0] = -a[:, 1:].sum(axis=1)                 # q̇(0) = 0
    b[:, 0] = -(ls[1:] * b[:, 1:]).sum(axis=1)      # q̈(0) = 0
    dur = period * max(1, int(round(duration / period)))
    probe = FourierTrajectory(a, b, omega, HOME, dur)
    t = np.linspace(0, dur, 2000)
    q, qd, qdd = probe.evaluate(t)
    scale = np.minimum.reduce([0.9 / np.max(np.abs(qd), axis=0), 3.0 / np.max(np.abs(qdd), axis=0),
                               0.9 / np.max(np.abs(q - HOME), axis=0)])
    return FourierTrajectory(a * scale[:, None], b * scale[:, None], omega, HOME, dur)


# ----------------------------------------------------------------------------- effects
def draw_effect(rng, name: str, joint: int) -> dict:
    """One effects-file entry with a realistic random magnitude (joint 0-based)."""
    big = joint < 3
    e: dict = {"name": name, "joints": [joint + 1]}
    if name == "stribeck":
        e.update(static_friction_ratio=float(rng.uniform(1.3, 1.8)),
                 stribeck_velocity_rad_s=float(rng.uniform(0.01, 0.04)))
    elif name == "load_friction":
        e.update(coefficient=float(rng.uniform(0.015, 0.04)))
    elif name == "thermal_drift":
        e.update(viscous_change_per_c=float(rng.uniform(-0.02, -0.01)),
                 coulomb_change_per_c=float(rng.uniform(-0.008, -0.003)),
                 warmup_c=float(rng.uniform(10.0, 20.0)),
                 warmup_time_constant_s=float(rng.uniform(20.0, 60.0)))
    elif name == "position_ripple":
        e.update(amplitude_nm=float(rng.uniform(0.3, 0.8) if big else rng.uniform(0.1, 0.25)),
                 harmonic=float(rng.choice([2.0, 3.0, 101.0])),
                 phase_rad=float(rng.uniform(-np.pi, np.pi)),
                 mode=str(rng.choice(["torque", "friction"])))
    elif name == "current_delay":
        e.update(delay_s=float(rng.uniform(0.004, 0.012)))
    elif name == "torque_constant_error":
        f = rng.uniform(1.05, 1.12)
        e.update(gain_factor=float(f if rng.random() < 0.5 else 1.0 / f))
    elif name == "current_offset":
        e.update(offset_a=float(rng.choice([-1, 1]) * rng.uniform(0.03, 0.1)))
    elif name == "payload_error":
        e = {"name": name, "mass_kg": float(rng.uniform(0.5, 2.0)),
             "offset_m": [float(x) for x in rng.uniform(-0.03, 0.03, 2)] + [float(rng.uniform(0.0, 0.08))]}
    elif name == "joint_elasticity":
        e.update(stiffness_nm_per_rad=float(rng.uniform(10000, 25000) if big else rng.uniform(3000, 8000)),
                 damping_ratio=float(rng.uniform(0.05, 0.2)))
    return e


def effects_text(entries: list[dict]) -> str:
    import yaml

    return yaml.safe_dump({"description": "gap_blind scenario", "effects": entries})


@dataclass
class Scenario:
    index: int
    seed: int
    truth: list[dict]          # [{"effect", "joint" (0-based or None), "entry"}]


def draw_scenario(index: int, seed: int, kinds=("none", "one", "one", "one", "one", "two")) -> Scenario:
    rng = np.random.default_rng([seed, index])
    kind = kinds[index % len(kinds)]
    n = {"none": 0, "one": 1, "two": 2}[kind]
    names = list(rng.choice(EFFECT_NAMES, size=n, replace=False))
    joints = list(rng.choice(6, size=n, replace=False))
    truth = []
    for name, j in zip(names, joints):
        entry = draw_effect(rng, str(name), int(j))
        truth.append({"effect": str(name), "joint": None if name == "payload_error" else int(j),
                      "entry": entry})
    return Scenario(index, int(seed), truth)


def _strip(rec):
    """What a log holds, without the simulator's ground truth (arrays and sidecar keys)."""
    plain = rec.to_recording()
    return dataclasses.replace(plain, metadata={"rows": None})


def simulate_runs(spec, sc: Scenario, rate: float, duration: float):
    from urident.simcontroller.effects import parse_effects_text
    from urident.simcontroller.offline import simulate

    rng = np.random.default_rng([sc.seed, sc.index, 7])
    always = [t["entry"] for t in sc.truth if t["effect"] not in BETWEEN_RUNS]
    later = [t["entry"] for t in sc.truth]
    cfg_always = parse_effects_text(effects_text(always), "scenario")
    cfg_later = parse_effects_text(effects_text(later), "scenario")
    ident = simulate(spec, random_fourier(rng, duration), rate, cfg_always, seed=int(rng.integers(1 << 31)))
    valid = simulate(spec, random_ptp(rng, duration), rate, cfg_later, seed=int(rng.integers(1 << 31)))
    sealed = simulate(spec, random_ptp(rng, duration), rate, cfg_later, seed=int(rng.integers(1 << 31)))
    return ident, valid, sealed


def run_scenario(spec, sc: Scenario, rate: float = 200.0, duration: float = 30.0, config=None) -> dict:
    from urident.gap import diagnose
    from urident.gap.data import build_set
    from urident.gap.residual import make_context

    ident, valid, sealed = simulate_runs(spec, sc, rate, duration)
    t0 = time.perf_counter()
    res = diagnose([_strip(ident)], [_strip(valid)], spec, config=config)   # recordings + robot only
    wall = time.perf_counter() - t0

    truth = []
    for t in sc.truth:
        j = t["joint"]
        if j is None:   # payload: the joint the injected torque affects most on the validation run
            j = int(np.argmax(np.sqrt(np.mean(valid.extra_torque ** 2, axis=0))))
        truth.append((t["effect"], j))
    found = [(f.effect, f.joint - 1) for f in res.findings]
    out = {"index": sc.index, "truth": [{"effect": e, "joint": j + 1} for e, j in truth],
           "found": [{"effect": e, "joint": j + 1} for e, j in found],
           "entries": [t["entry"] for t in sc.truth], "diagnosis_s": wall}
    if not truth:
        out["false_alarm"] = bool(found)
        return out
    first = found[0] if found else None
    out["top1"] = bool(first and first[0] in [e for e, _ in truth])
    out["joint_ok"] = bool(first and (first[0], first[1]) in truth)
    out["all_found"] = all(t in found for t in truth)
    # actual shrink on the sealed run with the true effect(s) at the magnitude the diagnosis fitted
    cands = []
    for e, j in truth:
        c = res.best_of(e, j)
        if c is not None:
            cands.append(c)
    sealed_set = build_set([_strip(sealed)], spec)
    ctx_s = make_context(spec, res.model, sealed_set)
    r0 = ctx_s.residual
    r1 = r0 - res.correction(cands).change(ctx_s) if cands else r0
    rms0, rms1 = np.sqrt(np.mean(r0 ** 2, axis=0)), np.sqrt(np.mean(r1 ** 2, axis=0))
    errs = []
    for e, j in truth:
        actual = 100 * (1 - rms1[j] / rms0[j])
        predicted = 100 * (1 - res.final_rms[j] / res.baseline_rms[j]) if res.findings else 0.0
        errs.append({"effect": e, "joint": j + 1, "predicted_shrink_pct": float(predicted),
                     "actual_shrink_pct": float(actual), "error_pts": float(abs(predicted - actual))})
    out["shrink"] = errs
    out["visible"] = any(e["actual_shrink_pct"] >= VISIBLE_PCT for e in errs)
    return out


def summarise(rows: list[dict]) -> dict:
    eff = [r for r in rows if r["truth"]]
    free = [r for r in rows if not r["truth"]]
    vis = [r for r in eff if r["visible"]]
    shrink = [s["error_pts"] for r in eff for s in r["shrink"]]
    return {
        "scenarios": len(rows),
        "with_effect": len(eff),
        "effect_free": len(free),
        "top1_accuracy_pct": 100.0 * np.mean([r["top1"] for r in eff]) if eff else None,
        "joint_accuracy_pct": 100.0 * np.mean([r["joint_ok"] for r in eff]) if eff else None,
        "all_effects_found_pct": 100.0 * np.mean([r["all_found"] for r in eff]) if eff else None,
        "false_alarms": int(sum(r["false_alarm"] for r in free)),
        "mean_shrink_error_pts": float(np.mean(shrink)) if shrink else None,
        "max_shrink_error_pts": float(np.max(shrink)) if shrink else None,
        "visible": len(vis),
        "top1_accuracy_visible_pct": 100.0 * np.mean([r["top1"] for r in vis]) if vis else None,
        "joint_accuracy_visible_pct": 100.0 * np.mean([r["joint_ok"] for r in vis]) if vis else None,
        "mean_diagnosis_s": float(np.mean([r["diagnosis_s"] for r in rows])) if rows else None,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenarios", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rate", type=float, default=200.0, help="simulation rate [Hz]")
    ap.add_argument("--duration", type=float, default=30.0, help="length of each run [s]")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)

    from urident.model import load_robot

    spec = load_robot(ROBOT)
    rows = []
    t0 = time.perf_counter()
    for i in range(args.scenarios):
        sc = draw_scenario(i, args.seed)
        row = run_scenario(spec, sc, args.rate, args.duration)
        rows.append(row)
        truth = ", ".join(f"{t['effect']}@{t['joint']}" for t in row["truth"]) or "none"
        found = ", ".join(f"{t['effect']}@{t['joint']}" for t in row["found"]) or "none"
        sh = " ".join(f"{s['predicted_shrink_pct']:.0f}/{s['actual_shrink_pct']:.0f}"
                      for s in row.get("shrink", []))
        ok = ("ok" if row.get("joint_ok") else "MISS") if row["truth"] else \
             ("FALSE ALARM" if row["false_alarm"] else "ok")
        print(f"[{i:3d}] truth {truth:40s} found {found:50s} shrink pred/actual {sh:12s} {ok}",
              flush=True)
        if args.verbose:
            print("      ", json.dumps(row["entries"]))
    summary = summarise(rows)
    summary.update(seed=args.seed, rate_hz=args.rate, duration_s=args.duration,
                   wall_s=time.perf_counter() - t0)
    print(f"top-1 effect accuracy {summary['top1_accuracy_pct']:.1f} %, joint accuracy "
          f"{summary['joint_accuracy_pct']:.1f} %, false alarms {summary['false_alarms']}/"
          f"{summary['effect_free']}, mean |predicted - actual shrink| "
          f"{summary['mean_shrink_error_pts']:.2f} points; over the {summary['visible']} visible: "
          f"top-1 {summary['top1_accuracy_visible_pct']:.1f} %, joint {summary['joint_accuracy_visible_pct']:.1f} %")
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
