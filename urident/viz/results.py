"""Identification and validation results in a Rerun recording (``urident identify`` /
``urident validate`` with ``--rerun`` or ``--save``)."""

from __future__ import annotations

from typing import Sequence

import rerun as rr

from urident.viz.torque_views import log_metrics, log_text, log_torque_comparison


def log_torque_results(rec: rr.RecordingStream, joint_names: Sequence[str],
                       results: Sequence[tuple[str, object]], prefix: str, title: str) -> None:
    """For each ``(label, result)`` — a :class:`urident.ident.ValidationResult` or anything with
    ``t, tau_measured, tau_predicted, e_n, rms_nm, method`` — the measured, predicted and residual
    torques under ``{prefix}/{label}/torque/{joint}``, its e_N and per-joint RMS under
    ``{prefix}/{label}/metrics``, and one markdown table of all of them at ``{prefix}/summary``."""
    lines = [f"# {title}", "", "| run | method | e_N | " + " | ".join(f"RMS {j} [N·m]" for j in joint_names) + " |",
             "| --- | --- | ---: | " + " | ".join("---:" for _ in joint_names) + " |"]
    for label, r in results:
        base = f"{prefix}/{label}"
        log_torque_comparison(rec, r.t, r.tau_measured, r.tau_predicted, prefix=f"{base}/torque",
                              joint_names=joint_names)
        metrics = {"e_N": float(r.e_n)}
        metrics.update({f"rms/{j}": float(v) for j, v in zip(joint_names, r.rms_nm)})
        log_metrics(rec, metrics, prefix=f"{base}/metrics")
        lines.append(f"| {label} | {r.method} | {r.e_n:.4f} | "
                     + " | ".join(f"{v:.3f}" for v in r.rms_nm) + " |")
    log_text(rec, f"{prefix}/summary", "\n".join(lines))
