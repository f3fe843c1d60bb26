"""Out-of-family forms for ``benchmarks/gap_blind.py --out-of-family``: unmodelled effects written
from the physics literature, not from the diagnosis' candidate columns (``urident.gap.candidates``)
nor the simulator's catalogue. Each is an extra joint torque (or a filter on the measured current)
computed from the run's true motion; the same function evaluated on a diagnosis' data gives the
"true form" column whose fitted shrink on the sealed run is the reference.

=====================  ===========================================================================
quadratic_viscous      τ = c₂·q̇|q̇|: lubricant drag growing faster than linearly with speed
                       (Bittencourt & Gunnarsson, "Static friction in a robot joint", IEEE TRO 2012:
                       friction rising with speed beyond the linear viscous law at high speed)
asymmetric_coulomb     τ = ΔF·(1 + tanh(q̇/v₀))/2: a Coulomb level that differs by direction
                       (Swevers et al. 2007; seals and preloads are direction-dependent)
lugre                  LuGre (Canudas de Wit et al., IEEE TAC 1995): ż = v − σ₀|v|z/g(v),
                       g(v) = F_c + (F_s − F_c)·exp(−(v/v_s)²), F = σ₀z + σ₁ż (its Coulomb and
                       static part; the arm's own Coulomb level is the baseline's)
position_friction      τ = A·sin(q + φ)·tanh(q̇/v₀): friction varying once per revolution
                       (bearing run-out; Kermani et al. 2007)
cold_start             τ = c·exp(−t/τ_c)·q̇: viscous friction of cold grease decaying as it warms
                       (Carlson et al., "Friction of a harmonic drive at start-up", 2015)
current_lag            i_meas = low-pass(i, T): a first-order current loop/filter lag
cogging_2x             τ = A·sin(2·N·q + φ): a ripple at twice the wave generator's rate (N = 101,
                       two teeth engagements per wave-generator turn; Tuttle & Seering 1996)
neighbour_load         τ = μ·|τ_L,k|·tanh(q̇/v₀), k the perpendicular neighbour's joint: a
                       bearing carrying the neighbour link's moment (cross-coupled bearing friction)
elastic_joint          two-mass joint whose servo holds the motor on the commanded path: the link
                       deflection δ obeys δ̈ + 2ζω·δ̇ + ω²·δ = −q̈ (the motor's acceleration drives
                       the link's mode, ringing at every jerk of the path), τ = M_jj(q)·δ̈ with the
                       pose's own inertia (Spong, "Modeling and control of elastic joint robots",
                       1987; f = ω/2π 5–15 Hz, ζ 0.02–0.1)
box_payload            a box of 1–4 kg (sides 0.05–0.25 m, its inertia about its centre) whose
                       centre sits off the flange axis, mounted after the identification run
                       (validation and sealed runs only; rigid-body torque of the box)
=====================  ===========================================================================

``EXTRA_FORMS`` (elastic_joint, box_payload) are drawn only when asked (``--oof-forms``): the
default draws keep the eight forms above, so that every seed draws the scenarios it drew before.
"""

from __future__ import annotations

import numpy as np

FORMS = ("quadratic_viscous", "asymmetric_coulomb", "lugre", "position_friction", "cold_start",
         "current_lag", "cogging_2x", "neighbour_load")
#: Catalogue explanations counted as the closest one for each form (besides "beyond the
#: catalogue" on the right joint, or a finding there reported as a partial explanation).
ACCEPT = {"quadratic_viscous": ("quadratic_viscous",), "asymmetric_coulomb": ("current_offset", "asymmetric_coulomb"),
          "lugre": ("stribeck", "presliding"), "position_friction": ("position_ripple",),
          "cold_start": ("thermal_drift",), "current_lag": ("current_delay", "current_lag"),
          "cogging_2x": ("position_ripple",), "neighbour_load": ("load_friction", "neighbour_load_friction")}
EXTRA_FORMS = ("elastic_joint", "box_payload")
ACCEPT.update({"elastic_joint": ("joint_elasticity",), "box_payload": ("payload_error",)})
#: Forms present only after the identification run (a payload mounted later)
BETWEEN_RUNS = ("box_payload",)
V0 = 0.005            # [rad/s] smooth sign of the forms
GEAR = 101


def neighbour(j: int) -> int:
    """The perpendicular neighbour whose link moment a joint's bearing carries. UR arms: joint 1's
    axis is vertical, joints 2, 3 and 4 are parallel and horizontal, 5 is perpendicular to 4 and
    6 to 5; a parallel neighbour's torque acts about the joint's own axis (its own load), so
    joint 2 takes joint 1's, 4 takes 5's, 5 and 6 the other wrist joint's, joint 1 joint 2's.
    Joint 3 has none (:func:`draw` puts the form on joint 2 instead)."""
    return {0: 1, 1: 0, 3: 4, 4: 3, 5: 4}[j]


def draw(rng, form: str, joint: int) -> dict:
    if form == "neighbour_load" and joint == 2:
        joint = 1                   # joint 3's neighbours are both parallel to it (neighbour())
    big = joint < 3
    p: dict = {"form": form, "joint": int(joint)}
    if form == "quadratic_viscous":
        p["c2"] = float(rng.uniform(4, 10) if big else rng.uniform(1, 3))
    elif form == "asymmetric_coulomb":
        p["delta_nm"] = float(rng.choice([-1, 1]) * (rng.uniform(1.5, 4) if big else rng.uniform(0.4, 1.0)))
    elif form == "lugre":
        fc = float(rng.uniform(1.5, 3) if big else rng.uniform(0.3, 0.8))   # a part of the arm's own
        p.update(fc=fc, fs=fc * float(rng.uniform(1.3, 1.8)), vs=float(rng.uniform(0.01, 0.04)),
                 sigma0=float(rng.uniform(2e4, 1e5)), sigma1=float(rng.uniform(50, 300)))
    elif form == "position_friction":
        p.update(amp_nm=float(rng.uniform(1, 3) if big else rng.uniform(0.3, 0.8)),
                 phase=float(rng.uniform(-np.pi, np.pi)))
    elif form == "cold_start":
        p.update(c=float(rng.uniform(4, 10) if big else rng.uniform(1, 3)), tau_s=float(rng.uniform(15, 60)))
    elif form == "current_lag":
        p["lag_s"] = float(rng.uniform(0.004, 0.010))
    elif form == "cogging_2x":
        p.update(amp_nm=float(rng.uniform(0.3, 0.8) if big else rng.uniform(0.1, 0.25)),
                 phase=float(rng.uniform(-np.pi, np.pi)))
    elif form == "neighbour_load":
        p["mu"] = float(rng.uniform(0.02, 0.05))
    elif form == "elastic_joint":
        p.update(freq_hz=float(rng.uniform(5.0, 15.0)), zeta=float(rng.uniform(0.02, 0.1)))
    elif form == "box_payload":
        sides = rng.uniform(0.05, 0.25, 3)
        radius, angle = rng.uniform(0.03, 0.1), rng.uniform(-np.pi, np.pi)
        p.update(mass_kg=float(rng.uniform(1.0, 4.0)), sides_m=[float(x) for x in sides],
                 com_m=[float(radius * np.cos(angle)), float(radius * np.sin(angle)), float(sides[2] / 2)])
    return p


def _box_params(p: dict, spec) -> np.ndarray:
    """The 78-vector of the box: its mass, centre (flange frame) and inertia about its centre."""
    from urident.model.parameters import body_params, tool_body_vector

    m = p["mass_kg"]
    a, b, c = p["sides_m"]
    inertia = np.diag([m * (b * b + c * c), m * (a * a + c * c), m * (a * a + b * b)]) / 12.0
    r = np.asarray(spec.tool_rotation, float)
    com = np.asarray(spec.tool_xyz, float) + r @ np.asarray(p["com_m"], float)
    return tool_body_vector(body_params(m, com, r @ inertia @ r.T))


def box_torque(p: dict, spec, q, qd, qdd) -> np.ndarray:
    """(N, 6) the box's rigid-body torque on every joint."""
    from urident.model import joint_torques

    return joint_torques(spec, _box_params(p, spec), q, qd, qdd)


def _own_inertia(spec, q, j: int) -> np.ndarray:
    """(N,) M_jj(q): the joint-space inertia of joint ``j`` at each pose (link side)."""
    from urident.model import joint_torques
    from urident.model.parameters import VISCOUS_OFFSET

    link = np.array(spec.nominal_params, float)
    link[VISCOUS_OFFSET:] = 0.0
    zero = np.zeros_like(q)
    unit = zero.copy()
    unit[:, j] = 1.0
    return joint_torques(spec, link, q, zero, unit)[:, j] - joint_torques(spec, link, q, zero, zero)[:, j]


def _elastic(t, qdd, inertia, freq_hz, zeta):
    """M_jj·δ̈ of the link mode δ̈ + 2ζω·δ̇ + ω²·δ = −q̈ (exact for an input linear between samples)."""
    from scipy import signal

    w = 2 * np.pi * freq_hz
    sys = signal.StateSpace([[0.0, 1.0], [-w * w, -2 * zeta * w]], [[0.0], [-1.0]],
                            [[-w * w, -2 * zeta * w]], [[-1.0]])
    _, y, _ = signal.lsim(sys, qdd, t - t[0])
    return inertia * np.asarray(y, float).reshape(-1)


def _lugre(t, v, fc, fs, vs, sigma0, sigma1):
    """LuGre friction along the velocity ``v`` (N,), exact exponential step per sample."""
    z = 0.0
    out = np.zeros(len(v))
    for k in range(len(v)):
        g = fc + (fs - fc) * np.exp(-(v[k] / vs) ** 2)
        dt = t[k] - t[k - 1] if k else 0.0
        zss = g * np.sign(v[k]) / sigma0 if v[k] != 0 else 0.0
        rate = sigma0 * abs(v[k]) / g
        z_new = zss + (z - zss) * np.exp(-rate * dt)
        zdot = (z_new - z) / dt if dt > 0 else 0.0
        z = z_new
        out[k] = sigma0 * z + sigma1 * zdot
    return out


def _lowpass(x, t, lag):
    """First-order low-pass with time constant ``lag`` along time ``t`` (exact per step)."""
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(x)):
        a = np.exp(-(t[k] - t[k - 1]) / lag)
        y[k] = a * y[k - 1] + (1 - a) * x[k]
    return y


def torque(p: dict, t, q, qd, tau, tau_link, qdd=None, spec=None) -> np.ndarray:
    """(N,) the form's extra torque on its joint from the motion (time from the run's start ``t``,
    ``q, qd`` (N, 6), the model torque ``tau`` and its link-side part ``tau_link`` (N, 6)); for
    ``current_lag`` the change the lag makes to the joint's torque, low-pass(τ) − τ."""
    j, f = p["joint"], p["form"]
    v = qd[:, j]
    s = np.tanh(v / V0)
    if f == "quadratic_viscous":
        return p["c2"] * v * np.abs(v)
    if f == "asymmetric_coulomb":
        return p["delta_nm"] * (1 + s) / 2
    if f == "lugre":
        return _lugre(t, v, p["fc"], p["fs"], p["vs"], p["sigma0"], p["sigma1"])
    if f == "position_friction":
        return p["amp_nm"] * np.sin(q[:, j] + p["phase"]) * s
    if f == "cold_start":
        return p["c"] * np.exp(-t / p["tau_s"]) * v
    if f == "current_lag":
        return _lowpass(tau[:, j], t, p["lag_s"]) - tau[:, j]
    if f == "cogging_2x":
        return p["amp_nm"] * np.sin(2 * GEAR * q[:, j] + p["phase"])
    if f == "neighbour_load":
        return p["mu"] * np.abs(tau_link[:, neighbour(j)]) * s
    if f == "elastic_joint":
        return _elastic(t, qdd[:, j], _own_inertia(spec, q, j), p["freq_hz"], p["zeta"])
    if f == "box_payload":
        return box_torque(p, spec, q, qd, qdd)[:, j]
    raise ValueError(f)


def inject(spec, rec, p: dict):
    """The recording ``rec`` (a simulated run, effect-free) with the form added to its current."""
    import dataclasses

    from urident.model import joint_torques
    from urident.model.parameters import VISCOUS_OFFSET

    q, qd, qdd = rec.target_q, rec.target_qd, rec.target_qdd
    link = np.array(spec.nominal_params, float)
    link[VISCOUS_OFFSET:] = 0.0
    tau_link = joint_torques(spec, link, q, qd, qdd)
    t = np.asarray(rec.t, float) - rec.t[0]
    gains = np.asarray(spec.drive_gains, float)
    current = np.array(rec.current, float)
    j = p["joint"]
    if p["form"] == "current_lag":          # the whole measured current lags, its noise too
        current[:, j] = _lowpass(current[:, j], t, p["lag_s"])
    elif p["form"] == "box_payload":        # every joint carries the box
        current += box_torque(p, spec, q, qd, qdd) / gains
    else:
        current[:, j] += torque(p, t, q, qd, rec.tau_true, tau_link, qdd, spec) / gains[j]
    return dataclasses.replace(rec.to_recording(), current=current, metadata={"rows": None})


def truth_candidate(p: dict, spec=None):
    """The form as a one-column candidate of the diagnosis (identification mode: present in every
    run; a payload mounted later: fitted inside the validation logs, on every joint), evaluated on
    a set's motion and model torque: the reference fit of the true form."""
    from urident.gap.candidates import Candidate

    j = p["joint"]
    if p["form"] in BETWEEN_RUNS:
        def build_all(ctx):
            return box_torque(p, spec, ctx.q, ctx.qd, ctx.qdd)[:, :, None]
        return Candidate("true_form", None, p["form"], "cv", ("true form",), build_all, {})

    def cols(ctx):
        return [torque(p, ctx.data.run_time, ctx.q, ctx.qd, ctx.tau_hat, ctx.tau_link, ctx.qdd, spec)]

    def build(ctx):
        out = np.zeros((ctx.n, 6, 1))
        out[:, j, 0] = cols(ctx)[0]
        return out
    return Candidate("true_form", j, p["form"], "ident", ("true form",), build, {}, cols)


def reported_joints(res) -> dict:
    """1-based joint → what the diagnosis says there: the findings' effects (with their claim) and
    whether it is listed beyond the catalogue."""
    out: dict = {}
    for f in res.findings:
        out.setdefault(f.joint, {"effects": [], "beyond": False})["effects"].append((f.effect, f.claim))
    for u in res.where.get("unexplained", []):
        out.setdefault(u["joint"], {"effects": [], "beyond": False})["beyond"] = True
    return out


def run_scenario(spec, index: int, seed: int, rate: float, duration: float, config=None,
                 forms=FORMS) -> dict:
    """One scenario: effect-free (one in nine) or one form of ``forms`` on a random joint (a box
    payload: the joint where it explains the most torque); the diagnosis on the identification and
    validation runs; scored against the true form's sealed shrink."""
    import time

    from gap_blind import _strip, random_fourier, random_ptp

    from urident.gap import diagnose
    from urident.gap.data import build_set
    from urident.gap.residual import make_context
    from urident.simcontroller.offline import simulate

    rng = np.random.default_rng([seed, index, 31])
    form = None if index % 9 == 0 else forms[int(rng.integers(len(forms)))]
    p = draw(rng, form, int(rng.integers(6))) if form else None
    runs = [simulate(spec, traj, rate, None, seed=int(rng.integers(1 << 31)))
            for traj in (random_fourier(rng, duration), random_ptp(rng, duration), random_ptp(rng, duration))]
    recs = [inject(spec, r, p) if p and (i > 0 or form not in BETWEEN_RUNS) else _strip(r)
            for i, r in enumerate(runs)]
    if form in BETWEEN_RUNS:     # its joint: where it explains the most torque on the validation run
        v = runs[1]
        p["joint"] = int(np.argmax(np.sqrt(np.mean(box_torque(p, spec, v.target_q, v.target_qd,
                                                                  v.target_qdd) ** 2, axis=0))))
    t0 = time.perf_counter()
    res = diagnose([recs[0]], [recs[1]], spec, config=config)
    wall = time.perf_counter() - t0
    rep = reported_joints(res)
    row = {"index": index, "form": form, "params": p, "diagnosis_s": wall,
           "found": [{"effect": f.effect, "joint": f.joint, "claim": f.claim, "shrink_pct": f.shrink_pct}
                     for f in res.findings],
           "beyond": [u["joint"] for u in res.where.get("unexplained", [])],
           "events": len(res.events)}
    if p is None:
        row["false_alarm"] = bool(res.findings or row["beyond"] or res.events)
        return row
    j = p["joint"] + 1
    cand = truth_candidate(p, spec)
    ctx_s = make_context(spec, res.model, build_set([recs[2]], spec))
    r0 = ctx_s.residual[:, j - 1]
    r1 = r0 - res.correction([cand]).change(ctx_s)[:, j - 1]
    true_shrink = float(100 * (1 - np.sqrt(np.mean(r1 ** 2) / np.mean(r0 ** 2))))
    # the oracle: the true form's own shrink of the validation run (what any prediction made from
    # the validation run can know; the sealed run's motion excites the form otherwise)
    v0 = res.valid.residual[:, j - 1]
    v1 = v0 - res.correction([cand]).change(res.valid)[:, j - 1]
    oracle = float(100 * (1 - np.sqrt(np.mean(v1 ** 2) / np.mean(v0 ** 2))))
    first = res.findings[0].joint if res.findings else (
        max(res.where["unexplained"], key=lambda u: u["structured_rms_nm"])["joint"]
        if res.where.get("unexplained") else None)
    here = rep.get(j, {"effects": [], "beyond": False})
    accepted = here["beyond"] or any(c == "partial" or e in ACCEPT[form] for e, c in here["effects"])
    causes_wrong = [e for e, c in here["effects"] if c == "cause" and e not in ACCEPT[form]]
    predicted = float(100 * (1 - res.final_rms[j - 1] / res.baseline_rms[j - 1])) if here["effects"] else None
    row.update(joint=j, true_shrink_pct=true_shrink, joint_found=first == j,
               class_accepted=bool(accepted and not causes_wrong), matters=true_shrink >= 5.0,
               silent_miss=bool(true_shrink >= 5.0 and j not in rep),
               shrink_error_pts=None if predicted is None else abs(predicted - true_shrink),
               oracle_valid_shrink_pct=oracle, oracle_error_pts=abs(oracle - true_shrink))
    return row


def summarise(rows: list[dict]) -> dict:
    eff = [r for r in rows if r["form"]]
    matter = [r for r in eff if r["matters"]]
    free = [r for r in rows if not r["form"]]
    errs = [r["shrink_error_pts"] for r in eff if r["shrink_error_pts"] is not None]
    elsewhere = sum(1 for r in eff for f in r["found"] if f["joint"] != r["joint"])
    share = lambda xs, key: (sum(bool(x[key]) for x in xs), len(xs))   # noqa: E731
    return {"scenarios": len(rows), "with_effect": len(eff), "that_matter_5pct": len(matter),
            "joint_found": share(matter, "joint_found"), "class_accepted": share(matter, "class_accepted"),
            "silent_misses": share(matter, "silent_miss"), "false_alarms": share(free, "false_alarm"),
            "mean_shrink_error_pts": float(np.mean(errs)) if errs else None,
            # the oracle (the true form's validation shrink) on the same scenarios: what the
            # difference of the validation and sealed motions alone costs
            "mean_shrink_error_oracle_pts": float(np.mean([r["oracle_error_pts"] for r in eff
                                                           if r["shrink_error_pts"] is not None])) if errs else None,
            "findings_on_other_joints": elsewhere,
            "findings": sum(len(r["found"]) for r in eff),
            "mean_diagnosis_s": float(np.mean([r["diagnosis_s"] for r in rows])) if rows else None}
