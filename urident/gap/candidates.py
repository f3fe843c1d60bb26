"""Which: regressor columns for every effect of the catalogue, per joint.

A :class:`Candidate` is one variant (e.g. one Stribeck velocity) of one effect on one joint (or on
all joints: payload_error), fitted in one mode:

* ``ident``: the columns are added to the baseline and refitted on the identification logs
  (jointly with the base parameters), then scored on the validation logs;
* ``cv``: for effects that may differ between runs (friction of the day, warm-up, a payload
  added later, a sensor offset), the baseline stays fixed and only the effect's columns are fitted by blocked
  cross-validation inside the validation logs.

Columns (on the rows of joint j; ε the model's tanh slope, s = tanh(q̇_j/ε); the friction-mode
ripple and neighbour-load friction also with a sharper s = tanh(q̇_j/(w·ε)), w in SIGN_WIDTHS):

=======================  =============================================================================
stribeck                 exp(−(q̇_j/v_s)²)·s, v_s on a grid
load_friction            |τ̂_link,j|·s
thermal_drift            x·q̇_j and x·s with x = time since the start of the run [min], a warm-up
                         curve 1 − exp(−t/τ_w) (τ_w on a grid), the joint temperature's change
                         since the start, or its difference to the identification logs' mean
                         temperature
position_ripple          sin(k·q_j), cos(k·q_j) (mode torque) or the same × s (mode friction), k = 2-4
                         (k = 1 too in friction mode: a bearing's run-out),
                         the peaks of the angle-domain spectrum of the identification residual and
                         its clear peaks up to the samples' angle-Nyquist (urident.gap.structure)
current_delay            dτ̂_j/dt (coefficient −d), or the exact shift τ̂_j(t − d) − τ̂_j(t) (d on a
                         grid, coefficient 1 for that delay): at a velocity reversal's sharp
                         Coulomb step the shift and the lag differ where the derivative cannot tell
torque_constant_error    τ̂_j (coefficient 1/gain_factor − 1)
current_offset           1 (coefficient the offset in N·m)
payload_error            all joints: the torque of 1 kg at the tool point, and the three first-moment
                         columns m·ρ of body 6 (mass and centre-of-mass shift)
joint_elasticity         d²τ̂_link,j/dt² (coefficient −J/k)
quadratic_viscous        q̇_j·|q̇_j| (friction growing faster than linearly with speed)
neighbour_load_friction  |τ̂_link,k|·s, k = j ± 1 with an axis perpendicular to j's: a bearing
                         carrying a neighbour's link moment
asymmetric_coulomb       |s|: a Coulomb level that differs by direction (coefficient ΔF/2), an offset
                         that acts only while the joint moves
current_lag              lag_T(τ̂_j) − τ̂_j, lag_T the first-order filter 1/(Ts + 1) (T on a grid;
                         coefficient 1 for that lag); in one family with current_delay's variants
                         (the identification fit chooses a delay or a lag, as it chooses a
                         Stribeck velocity: held-out gains barely tell them apart)
presliding               z_j − s, z the normalised Dahl state driven by the integrated velocity
                         (presliding distance δ on a grid): holding friction that keeps the sign
                         and size of the motion before a stop, where tanh(q̇/ε) falls to 0
=======================  =============================================================================

``presliding`` is a diagnosis-only candidate: the simulator's catalogue has no such effect, and no
simulator model format can express it (``urident.gap.sim_baseline.EXPRESSIBLE`` lacks it).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from urident.gap.residual import SetContext
from urident.ident import features
from urident.simcontroller.effects.catalogue import EFFECT_NAMES

#: Candidates with no simulator effect behind them (what real arms show beyond the catalogue).
DIAGNOSIS_ONLY = ("presliding",)
#: The catalogue's names, in its order, then the diagnosis-only candidates.
EFFECTS = EFFECT_NAMES + DIAGNOSIS_ONLY
#: Effects that may differ between runs (friction of the day, warm-up, a sensor offset, a payload
#: added later) or that the identification run barely excites (presliding: the holding friction
#: shows only at stops, and an excitation run rests only at its ends): also fitted by blocked CV
#: inside the validation logs.
CV_EFFECTS = ("stribeck", "load_friction", "thermal_drift", "current_offset", "payload_error", "presliding")
#: Effects the identification fit cannot see when present there too (absorbed exactly by the
#: base parameters): only CV.
CV_ONLY = ("payload_error",)
STRIBECK_VS = (0.005, 0.01, 0.02, 0.04, 0.08)   # [rad/s]
#: thermal_drift: time constants of the grease warm-up curve 1 − exp(−t/τ_w) [s]. A cold gearbox
#: warms within the first minutes, faster than the housing sensor shows; a straight line in time
#: (also tried) fits only the slow end of that range.
WARMUP_TAUS_S = (15.0, 30.0, 60.0, 120.0)
LOW_HARMONICS = (2, 3, 4)    # position_ripple: always tried (k = 1 is a gravity-like term)
#: ... in friction mode also k = 1: sin(q)·s is no gravity term, and a bearing's run-out or an
#: eccentric seal varies the friction once per revolution
FRICTION_LOW_HARMONICS = (1,) + LOW_HARMONICS
#: presliding: Dahl presliding distances [rad]; the UR10e pair's joints pick 0.1-0.3 mrad
#: (benchmarks/gap_presliding.py), the grid spans a decade either side.
PRESLIDING_DELTAS = (1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
#: ... fitted inside the validation logs also shorter ones: a LuGre bristle stiffness σ₀ of 1e4-1e5
#: N·m/rad holds a wrist's 0.3-1.5 N·m within 0.01-0.1 mrad. Only there: the identification run,
#: a Fourier excitation at rest only at its ends, cannot tell a distance shorter than its motion
#: between two samples; the validation run's stops can.
CV_PRESLIDING_DELTAS = (1e-5, 3e-5) + PRESLIDING_DELTAS
#: Friction transition widths of the friction-mode columns, as fractions of the baseline's ε: a
#: real friction changes sign within its presliding distance, often more sharply than tanh(q̇/ε)
SIGN_WIDTHS = (1.0, 0.5, 0.25)
#: current_lag: first-order time constants [s] (a current loop or measurement filter: a few ms)
LAG_TAUS_S = (0.002, 0.004, 0.007, 0.010, 0.015)
#: current_delay: delays of the exact-shift variants [s] (one to a few controller periods)
DELAYS_S = (0.002, 0.004, 0.007, 0.010, 0.015)


@dataclass(eq=False)
class Candidate:
    effect: str
    joint: int | None                    # 0-based; None: acts on all joints
    variant: str
    mode: str                            # "ident" or "cv"
    columns: tuple[str, ...]
    build: Callable[[SetContext], np.ndarray] = field(repr=False)   # → (N, 6, k)
    settings: dict = field(default_factory=dict)
    #: the columns on the rows of ``joint`` alone (each (N,) or a scalar), the other rows zero;
    #: None: only ``build`` (the fits then scan its rows for the joints it touches)
    on_joint: Callable[[SetContext], list] | None = field(default=None, repr=False)

    @property
    def key(self) -> tuple[str, int | None]:
        return (self.effect, self.joint)

    @property
    def name(self) -> str:
        where = "all joints" if self.joint is None else f"joint {self.joint + 1}"
        v = f" ({self.variant})" if self.variant else ""
        return f"{self.effect}{v} on {where} [{self.mode}]"

    @property
    def k(self) -> int:
        return len(self.columns)

    def features(self, ctx: SetContext) -> np.ndarray:
        # built afresh (bounded memory: the scorer keeps only their statistics); only the payload's
        # few columns, costly to build, are kept while a diagnosis runs (payload_error)
        f = np.asarray(self.build(ctx), float)
        assert f.shape == (ctx.n, 6, self.k), (self.name, f.shape)
        return f

    def joint_columns(self, ctx: SetContext) -> np.ndarray | None:
        """(N, k) the columns on the rows of ``joint`` (:attr:`on_joint`; the same numbers as
        ``features(ctx)[:, joint]``, without the (N, 6, k) array), or None."""
        if self.on_joint is None:
            return None
        return np.stack([np.asarray(c, float) * np.ones(ctx.n) for c in self.on_joint(ctx)], axis=1)

    def magnitude(self, beta: np.ndarray, spec=None) -> dict:
        """The fitted coefficients in the effect's own terms."""
        b = np.asarray(beta, float)
        e = self.effect
        out: dict = {"coefficients": [float(x) for x in b]}
        if e == "stribeck":
            out.update(extra_static_friction_nm=float(b[0]), stribeck_velocity_rad_s=self.settings["vs"])
        elif e == "load_friction":
            out.update(coefficient=float(b[0]))
        elif e == "quadratic_viscous":
            out.update(coefficient_nm_s2=float(b[0]))
        elif e == "neighbour_load_friction":
            out.update(coefficient=float(b[0]), neighbour_joint=self.settings["neighbour"] + 1)
        elif e == "asymmetric_coulomb":
            out.update(coulomb_difference_nm=float(2 * b[0]))
        elif e == "current_lag":
            # g·(lag_T − 1) ≈ −g·T·s on slow motion: the lag it amounts to; T the grid's form
            out.update(time_constant_s=float(b[0] * self.settings["tau_s"]), form_time_constant_s=self.settings["tau_s"],
                       lag_gain=float(b[0]))
        elif e == "thermal_drift":
            out.update(drift_variable=self.variant, viscous_change_nm_s_per_unit=float(b[0]),
                       coulomb_change_nm_per_unit=float(b[1]))
        elif e == "position_ripple":
            out.update(harmonic=self.settings["k"], mode=self.settings["ripple_mode"],
                       amplitude_nm=float(np.hypot(b[0], b[1])),
                       phase_rad=float(np.arctan2(b[1], b[0])))
        elif e == "current_delay" and "delay_s" in self.settings:
            out.update(delay_s=float(b[0] * self.settings["delay_s"]), form_delay_s=self.settings["delay_s"],
                       delay_gain=float(b[0]))    # g·shift_d ≈ −g·d·s on slow motion
        elif e == "current_delay":
            out.update(delay_s=float(-b[0]))
        elif e == "torque_constant_error":
            if b[0] > -1:
                out.update(gain_factor=float(1.0 / (1.0 + b[0])))
            else:
                out["absent"] = {"gain_factor": "the fitted correction leaves no positive gain "
                                                "(1 + coefficient <= 0)"}
        elif e == "current_offset":
            out.update(offset_nm=float(b[0]))
            if spec is not None and self.joint is not None:
                out.update(offset_a=float(b[0] / spec.drive_gains[self.joint]))
        elif e == "payload_error":
            m = float(b[0])
            out.update(mass_kg=m, first_moment_kg_m=[float(x) for x in b[1:4]])
        elif e == "presliding":
            out.update(holding_friction_nm=float(b[0]), presliding_distance_rad=self.settings["delta"])
        elif e == "joint_elasticity":
            out.update(inertia_over_stiffness_s2=float(-b[0]))
            if b[0] < 0:
                out.update(resonance_hz=float(1.0 / (2 * np.pi * np.sqrt(-b[0]))))
        return out


def _joint(effect: str, j: int, variant: str, mode: str, columns: tuple[str, ...], cols,
           settings: dict | None = None) -> Candidate:
    """A candidate on the rows of joint ``j`` alone: ``cols(ctx)`` its columns there."""
    return Candidate(effect, j, variant, mode, columns, lambda ctx: _on_joint(ctx, j, cols(ctx)),
                     settings or {}, cols)


def _on_joint(ctx: SetContext, j: int, cols) -> np.ndarray:
    cols = [np.asarray(c, float) * np.ones(ctx.n) for c in cols]
    out = np.zeros((ctx.n, 6, len(cols)))
    for i, c in enumerate(cols):
        out[:, j, i] = c
    return out


def _segment_first(ctx: SetContext, x: np.ndarray) -> np.ndarray:
    """(N, 6) value of x at the first sample of each sample's segment."""
    seg = ctx.data.segment
    starts = np.r_[0, np.flatnonzero(np.diff(seg) != 0) + 1]
    first = np.zeros_like(x)
    bounds = np.r_[starts, len(seg)]
    for a, b in zip(bounds[:-1], bounds[1:]):
        first[a:b] = x[a]
    return first


def stribeck(j: int, vs: float, mode: str = "ident") -> Candidate:
    def cols(ctx):
        return [features.stribeck(ctx.qd[:, j], ctx.friction_eps, vs)]
    return _joint("stribeck", j, f"v_s={vs:g} rad/s", mode, ("exp(-(qd/vs)^2)*sign(qd)",), cols,
                  {"vs": vs})


def load_friction(j: int, mode: str = "ident") -> Candidate:
    def cols(ctx):
        return [features.load_friction(ctx.tau_link[:, j], ctx.sign()[:, j])]
    return _joint("load_friction", j, "", mode, ("|tau_link|*sign(qd)",), cols)


def thermal_drift(j: int, variable: str, mode: str = "ident", reference: np.ndarray | None = None,
                  tau_s: float | None = None) -> Candidate:
    def cols(ctx):
        if variable == "time":
            x = ctx.data.run_time / 60.0
        elif variable == "warmup":
            x = -np.expm1(-ctx.data.run_time / tau_s)
        else:
            temp = ctx.data.temperature
            if temp is None:
                x = np.zeros(ctx.n)
            elif variable == "temperature":
                x = (temp - _segment_first(ctx, temp))[:, j]
            else:
                x = temp[:, j] - reference[j]
        return [x * ctx.qd[:, j], x * ctx.sign()[:, j]]
    if variable == "warmup":
        label = f"warm-up 1-exp(-t/{tau_s:g} s)"
    else:
        unit = {"time": "min", "temperature": "°C since run start", "temperature_abs": "°C vs ident"}
        label = f"{variable} [{unit[variable]}]"
    return _joint("thermal_drift", j, label, mode, ("x*qd", "x*sign(qd)"), cols,
                  {"variable": variable, "tau_s": tau_s})


def _sign(ctx: SetContext, j: int, width: float) -> np.ndarray:
    """(N,) tanh(q̇_j/(width·ε)): the baseline's Coulomb state, or a sharper one (``width`` < 1)."""
    return ctx.sign()[:, j] if width == 1.0 else np.tanh(ctx.qd[:, j] / (width * ctx.friction_eps))


def _width_label(width: float) -> str:
    return "" if width == 1.0 else f", sign width {width:g} eps"


def position_ripple(j: int, k: int, ripple_mode: str, mode: str = "ident", width: float = 1.0) -> Candidate:
    def cols(ctx):
        q = ctx.q[:, j]
        s = _sign(ctx, j, width) if ripple_mode == "friction" else 1.0
        return [np.sin(k * q) * s, np.cos(k * q) * s]
    return _joint("position_ripple", j, f"k={k} {ripple_mode}{_width_label(width)}", mode, ("sin(kq)", "cos(kq)"),
                  cols, {"k": int(k), "ripple_mode": ripple_mode, "sign_width": width})


def shifted(ctx: SetContext, j: int, d: float) -> np.ndarray:
    """(N,) τ̂_j(t − d) − τ̂_j(t) per segment (0 where t − d falls before the segment's start)."""
    from urident.gap.residual import segment_slices

    out = np.zeros(ctx.n)
    for sl in segment_slices(ctx.data.prepared.segment):
        ts, th = ctx.t[sl], ctx.tau_hat[sl, j]
        out[sl] = np.where(ts - d >= ts[0], np.interp(ts - d, ts, th) - th, 0.0)
    return out


def current_delay(j: int, mode: str = "ident", delay_s: float | None = None) -> Candidate:
    """The delay's first-order column dτ̂/dt, or (``delay_s``) the exact shift by that delay."""
    if delay_s is None:
        return _joint("current_delay", j, "", mode, ("dtau/dt",), lambda ctx: [ctx.dtau[:, j]])
    return _joint("current_delay", j, f"d={1000 * delay_s:g} ms", mode, ("tau_hat(t-d)-tau_hat",),
                  lambda ctx: [shifted(ctx, j, delay_s)], {"delay_s": float(delay_s)})


def quadratic_viscous(j: int, mode: str = "ident") -> Candidate:
    return _joint("quadratic_viscous", j, "", mode, ("qd*|qd|",),
                  lambda ctx: [features.quadratic_viscous(ctx.qd[:, j])])


def neighbour_load_friction(j: int, k: int, mode: str = "ident", width: float = 1.0) -> Candidate:
    """Friction of joint ``j`` driven by the load of the neighbour joint ``k`` (0-based)."""
    def cols(ctx):
        return [features.load_friction(ctx.tau_link[:, k], _sign(ctx, j, width))]
    return _joint("neighbour_load_friction", j, f"load of joint {k + 1}{_width_label(width)}", mode,
                  ("|tau_link,k|*sign(qd)",), cols, {"neighbour": k, "sign_width": width})


def asymmetric_coulomb(j: int, mode: str = "ident") -> Candidate:
    return _joint("asymmetric_coulomb", j, "", mode, ("|sign(qd)|",), lambda ctx: [np.abs(ctx.sign()[:, j])])


def lagged(ctx: SetContext, j: int, tau_s: float) -> np.ndarray:
    """(N,) τ̂_j through 1/(τs + 1), per segment (each starts at rest on its first sample)."""
    from urident.gap.residual import segment_slices
    from urident.simcontroller.effects.sensor import first_order_lag

    out = np.empty(ctx.n)
    for sl in segment_slices(ctx.data.segment):
        out[sl] = first_order_lag(ctx.t[sl], ctx.tau_hat[sl, j], tau_s)
    return out


def current_lag(j: int, tau_s: float, mode: str = "ident") -> Candidate:
    return _joint("current_lag", j, f"T={1000 * tau_s:g} ms", mode, ("lag_T(tau_hat)-tau_hat",),
                  lambda ctx: [lagged(ctx, j, tau_s) - ctx.tau_hat[:, j]], {"tau_s": float(tau_s)})


def torque_constant_error(j: int, mode: str = "ident") -> Candidate:
    return _joint("torque_constant_error", j, "", mode, ("tau_hat",), lambda ctx: [ctx.tau_hat[:, j]])


def current_offset(j: int, mode: str = "ident") -> Candidate:
    return _joint("current_offset", j, "", mode, ("1",), lambda ctx: [1.0])


def joint_elasticity(j: int, mode: str = "ident") -> Candidate:
    return _joint("joint_elasticity", j, "", mode, ("d2tau_link/dt2",), lambda ctx: [ctx.ddtau_link[:, j]])


#: One Dahl state per (data set, δ) for all joints: six joints' candidates share it.
_DAHL: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _dahl(data, delta: float) -> np.ndarray:
    from urident.ident.friction import dahl_states, velocity_displacement

    per_set = _DAHL.setdefault(data, {})
    if delta not in per_set:
        p = data.prepared
        grid = CV_PRESLIDING_DELTAS if delta in CV_PRESLIDING_DELTAS else (delta,)   # the grid at once
        z = dahl_states(velocity_displacement(p.t, p.qd, p.segment), grid, p.segment)
        for dg, zg in zip(grid, z):
            per_set.setdefault(dg, np.ascontiguousarray(zg))
    return per_set[delta]


def presliding(j: int, delta: float, mode: str = "ident") -> Candidate:
    def cols(ctx):
        # z − tanh: the Dahl state minus the baseline's own Coulomb state (the difference is
        # what the baseline lacks: friction held at standstill and the presliding transition)
        return [_dahl(ctx.data, delta)[:, j] - ctx.sign()[:, j]]
    return _joint("presliding", j, f"Dahl delta={delta:g} rad", mode, ("z-tanh(qd/eps)",), cols,
                  {"delta": float(delta)})


def set_payload_columns(spec, ctx) -> np.ndarray:
    """(N, 6, 4) :func:`urident.ident.features.payload_columns` of a set's motion, built once per
    set during a diagnosis (kept read-only in its cache; the events' smooth basis shares them)."""
    from urident.model import regressor_blocks

    keep = isinstance(ctx, SetContext) and ctx.keeps_design()
    key = ("payload_columns", spec.name)
    if keep and key in ctx.cache:
        return ctx.cache[key]
    cols = features.payload_columns(regressor_blocks(spec, ctx.q, ctx.qd, ctx.qdd, ctx.friction_eps), spec.tool_xyz)
    if keep:
        cols.flags.writeable = False
        ctx.cache[key] = cols
    return cols


def payload_error(spec, mode: str = "cv") -> Candidate:
    def build(ctx):
        return set_payload_columns(spec, ctx)
    return Candidate("payload_error", None, "point mass at the tool", mode,
                     ("tool point mass", "m*rho_x6", "m*rho_y6", "m*rho_z6"), build)


def perpendicular_neighbours(spec, j: int) -> list[int]:
    """0-based neighbours of joint ``j`` whose axis is perpendicular to its own (DH twist ±π/2):
    only their moment bends ``j``'s bearing; a parallel neighbour's torque acts about ``j``'s own
    axis, in its own load (load_friction)."""
    alpha = np.asarray(spec.dh["alpha"], float)
    return [k for k in (j - 1, j + 1) if 0 <= k < len(alpha) and abs(np.sin(alpha[min(j, k)])) > 0.5]


def families(spec, ident: SetContext, valid: SetContext, effects=EFFECTS, ripple_peaks: int = 3,
             joints=range(6)) -> list[list[Candidate]]:
    """Every (effect, joint, mode) with its variants; the diagnosis keeps, per family, the variant
    that fits the identification data best (the validation data in CV mode;
    :func:`urident.gap.significance.choose_variant`: again on top of a friction finding on the
    joint)."""
    from urident.gap.maps import angle_spectrum
    from urident.gap.structure import angle_harmonics

    out: list[list[Candidate]] = []
    have_temp = ident.data.temperature is not None and valid.data.temperature is not None
    t_ref = np.mean(ident.data.temperature, axis=0) if have_temp else None
    r_id = ident.residual
    for e in effects:
        if e == "payload_error":
            out.append([payload_error(spec, "cv")])
            continue
        for j in joints:
            modes = ["cv"] if e in CV_ONLY else (["ident", "cv"] if e in CV_EFFECTS else ["ident"])
            for mode in modes:
                if e == "stribeck":
                    fam = [stribeck(j, vs, mode) for vs in STRIBECK_VS]
                elif e == "load_friction":
                    fam = [load_friction(j, mode)]
                elif e == "thermal_drift":
                    fam = [thermal_drift(j, "time", mode)]
                    fam += [thermal_drift(j, "warmup", mode, tau_s=tau) for tau in WARMUP_TAUS_S]
                    if have_temp:
                        fam += [thermal_drift(j, "temperature", mode)]
                        if mode == "ident":
                            fam += [thermal_drift(j, "temperature_abs", mode, t_ref)]
                elif e == "position_ripple":
                    spec_j = angle_spectrum(r_id[:, j], ident.q[:, j], ident.qd[:, j], ident.friction_eps)
                    # low flexspline harmonics always, plus the spectrum's peaks, and the clear
                    # peaks up to the samples' angle-Nyquist (a gear harmonic such as 2·101)
                    fast = angle_harmonics(r_id[:, j], ident.q[:, j], ident.qd[:, j],
                                           ident.data.sample_rate, ident.sign()[:, j], ripple_peaks)
                    ks_t = sorted(set(LOW_HARMONICS) | set(spec_j.peaks(ripple_peaks))
                                  | {h["k"] for h in fast if h["mode"] == "torque"})
                    ks_f = sorted(set(FRICTION_LOW_HARMONICS) | set(spec_j.peaks(ripple_peaks, friction=True))
                                  | {h["k"] for h in fast if h["mode"] == "friction"})
                    fam = [position_ripple(j, k, "torque", mode) for k in ks_t]
                    fam += [position_ripple(j, k, "friction", mode, w) for k in ks_f for w in SIGN_WIDTHS]
                elif e == "current_delay":
                    fam = [current_delay(j, mode)] + [current_delay(j, mode, d) for d in DELAYS_S]
                    if "current_lag" in effects:      # one family: the measurement's dynamics
                        fam += [current_lag(j, tau, mode) for tau in LAG_TAUS_S]
                elif e == "quadratic_viscous":
                    fam = [quadratic_viscous(j, mode)]
                elif e == "neighbour_load_friction":
                    fam = [neighbour_load_friction(j, k, mode, w) for k in perpendicular_neighbours(spec, j)
                           for w in SIGN_WIDTHS]
                elif e == "asymmetric_coulomb":
                    fam = [asymmetric_coulomb(j, mode)]
                elif e == "current_lag":
                    fam = [] if "current_delay" in effects else [current_lag(j, tau, mode) for tau in LAG_TAUS_S]
                elif e == "torque_constant_error":
                    fam = [torque_constant_error(j, mode)]
                elif e == "current_offset":
                    fam = [current_offset(j, mode)]
                elif e == "joint_elasticity":
                    fam = [joint_elasticity(j, mode)]
                elif e == "presliding":
                    fam = [presliding(j, d, mode) for d in (CV_PRESLIDING_DELTAS if mode == "cv" else PRESLIDING_DELTAS)]
                else:
                    raise ValueError(f"unknown effect {e!r}")
                if fam:
                    out.append(fam)
    return out
