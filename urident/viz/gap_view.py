"""The gap diagnosis in Rerun (``urident gap --save``/``--rerun``): the baseline's and the final
model's torques against the measured ones on the validation logs, the improvement per joint, the
metrics and the residual maps as tables."""

from __future__ import annotations


def log_gap_result(rec, result, spec) -> None:
    """Baseline and final comparison on the validation logs, residual maps as tables."""
    from urident.gap.report import maps_markdown
    from urident.viz.recording import close_recording
    from urident.viz.torque_views import log_joint_series, log_metrics, log_text, log_torque_comparison

    ctx = result.valid
    t = ctx.t - ctx.t[0]
    tau = ctx.tau
    names = tuple(spec.joint_names)
    log_torque_comparison(rec, t, tau, ctx.tau_hat, prefix="gap/baseline", joint_names=names)
    log_torque_comparison(rec, t, tau, tau - result.fit.residual, prefix="gap/final", joint_names=names)
    log_joint_series(rec, "gap/improvement", t, ctx.residual ** 2 - result.fit.residual ** 2, names)
    metrics = {"e_N/baseline": result.baseline_e_n, "e_N/final": result.final_e_n}
    for j, n in enumerate(names):
        metrics[f"rms/baseline/{n}"] = float(result.baseline_rms[j])
        metrics[f"rms/final/{n}"] = float(result.final_rms[j])
    log_metrics(rec, metrics, prefix="gap/metrics")
    log_text(rec, "gap/report", maps_markdown(result))
    close_recording(rec)
