"""How far the findings shrink another run's residual, predicted from that run's motion alone.

The validation shrink of a joint, 100·(1 − RMS_after/RMS_before), holds for another run only when
that run excites the effect as the validation run did. An effect that grows with time (a warm-up)
or with load (load-dependent friction) does more on a longer or more heavily loaded run, so the
validation figure under-shoots there. The prediction here extrapolates instead: the chosen
effects, fitted as the diagnosis fitted them, are applied to the other run's *motion* (joint
angles, velocities, accelerations, the baseline's torque on them, time since the run's start,
logged temperatures; never its measured current), giving the correction C_j (RMS on joint j) that
the findings make there. What the findings leave on the validation run, U_j, splits into white
noise σ_j (:func:`urident.gap.significance.noise_sigma`, the same on any run of that arm) and a
structured part S_j² = U_j² − σ_j² (the misfit the findings leave, which an effect's imperfect
form leaves in proportion to the effect): on the other run U'_j² = σ_j² + S_j²·(C'_j/C_j)², C_j the
correction's RMS on the validation run. With the correction uncorrelated with what is left:

    predicted shrink_j = 100·(1 − U'_j / √(U'_j² + C'_j²))

(with no noise this is the validation shrink; with a correction that fits, S ≈ 0, it is what the
correction does against the noise.)

Per effect class, the quantity carried to the other run (the columns of
:mod:`urident.gap.candidates` evaluated there, coefficients unchanged):

=====================  ==========================================================================
stribeck               the time the run spends near zero velocity: exp(−(q̇/v_s)²)·sign(q̇)
load_friction          the run's link-torque distribution |τ̂_link| (from the model on its motion)
thermal_drift          the run's warm-up: 1 − exp(−t/τ_w) over its own duration (fitted τ_w and
                       amplitude), minutes elapsed (time variant), or its logged temperature
                       history (temperature variants), times q̇ and sign(q̇)
position_ripple        the angles it visits: sin/cos(k·q) (× sign(q̇) for friction ripple)
current_delay          how fast its torque changes, dτ̂/dt
torque_constant_error  its torque τ̂
current_offset         nothing (a constant)
payload_error          its gravity and inertial load of the payload (the regressor on its motion)
joint_elasticity       its link-torque curvature d²τ̂_link/dt²
presliding             its stops and reversals: the Dahl state minus tanh(q̇/ε)
=====================  ==========================================================================

Identification-mode effects carry their share of the base parameters' refit too (the correction is
``Fit.change``, the same as :mod:`urident.gap.check` applies).
"""

from __future__ import annotations

import numpy as np

from urident.gap.data import GapSet
from urident.gap.residual import SetContext, make_context


def extrapolated_shrink_pct(remaining_rms, correction_rms) -> np.ndarray:
    """100·(1 − U/√(U² + C²)) per joint (module doc); 0 where there is no correction."""
    u = np.asarray(remaining_rms, float)
    c = np.asarray(correction_rms, float)
    total = np.sqrt(u ** 2 + c ** 2)
    return np.where(total > 0, 100.0 * (1.0 - u / np.where(total > 0, total, 1.0)), 0.0)


def correction_rms(fit, ctx: SetContext) -> np.ndarray:
    """(6,) RMS of ``fit``'s correction of the prediction on ``ctx`` [N·m] (motion only)."""
    if not (list(fit.ident) or list(fit.cv)):
        return np.zeros(6)
    return np.sqrt(np.mean(fit.change(ctx) ** 2, axis=0))


def remaining_rms(fit, c_valid, c_other) -> np.ndarray:
    """(6,) what ``fit`` is expected to leave on the other run: white noise plus the validation
    run's structured leftover scaled with the correction (module doc)."""
    from urident.gap.significance import noise_sigma

    u = np.sqrt(np.mean(fit.residual ** 2, axis=0))
    sigma = np.minimum(noise_sigma(fit.residual), u)
    structured2 = u ** 2 - sigma ** 2
    ratio = np.where(c_valid > 0, c_other / np.where(c_valid > 0, c_valid, 1.0), 1.0)
    return np.sqrt(sigma ** 2 + structured2 * ratio ** 2)


def predict_shrink(res, spec, other: GapSet | SetContext, fit=None, valid: SetContext | None = None) -> np.ndarray:
    """(6,) predicted shrink [%] per joint of ``res``'s findings on the run ``other``, from its
    motion (module doc); or of ``fit`` (a :class:`~urident.gap.scoring.Fit`) fitted with the
    validation set ``valid``."""
    fit = res.fit if fit is None else fit
    valid = res.valid if valid is None else valid
    ctx = other if isinstance(other, SetContext) else make_context(spec, res.model, other)
    c_other = correction_rms(fit, ctx)
    c_valid = np.sqrt(np.mean((valid.residual - fit.residual) ** 2, axis=0))
    return extrapolated_shrink_pct(remaining_rms(fit, c_valid, c_other), c_other)
