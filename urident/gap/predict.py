"""How far the findings shrink another run's residual, predicted from that run's motion alone.

The validation shrink of a joint, 100·(1 − RMS_after/RMS_before), holds for another run only when
that run excites the effect as the validation run did. An effect that grows with time (a warm-up)
or with load (load-dependent friction) does more on a longer or more heavily loaded run, so the
validation figure under-shoots there. The prediction here extrapolates instead: the chosen
effects, fitted as the diagnosis fitted them, are applied to the other run's *motion* (joint
angles, velocities, accelerations, the baseline's torque on them, time since the run's start,
logged temperatures; never its measured current), giving the correction C_j (RMS on joint j) that
the findings make there. What the findings leave on the validation run, U_j, splits into white
noise σ_j (:func:`urident.gap.significance.noise_sigma`, the same on any run of that arm), the
form misfit M_j of a delay finding on that joint (below) and a structured rest R_j² = U_j² − σ_j² − M_j²
(the misfit the findings leave, which an effect's imperfect form leaves in proportion to the
effect). On the other run U'_j² = σ_j² + R_j²·ρ_j² + M'_j², ρ_j the RMS ratio (other / validation)
of the correction made by the joint's own findings other than a delay or a whole-arm payload (1
where it has none: the rest is then the baseline's own misfit, carried over as it is), and

    predicted shrink_j = 100·(1 − U'_j / √(U'_j² + C'_j² + 2·X'_j))

X'_j the mean product of the correction and the form misfit M' (0 without a delay: the correction
is taken as uncorrelated with what is left). With no noise this is the validation shrink; with a
correction that fits, R ≈ M ≈ 0, it is what the correction does against the noise.

A delay's column −d·dτ̂/dt is the first-order, low-passed form of the shifted torque
τ̂(t − d) − τ̂(t); it cannot follow the Coulomb step at a velocity reversal, which is sharper on a
faster run, so there its misfit grows faster than its correction (:func:`delay_form_misfit`
computes it on the run's motion, with the delay :func:`delay_behind` the fitted coefficient, whose
column over-states the delay by the same attenuation).

Per effect class, the quantity carried to the other run (the columns of
:mod:`urident.gap.candidates` evaluated there, coefficients unchanged):

=======================  ==========================================================================
stribeck                 the time the run spends near zero velocity: exp(−(q̇/v_s)²)·sign(q̇)
load_friction            the run's link-torque distribution |τ̂_link| (from the model on its motion)
thermal_drift            the run's warm-up: 1 − exp(−t/τ_w) over its own duration (fitted τ_w and
                         amplitude), minutes elapsed (time variant), or its logged temperature
                         history (temperature variants), times q̇ and sign(q̇)
quadratic_viscous        its speed: q̇·|q̇|
neighbour_load_friction  the neighbour's link-torque distribution |τ̂_link,k|
position_ripple          the angles it visits: sin/cos(k·q) (× sign(q̇) for friction ripple)
current_delay            how fast its torque changes, dτ̂/dt, and the model torque shifted by
                         the delay behind the fit, τ̂(t − d) − τ̂(t): the column's misfit there
                         (the exact-shift variant: τ̂(t − d) − τ̂(t) itself)
current_lag              its model torque through the fitted lag, lag_T(τ̂) − τ̂
asymmetric_coulomb       the time it spends moving: |tanh(q̇/ε)|
torque_constant_error    its torque τ̂
current_offset           nothing (a constant)
payload_error            its gravity and inertial load of the payload (the regressor on its motion)
joint_elasticity         its link-torque curvature d²τ̂_link/dt²
presliding               its stops and reversals: the Dahl state minus tanh(q̇/ε)
=======================  ==========================================================================

Identification-mode effects carry their share of the base parameters' refit too (the correction is
``Fit.change``, the same as :mod:`urident.gap.check` applies).
"""

from __future__ import annotations

import numpy as np

from urident.gap.candidates import shifted
from urident.gap.data import GapSet
from urident.gap.residual import SetContext, make_context


def extrapolated_shrink_pct(remaining_rms, correction_rms, cross=None) -> np.ndarray:
    """100·(1 − U/√(U² + C² + 2X)) per joint (module doc), X the mean product of the correction
    and what it leaves where that is known (a delay's form misfit), else 0; 0 with no correction."""
    u = np.asarray(remaining_rms, float)
    c = np.asarray(correction_rms, float)
    x = np.zeros_like(c) if cross is None else np.asarray(cross, float)
    total = np.sqrt(np.maximum(u ** 2 + c ** 2 + 2 * x, 0.0))
    return np.where(total > 0, 100.0 * (1.0 - u / np.where(total > 0, total, 1.0)), 0.0)


def delay_behind(beta: float, ctx: SetContext, j: int, iterations: int = 4) -> float:
    """The delay d [s] whose exact shift of τ̂_j, fitted on ``ctx`` by the column dτ̂_j/dt, gives
    the fitted coefficient ``beta``: the low-passed column is attenuated at the sharp Coulomb
    steps of the reversals, so the fitted −β over-states d (11.8 ms for 10 ms in the unit test)."""
    x = ctx.dtau[:, j]
    xx = float(x @ x)
    d = -beta
    if xx <= 0 or d == 0:
        return d
    for _ in range(iterations):
        k = -float(shifted(ctx, j, d) @ x) / (d * xx)    # column coefficient per second of delay
        if not k > 0:
            return -beta
        d = -beta / k
    return d


def delay_form_misfit(fit, ctx: SetContext) -> np.ndarray:
    """(N, 6) what ``fit``'s current_delay columns leave on ``ctx``: the model torque shifted by
    the delay behind them (:func:`delay_behind`), τ̂(t − d) − τ̂(t), minus their correction
    β·dτ̂/dt (the Coulomb step at a reversal, sharper on faster motion); 0 on other joints and
    for the exact-shift variants (their column is the shift itself)."""
    out = np.zeros((ctx.n, 6))
    for c, b in fit.coefficients().items():
        if c.effect != "current_delay" or "delay_s" in c.settings:
            continue
        j, beta = c.joint, float(b[0])
        fitted_on = fit.scorer.ident if c in fit.ident else fit.scorer.valid
        out[:, j] = shifted(ctx, j, delay_behind(beta, fitted_on, j)) - beta * ctx.dtau[:, j]
    return out


def change_share(fit, ctx: SetContext, c) -> np.ndarray:
    """(N, 6) candidate ``c``'s share of ``fit.change(ctx)``: its columns and, in identification
    mode, its share of the base parameters' refit."""
    b = fit.coefficients()[c]
    out = c.features(ctx) @ b
    if c in fit.ident:
        out = out - ctx.design_product(fit.g[c] @ b)
    return out


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(x ** 2, axis=0))


def rest_ratio(fit, valid: SetContext, other: SetContext) -> np.ndarray:
    """(6,) how the structured leftover not explained by a delay's form misfit scales on the other
    run: with the correction of the joint's own findings other than delays, RMS on the other run
    over RMS on the validation run; 1 (carried over as it is) where the joint has none: the slow
    validation run barely excites a delay, so most of its leftover there is the baseline's own
    misfit, not the delay's, and another joint's refit collateral is no effect of this joint whose
    imperfect form would grow. A whole-arm finding (a payload) is no joint's own: its columns are
    the rigid-body regressor itself, no imperfect form (counted, its inertial torque on a faster
    run scaled the rest of a delay's joint: seed 213 scenario 23, 8 % predicted, 60 % actual)."""
    cands = [c for c in fit.coefficients() if c.effect != "current_delay" and c.joint is not None]
    shares = {c: [change_share(fit, ctx, c) for ctx in (valid, other)] for c in cands}
    out = np.ones(6)
    for j in range(6):
        own = [shares[c] for c in cands if c.joint == j]
        if not own:
            continue
        cv, co = (_rms(sum(s[k] for s in own)[:, j]) for k in (0, 1))
        if cv > 0:
            out[j] = co / cv
    return out


def remaining_rms(fit, c_valid, c_other, misfit_valid=None, misfit_other=None, ratio=None) -> np.ndarray:
    """(6,) what ``fit`` is expected to leave on the other run: white noise, the form misfit the
    other run's motion gives a delay's column (``misfit_other``, RMS; :func:`delay_form_misfit`),
    and the rest of the validation run's structured leftover (less ``misfit_valid``) scaled with
    the correction, ``c_other / c_valid`` or ``ratio`` (:func:`rest_ratio`) (module doc)."""
    from urident.gap.significance import noise_sigma

    u = np.sqrt(np.mean(fit.residual ** 2, axis=0))
    sigma = np.minimum(noise_sigma(fit.residual), u)
    m_v = np.zeros(6) if misfit_valid is None else np.asarray(misfit_valid, float)
    m_o = np.zeros(6) if misfit_other is None else np.asarray(misfit_other, float)
    structured2 = np.maximum(u ** 2 - sigma ** 2 - m_v ** 2, 0.0)
    if ratio is None:
        ratio = np.where(c_valid > 0, c_other / np.where(c_valid > 0, c_valid, 1.0), 1.0)
    return np.sqrt(sigma ** 2 + structured2 * ratio ** 2 + m_o ** 2)


def predict_shrink(res, spec, other: GapSet | SetContext, fit=None, valid: SetContext | None = None) -> np.ndarray:
    """(6,) predicted shrink [%] per joint of ``res``'s findings on the run ``other``, from its
    motion (module doc); or of ``fit`` (a :class:`~urident.gap.scoring.Fit`) fitted with the
    validation set ``valid``."""
    fit = res.fit if fit is None else fit
    valid = res.valid if valid is None else valid
    ctx = other if isinstance(other, SetContext) else make_context(spec, res.model, other)
    change_o = fit.change(ctx) if (list(fit.ident) or list(fit.cv)) else np.zeros((ctx.n, 6))
    change_v = valid.residual - fit.residual
    m_v, m_o = delay_form_misfit(fit, valid), delay_form_misfit(fit, ctx)
    ratio = rest_ratio(fit, valid, ctx)
    u = remaining_rms(fit, _rms(change_v), _rms(change_o), _rms(m_v), _rms(m_o), ratio)
    return extrapolated_shrink_pct(u, _rms(change_o), np.mean(m_o * change_o, axis=0))
