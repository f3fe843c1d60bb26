"""Post-hoc view of a log: measured vs predicted torque, residual, metrics, robot in 3-D.

Used by ``urident view``. It draws the arrays it is given: the prediction and its metrics come
from :func:`urident.ident.predict_recordings` (pass a ``prefix`` so several comparisons can share
one recording).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from urident.model.robot import RobotSpec
from urident.viz.robot3d import DEFAULT_POSE_RATE_HZ, log_robot_motion
from urident.viz.torque_views import (
    log_joint_series,
    log_metrics,
    log_text,
    log_torque_comparison,
    metrics_markdown,
    torque_metrics,
)


MAX_DISPLAY_SAMPLES = 50_000  # per time series sent to Rerun: hours of 500 Hz data stay drawable


def display_stride(n: int, max_samples: int = MAX_DISPLAY_SAMPLES) -> int:
    """Every k-th sample to draw so that at most ``max_samples`` of ``n`` are sent (metrics use all)."""
    return max(1, -(-int(n) // int(max_samples)))


def describe_recording(recording: Any) -> str:
    """Markdown lines describing a loaded log (source, robot, samples, duration, status)."""
    lines = [f"- log: `{recording.source}`" if recording.source else "- log: (in memory)",
             f"- robot: {recording.robot or 'unknown'}",
             f"- samples: {len(recording)} over {recording.duration:.3f} s"
             + (f" ({recording.rate_hz:g} Hz)" if recording.rate_hz else ""),
             f"- status: {recording.status}"]
    reason = recording.metadata.get("abort_reason")
    if reason:
        lines.append(f"- abort reason: {reason}")
    dropped = recording.dropped.get("count", 0)
    if dropped:
        lines.append(f"- rows dropped while loading: {dropped}")
    return "\n".join(lines) + "\n"


def log_recording_comparison(
    rec: rr.RecordingStream,
    spec: RobotSpec,
    recording: Any,
    t: np.ndarray,
    q: np.ndarray,
    tau_measured: np.ndarray,
    tau_predicted: np.ndarray,
    *,
    e_n: float | None = None,
    rms: np.ndarray | None = None,
    index: np.ndarray | None = None,
    prefix: str = "torque",
    metrics_prefix: str = "metrics",
    summary_path: str = "summary",
    title: str = "Measured vs predicted torque",
    pose_rate_hz: float | None = DEFAULT_POSE_RATE_HZ,
    robot_path: str | None = "robot",
) -> dict[str, float]:
    """Log a prediction of a :class:`urident.logs.Recording`: measured and predicted torque
    ``(N, 6)`` at times ``t``, tracking error when the log has ``target_q`` (``index``: the
    recording's samples shown, default all), metrics as scalars and markdown (``e_n``/``rms`` as
    computed by the caller), and the motion ``q`` decimated to ``pose_rate_hz``
    (``robot_path=None`` skips it). Series are drawn at every :func:`display_stride`-th sample
    (at most :data:`MAX_DISPLAY_SAMPLES`); metrics use every sample. Returns the metrics
    (``e_N``, ``rms/{joint}``, …)."""
    joints = spec.joint_names
    t = np.asarray(t, dtype=float)
    tau_m = np.asarray(tau_measured, dtype=float)
    tau_p = np.asarray(tau_predicted, dtype=float)
    if tau_p.shape != tau_m.shape or tau_m.shape != (len(t), 6):
        raise ValueError(f"measured and predicted torque must be ({len(t)}, 6), got {tau_m.shape} "
                         f"and {tau_p.shape}")
    k = display_stride(len(t))
    log_torque_comparison(rec, t[::k], tau_m[::k], tau_p[::k], prefix=prefix, joint_names=joints)
    if getattr(recording, "target_q", None) is not None:
        sel = np.arange(len(recording.q)) if index is None else np.asarray(index)
        sel = sel[::k]
        log_joint_series(rec, "tracking", t[::k], recording.target_q[sel] - recording.q[sel], joints)
    metrics = torque_metrics(tau_m, tau_p, joints, e_n=e_n, rms=rms)
    t_end = float(t[-1]) if len(t) else 0.0
    log_metrics(rec, {k: v for k, v in metrics.items() if not k.startswith("rms_measured/")},
                prefix=metrics_prefix, t=t_end)
    text = metrics_markdown(metrics, title, joints) + "\n" + describe_recording(recording)
    log_text(rec, summary_path, text)
    if robot_path is not None:
        log_robot_motion(rec, spec, t, q, path=robot_path, rate_hz=pose_rate_hz)
    return metrics


def log_prediction(rec: rr.RecordingStream, spec: RobotSpec, recording: Any, prediction: Any, title: str,
                   pose_rate_hz: float | None = None):
    """A log's measured torques against a model's (``prediction``:
    :func:`urident.ident.predict_recordings` of ``recording``), with the arm in 3-D, to ``rec``
    (``urident view``); returns the :class:`urident.ident.ValidationResult`."""
    result = prediction.validation()
    log_recording_comparison(
        rec, spec, recording, prediction.data.t, prediction.data.q, result.tau_measured,
        result.tau_predicted, e_n=result.e_n, rms=result.rms_nm, index=prediction.sample_index(),
        title=title, pose_rate_hz=pose_rate_hz)
    return result

