"""The controller's own model beside the identified one, from the logged target moment."""

from __future__ import annotations

import numpy as np

from urident.gap.residual import SetContext
from urident.ident.metrics import error_metrics


def _rms(x: np.ndarray) -> np.ndarray:
    return error_metrics(x)[1]


#: The controller's model "changed between the runs" when, fitted on the identification logs'
#: target moments, it misses the validation logs' on some joint by more than this share of the
#: largest joint's target moment RMS and by more than twice its own fit error there (a 1 kg
#: payload at a UR10e's tool is ~15 % of the shoulder's torque; the real UR10e logs: 0.8 %).
CONTROLLER_CHANGE_SHARE = 0.05


def controller_reference(ctx: SetContext, ident: SetContext | None = None) -> dict | None:
    """The controller's own model on the same samples, when the logs hold its target moment
    (the torque its model computes for the target motion): RMS per joint of measured torque −
    target moment, and of the identified model's rigid-body part τ̂_link − target moment.

    Why: the target moment is the manufacturer's model, independent of our identification. On
    the real UR10e logs it carries no friction (joints 1, 5 and 6, friction-dominated there, get a
    few % of the measured torque), so it is compared with our rigid-body part: a joint where the
    two disagree by much more than elsewhere points at a rigid-body difference (a payload declared
    to the controller, a mis-identified link), not at friction. Tracking errors count in both
    figures: the target moment is computed on the target, not the measured, motion.

    With the identification logs' target moments too: did the controller's model change between
    the runs? Its torque is linear in the same regressor, so its parameters are fitted on the
    identification logs' target moments (no noise: the fit is nearly exact) and its validation
    target moments predicted. A change well above the fit's own error is a payload or tool
    declared to the controller between the runs; none means a ``payload_error`` finding is a
    payload the controller was not told about."""
    tm = _target_moment(ctx)
    if tm is None:
        return None
    r = ctx.tau - tm
    out = {"measured_minus_target_rms_nm": [float(x) for x in _rms(r)],
           "rigid_body_minus_target_rms_nm": [float(x) for x in _rms(ctx.tau_link - tm)],
           "target_rms_nm": [float(x) for x in _rms(tm)],
           # least-squares scale of measured torque on target moment, per joint (1: same size)
           "measured_over_target_scale": [float(np.sum(ctx.tau[:, j] * tm[:, j]) / np.sum(tm[:, j] ** 2))
                                          if np.any(tm[:, j]) else None for j in range(6)],
           "change_between_runs": None}
    tm_i = None if ident is None else _target_moment(ident)
    if tm_i is not None:
        beta, fit_err = _fit_design(ident, tm_i)
        change = _rms(tm - ctx.design_product(beta))
        share = change / max(float(_rms(tm).max()), 1e-12)
        changed = (share > CONTROLLER_CHANGE_SHARE) & (change > 2.0 * fit_err)
        out["change_between_runs"] = {
            "rms_nm": [float(x) for x in change], "ident_fit_rms_nm": [float(x) for x in fit_err],
            "share_of_largest_target": [float(x) for x in share],
            "changed": bool(np.any(changed))}
    return out


def _fit_design(ctx: SetContext, y: np.ndarray) -> np.ndarray:
    """Least squares (minimum norm) of ``y`` (N, 6) on the set's design matrix, streamed: per joint
    the R factor of [W_j | y_j] (:mod:`urident.ident.reduced`), then one merged triangle; and the
    fit's RMS error per joint."""
    from urident.ident.reduced import Accumulator

    acc = Accumulator()
    for a, b, blocks in ctx.chunks():
        acc.add(blocks, y[a:b])
    red = acc.result()
    n = red.n_params
    r = np.linalg.qr(np.vstack(list(red.r)), mode="r")
    beta = np.linalg.lstsq(r[:n, :n], r[:n, n], rcond=None)[0]
    return beta, np.sqrt(red.residual_sq(beta) / red.n_samples)


def _target_moment(ctx: SetContext) -> np.ndarray | None:
    tm = ctx.data.target_moment
    if tm is None:
        return None
    tm = np.asarray(tm, float)
    return tm if np.all(np.isfinite(tm)) else None
