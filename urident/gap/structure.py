"""Structure left in a joint's residual that a white-noise level test does not see: harmonics of
the joint angle up to the angle-Nyquist of the samples, linear dependence on each joint's velocity,
on the model torque and on time, and energy localised in time. Each is reported only when fitting it
would shrink the joint's RMS by at least ``min_shrink_pct`` and its fitted part reaches
``noise_ratio`` times the white-noise torque (the materiality rules of the findings)."""

from __future__ import annotations

import numpy as np

from urident.gap.maps import NEAR_ZERO_VELOCITY

#: Harmonics up to this many cycles per revolution at most (bounded cost).
MAX_HARMONIC = 2000
#: A harmonic is a spectral peak when its power exceeds this multiple of the spectrum's mean power
#: (exponentially distributed for noise: P = e^−16 ≈ 1e−7 per harmonic, < 1e−3 over 2000).
PEAK_POWER_RATIO = 16.0
#: Blocks [s] of the time-localisation test, and how far above the median block a block must be.
BLOCK_S = 1.0
BLOCK_ENERGY_RATIO = 4.0


def _shrink_pct(explained_ss: float, total_ss: float) -> float:
    if total_ss <= 0:
        return 0.0
    return float(100.0 * (1.0 - np.sqrt(max(total_ss - explained_ss, 0.0) / total_ss)))


def angle_nyquist(qd: np.ndarray, fs: float) -> int:
    """The highest harmonic k (cycles per revolution) the samples resolve on most of the motion:
    k·|q̇| < π·fs at the 90th percentile of the moving samples' speed."""
    v = np.abs(np.asarray(qd, float))
    v = v[v > NEAR_ZERO_VELOCITY]
    if v.size < 10:
        return 0
    return int(min(MAX_HARMONIC, np.floor(np.pi * fs / np.percentile(v, 90))))


def angle_harmonics(r: np.ndarray, q: np.ndarray, qd: np.ndarray, fs: float, sign: np.ndarray,
                    top: int = 3) -> list[dict]:
    """Peaks of the residual's spectrum against the joint angle, k = 2 … :func:`angle_nyquist`, of
    r (torque ripple) and of r·sign(q̇) (friction ripple), on the moving samples; each with the
    RMS [N·m] of the fitted sin/cos(k·q) and the share of the samples' energy it explains."""
    moving = np.abs(qd) > NEAR_ZERO_VELOCITY
    if moving.sum() < 50:
        return []
    stride = max(1, int(moving.sum() // 40000))
    qm = np.asarray(q, float)[moving][::stride]
    k_max = angle_nyquist(qd, fs)
    span = float(np.ptp(qm))
    k_min = max(2, int(np.ceil(2 * np.pi / span))) if span > 0 else k_max + 1
    if k_max < k_min:
        return []
    # e^{-ikq} is 2π-periodic in q for integer k: the sums Σ y·e^{-ikq} for every k at once by an
    # FFT of y binned on [0, 2π) (bins of 2π/(8·k_max): a phase error of at most π/8 at k_max)
    m = 8 * k_max
    idx = np.minimum((np.mod(qm, 2 * np.pi) / (2 * np.pi) * m).astype(int), m - 1)
    ks = np.arange(k_min, k_max + 1)
    out = []
    for mode, x in (("torque", r), ("friction", r * sign)):
        y = np.asarray(x, float)[moving][::stride]
        y = y - y.mean()
        n = len(y)
        power = np.abs(np.fft.fft(np.bincount(idx, weights=y, minlength=m))[ks]) ** 2
        mean = np.median(power) / np.log(2.0)
        if not mean > 0:
            continue
        # the span of angles visited widens each peak to about 2π/span harmonics: one per peak
        width = max(1, int(np.ceil(2 * np.pi / span)))
        taken: list[int] = []
        for i in np.argsort(-power):
            if len(taken) == top or power[i] < PEAK_POWER_RATIO * mean:
                break
            k = int(ks[i])
            if any(abs(k - o) <= width for o in taken):
                continue
            # the binned spectrum places a wide peak to ±1: the exact fit decides within it
            best = None
            for kk in range(max(k_min, k - width), min(k_max, k + width) + 1):
                a = np.column_stack([np.sin(kk * qm), np.cos(kk * qm)])
                beta, *_ = np.linalg.lstsq(a, y, rcond=None)
                f_kk = a @ beta
                if best is None or f_kk @ f_kk > best[1] @ best[1]:
                    best = (kk, f_kk)
            k, fit = best
            taken.append(k)
            out.append({"kind": "angle_harmonic", "mode": mode, "k": k,
                        "fitted_rms_nm": float(np.sqrt(np.mean(fit ** 2))),
                        "explained_ss": float(fit @ fit) * stride, "n": n * stride,
                        "peak_over_mean_power": float(power[i] / mean)})
    return out


def linear_dependence(r: np.ndarray, signals: dict) -> list[dict]:
    """Per signal (name → (N,)), the part of ``r`` linear in it (with a constant): its RMS and the
    energy it explains."""
    out = []
    y = np.asarray(r, float)
    yc = y - y.mean()
    for name, x in signals.items():
        xc = np.asarray(x, float) - np.mean(x)
        xx = float(xc @ xc)
        if xx <= 0:
            continue
        b = float(xc @ yc) / xx
        fit = b * xc
        out.append({"kind": "linear", "signal": name, "correlation": float(xc @ yc / np.sqrt(xx * float(yc @ yc)))
                    if yc @ yc > 0 else 0.0, "fitted_rms_nm": float(np.sqrt(np.mean(fit ** 2))),
                    "explained_ss": float(fit @ fit)})
    return out


def time_localised(r: np.ndarray, run_time: np.ndarray, fs: float) -> list[dict]:
    """1-s blocks whose mean square exceeds :data:`BLOCK_ENERGY_RATIO` × the median block's, merged
    when adjacent: their excess energy over that median."""
    r = np.asarray(r, float)
    n = len(r)
    size = max(1, int(round(BLOCK_S * fs)))
    m = n // size
    if m < 5:
        return []
    ms = np.mean(r[:m * size].reshape(m, size) ** 2, axis=1)
    med = float(np.median(ms))
    hot = ms > BLOCK_ENERGY_RATIO * med
    out = []
    b = 0
    while b < m:
        if not hot[b]:
            b += 1
            continue
        a = b
        while b < m and hot[b]:
            b += 1
        excess = float(np.sum(ms[a:b] - med) * size)
        out.append({"kind": "time_localised", "t_start_s": float(run_time[a * size]),
                    "t_end_s": float(run_time[min(b * size, n) - 1]), "explained_ss": excess,
                    "fitted_rms_nm": float(np.sqrt(max(excess, 0.0) / n))})
    return out


def joint_structure(j: int, r: np.ndarray, ctx, sigma_j: float, min_shrink_pct: float,
                    noise_ratio: float) -> list[dict]:
    """The material structure of joint ``j``'s residual ``r`` (N,) on the set ``ctx``
    (module doc), largest first; each with ``shrink_pct``, what fitting it would do."""
    r = np.asarray(r, float)
    total = float(r @ r)
    fs = ctx.data.sample_rate
    found = angle_harmonics(r, ctx.q[:, j], ctx.qd[:, j], fs, ctx.sign()[:, j])
    signals = {f"velocity of joint {i + 1}": ctx.qd[:, i] for i in range(6)}
    signals.update({f"model torque of joint {i + 1}": ctx.tau_hat[:, i] for i in range(6)})
    signals["time"] = ctx.data.run_time
    found += linear_dependence(r, signals)
    found += time_localised(r, ctx.data.run_time, fs)
    out = []
    for f in found:
        n = f.pop("n", len(r))
        share = f.pop("explained_ss") * len(r) / n
        f["shrink_pct"] = _shrink_pct(share, total)
        if f["shrink_pct"] >= min_shrink_pct and f["fitted_rms_nm"] >= noise_ratio * sigma_j:
            out.append(f)
    out.sort(key=lambda f: -f["shrink_pct"])
    return out


def identification_only(scorer, pool, selected, last_scores, min_shrink_pct: float) -> dict[int, dict]:
    """0-based joint → the identification-mode candidate of ``pool`` (one joint each) that, refitted
    with the base parameters on top of the ``selected`` ones, would shrink that joint's
    identification residual in-sample by at least ``min_shrink_pct`` (the largest there), with
    its shrink of the validation run (``last_scores``: the selection's last step, on top of the
    findings; 0 when it is not scored there).

    Why: an effect present in every run but barely excited by the validation motion (a cold
    start on a joint the validation run hardly moves in its first minute) leaves the validation
    residual at the noise and goes unreported, though the identification logs hold it clearly;
    effect-free identification residuals give at most a few hundredths of a per cent here."""
    chosen = [c for c in selected if c.mode == "ident"]
    cands = [c for c in pool if c.mode == "ident" and c.joint is not None and c not in selected]
    if not cands:
        return {}
    ss0 = scorer.ident_ss(chosen)
    r_ss = np.sum(np.asarray(scorer.ident.residual, float) ** 2, axis=0)   # the baseline's, per joint
    valid = {id(sc.candidate): sc.shrink_pct for sc in last_scores}
    out: dict[int, dict] = {}
    for c in cands:
        j = c.joint
        d = ss0 - scorer.ident_ss(chosen + [c])
        if not r_ss[j] > 0 or d <= 0:
            continue
        shrink = _shrink_pct(d, float(r_ss[j]))
        if shrink >= min_shrink_pct and shrink > out.get(j, {}).get("shrink_pct", -np.inf):
            out[j] = {"kind": "identification_logs", "candidate": c.name, "shrink_pct": shrink,
                      "validation_shrink_pct": float(valid.get(id(c), 0.0)),
                      "fitted_rms_nm": float(np.sqrt(d / scorer.ident.n))}
    return out


def describe(f: dict) -> str:
    """One line of text for a structure of :func:`joint_structure` or :func:`identification_only`."""
    if f["kind"] == "identification_logs":
        return (f"in the identification logs: {f['candidate']} would shrink the joint's residual by "
                f"{f['shrink_pct']:.1f} % (in-sample, with the base parameters refitted), the validation "
                f"run's by {f['validation_shrink_pct']:.1f} % (no finding there)")
    if f["kind"] == "angle_harmonic":
        what = (f"{f['mode']} ripple at k = {f['k']} cycles per revolution "
                f"({f['fitted_rms_nm']:.3g} N·m RMS)")
    elif f["kind"] == "linear":
        what = f"linear in the {f['signal']} (correlation {f['correlation']:+.2f})"
    else:
        what = f"localised in time, t in [{f['t_start_s']:.3g}, {f['t_end_s']:.3g}] s"
    return f"{what}: fitting it would shrink the RMS by {f['shrink_pct']:.1f} %"


#: The axis along which each effect's form is checked after the findings (its own variable): the
#: joint's signed velocity for friction effects, the model torque for a gain, time for a drift.
#: Friction forms: functions of the joint's motion along its velocity (their misfit is a friction curve)
FRICTION_FORMS = ("stribeck", "load_friction", "presliding", "quadratic_viscous", "neighbour_load_friction",
                  "asymmetric_coulomb")
FORM_AXIS = {"stribeck": "velocity", "load_friction": "velocity", "presliding": "velocity",
             "quadratic_viscous": "velocity", "neighbour_load_friction": "velocity",
             "thermal_drift": "time", "torque_constant_error": "torque", "current_delay": "velocity",
             "current_offset": "velocity", "asymmetric_coulomb": "velocity", "current_lag": "velocity"}
#: Bins per sign of the velocity axis (quantiles of the moving samples), and of the other axes.
FORM_BINS = 6


def _axis_bins(axis: str, j: int, ctx) -> tuple[np.ndarray, str]:
    """(N,) bin of every sample along ``axis`` for joint ``j`` (−1: none), and the axis' name."""
    n = ctx.n
    if axis == "velocity":
        v = ctx.qd[:, j]
        out = np.zeros(n, int)                 # bin 0: |q̇| below the near-zero band
        for sgn, first in ((1, 1), (-1, 1 + FORM_BINS)):
            sel = sgn * v > NEAR_ZERO_VELOCITY
            if sel.sum() >= FORM_BINS:
                edges = np.quantile(sgn * v[sel], np.linspace(0, 1, FORM_BINS + 1)[1:-1])
                out[sel] = first + np.searchsorted(edges, sgn * v[sel])
        return out, f"velocity of joint {j + 1}"
    x = ctx.tau_hat[:, j] if axis == "torque" else ctx.data.run_time
    edges = np.quantile(x, np.linspace(0, 1, 2 * FORM_BINS + 1)[1:-1])
    return np.searchsorted(edges, x), ("model torque of joint " + str(j + 1)) if axis == "torque" else "time"


def form_left(effect: str, j: int, r: np.ndarray, ctx, sigma_j: float, min_shrink_pct: float,
              noise_ratio: float) -> dict | None:
    """What a finding of ``effect`` on 0-based joint ``j`` leaves along its own axis
    (:data:`FORM_AXIS`) in the residual ``r`` (N,) after the findings: the bin means of r along
    it, when they would shrink the joint's RMS by ``min_shrink_pct`` with an RMS of at least
    ``noise_ratio`` × the white-noise torque, else None (its form fits)."""
    axis = FORM_AXIS.get(effect)
    if axis is None:
        return None
    r = np.asarray(r, float)
    b, name = _axis_bins(axis, j, ctx)
    count = np.bincount(b, minlength=b.max() + 1).astype(float)
    mean = np.bincount(b, weights=r, minlength=len(count)) / np.where(count > 0, count, 1.0)
    fit = mean[b] - r.mean()
    share = float(fit @ fit)
    shrink = _shrink_pct(share, float(r @ r))
    fit_rms = float(np.sqrt(share / len(r)))
    if shrink < min_shrink_pct or fit_rms < noise_ratio * sigma_j:
        return None
    where = int(np.argmax(np.abs(mean - r.mean()) * np.sqrt(count)))
    sel = b == where
    lo, hi = (float(v) for v in (np.min(_axis_values(axis, j, ctx)[sel]), np.max(_axis_values(axis, j, ctx)[sel])))
    return {"axis": name, "shrink_pct": shrink, "fitted_rms_nm": fit_rms,
            "text": (f"its form leaves structure along the {name}: the residual's mean per bin of it "
                     f"would shrink the RMS by a further {shrink:.1f} % (largest in [{lo:.3g}, {hi:.3g}])")}


def velocity_bins(j: int, ctx) -> tuple[np.ndarray, str]:
    """(N,) the bin of joint ``j``'s signed velocity of every sample (:data:`FORM_BINS` quantile
    bins per direction and the near-zero band), and the axis' name."""
    return _axis_bins("velocity", j, ctx)


def _axis_values(axis: str, j: int, ctx) -> np.ndarray:
    return {"velocity": ctx.qd[:, j], "torque": ctx.tau_hat[:, j], "time": ctx.data.run_time}[axis]


def transition_of(col: np.ndarray, r: np.ndarray, others: list[tuple[str, np.ndarray]], near: np.ndarray,
                  tol: float) -> dict | None:
    """Whether a near-zero-velocity friction column ``col`` (N,) of a joint (a Stribeck bump) is
    another finding's transition rather than a friction of its own: ``others`` (label, that
    finding's correction on the joint (N,)); ``near`` (N,) the bump's own shape (≤ 1, largest at
    rest). A friction A·s whose sign changes more sharply than the baseline's s = tanh(q̇/ε) leaves
    A·(sharper − s), a bump scaled by A; a constant static friction leaves one scaled by nothing.
    When the other finding's correction times ``near`` explains ``r`` (the joint's residual
    without ``col``'s correction) at least (1 − ``tol``) as well as ``col`` does, the bump is
    that finding's (its ``label``, with both shares of r's sum of squares), else None."""
    def share(x):
        xx = float(x @ x)
        return float((r @ x) ** 2 / xx) if xx > 0 else 0.0
    own = share(col)
    rr = float(r @ r)
    best = None
    for name, c in others:
        s = share(c * near)
        if own > 0 and s >= (1 - tol) * own and (best is None or s > best[1]):
            best = (name, s)
    if best is None or rr <= 0:
        return None
    return {"of": best[0], "scaled_pct": 100 * best[1] / rr, "constant_pct": 100 * own / rr}


def misfit_of(col: np.ndarray, r: np.ndarray, others: list[tuple[str, np.ndarray]], bins: np.ndarray,
              tol: float) -> dict | None:
    """Whether a finding's correction ``col`` (N,) on a joint only mends the form of another finding
    there: ``others`` (label, that finding's correction on the joint (N,)); ``bins`` (N,) the bins
    of the joint's velocity (:func:`_axis_bins`). The other finding scaled freely per velocity bin
    is its own form with a different velocity dependence (a sharper transition, a bump, a faster
    rise); a correction None stands for the joint's friction curve, free per bin. When that explains ``r`` (the joint's residual without ``col``'s correction) at least
    (1 − ``tol``) as well as ``col`` does, ``col`` is that finding's form misfit: its ``label``,
    with both shares of r's sum of squares; else None."""
    rr = float(r @ r)
    xx = float(col @ col)
    if rr <= 0 or xx <= 0:
        return None
    own = float((r @ col) ** 2 / xx)
    best = None
    for name, c in others:
        # None: a free function of the velocity (a constant per bin), the friction curve itself
        x = np.stack([(c if c is not None else 1.0) * (bins == b) for b in np.unique(bins)], axis=1)
        x = x[:, np.any(x != 0, axis=0)]
        if not x.size:
            continue
        beta, *_ = np.linalg.lstsq(x, r, rcond=None)
        fit = x @ beta
        s = float(fit @ fit)
        if s >= (1 - tol) * own and (best is None or s > best[1]):
            best = (name, s)
    if best is None:
        return None
    return {"of": best[0], "scaled_pct": 100 * best[1] / rr, "own_pct": 100 * own / rr}
