"""Measured vs predicted torque series, metrics and text, logged to a Rerun recording.

Entity layout under ``prefix`` (default ``torque``), one subtree per joint named as in the robot
file (``shoulder_pan`` … ``wrist_3``)::

    {prefix}/{joint}/measured     Scalars [N m]  (time series, send_columns)
    {prefix}/{joint}/predicted    Scalars [N m]
    {prefix}/{joint}/residual     Scalars [N m]  measured − predicted

Metrics go to ``metrics/{key}`` as Scalars (e.g. ``metrics/e_N``, ``metrics/rms/{joint}``) and text
to any path as a markdown TextDocument.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import rerun as rr

from urident.viz.recording import set_time, time_column

DEFAULT_JOINT_NAMES = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
SERIES = ("measured", "predicted", "residual")
SERIES_COLORS = {"measured": (31, 119, 180), "predicted": (255, 127, 14), "residual": (150, 150, 150)}
SERIES_WIDTHS = {"measured": 1.5, "predicted": 1.5, "residual": 1.0}


def _as_series(name: str, values, n: int) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape != (n, 6):
        raise ValueError(f"{name} must be ({n}, 6), got {arr.shape}")
    return arr


def log_series_style(rec: rr.RecordingStream, prefix: str = "torque",
                     joint_names: Sequence[str] = DEFAULT_JOINT_NAMES) -> None:
    """Static line names, colours and widths of the torque series (once per recording)."""
    for joint in joint_names:
        for series in SERIES:
            rec.log(f"{prefix}/{joint}/{series}",
                    rr.SeriesLines(names=series, colors=SERIES_COLORS[series],
                                   widths=SERIES_WIDTHS[series]), static=True)


def log_torque_comparison(
    rec: rr.RecordingStream,
    t: np.ndarray,
    tau_measured: np.ndarray,
    tau_predicted: np.ndarray,
    prefix: str = "torque",
    joint_names: Sequence[str] = DEFAULT_JOINT_NAMES,
    style: bool = True,
) -> None:
    """Log measured, predicted and residual torque ``(N, 6)`` at times ``t (N,)`` [s] as columns
    (fast for 10^5 samples). ``style=False`` skips the static line styling (for repeated calls
    by the live streamer, which styles once)."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    n = len(t)
    measured = _as_series("tau_measured", tau_measured, n)
    predicted = _as_series("tau_predicted", tau_predicted, n)
    if len(joint_names) != 6:
        raise ValueError(f"need 6 joint names, got {len(joint_names)}")
    if style:
        log_series_style(rec, prefix, joint_names)
    if n == 0:
        return
    residual = measured - predicted
    index = [time_column(t)]
    for j, joint in enumerate(joint_names):
        for series, values in (("measured", measured), ("predicted", predicted),
                               ("residual", residual)):
            rec.send_columns(f"{prefix}/{joint}/{series}", indexes=index,
                             columns=rr.Scalars.columns(scalars=np.ascontiguousarray(values[:, j])))


def log_joint_series(rec: rr.RecordingStream, path: str, t: np.ndarray, values: np.ndarray,
                     joint_names: Sequence[str] = DEFAULT_JOINT_NAMES) -> None:
    """Any per-joint quantity ``(N, 6)`` as ``{path}/{joint}`` scalar columns (e.g. tracking
    error ``tracking/{joint}``)."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    values = _as_series(path, values, len(t))
    if len(t) == 0:
        return
    index = [time_column(t)]
    for j, joint in enumerate(joint_names):
        rec.send_columns(f"{path}/{joint}", indexes=index,
                         columns=rr.Scalars.columns(scalars=np.ascontiguousarray(values[:, j])))


def torque_metrics(tau_measured: np.ndarray, tau_predicted: np.ndarray,
                   joint_names: Sequence[str] = DEFAULT_JOINT_NAMES, e_n: float | None = None,
                   rms=None) -> dict[str, float]:
    """``e_N`` (the paper's eq. 22) and ``rms/{joint}`` of the residual [N m] (``e_n``/``rms`` when
    the caller has them, else computed by :mod:`urident.ident.metrics`), and ``rms_measured/{joint}``."""
    from urident.ident.metrics import error_metrics, metrics

    measured = np.asarray(tau_measured, dtype=float)
    out: dict[str, float] = {}
    if e_n is None or rms is None:
        e_n, rms = (metrics(measured, tau_predicted)[:2] if len(measured)
                    else (float("nan"), np.full(6, np.nan)))
    out["e_N"] = float(e_n)
    rms_m = error_metrics(measured)[1] if len(measured) else np.full(6, np.nan)
    for j, joint in enumerate(joint_names):
        out[f"rms/{joint}"] = float(rms[j])
    for j, joint in enumerate(joint_names):
        out[f"rms_measured/{joint}"] = float(rms_m[j])
    return out


def metrics_markdown(metrics: Mapping[str, float], title: str = "Torque prediction",
                     joint_names: Sequence[str] = DEFAULT_JOINT_NAMES) -> str:
    """Markdown summary of :func:`torque_metrics` (a table per joint when rms keys are there)."""
    lines = [f"# {title}", ""]
    if "e_N" in metrics:
        lines += [f"**e_N** (paper eq. 22, ‖τ−τ̂‖/m): **{metrics['e_N']:.4f}** N·m", ""]
    if any(f"rms/{j}" in metrics for j in joint_names):
        lines += ["| joint | RMS residual [N·m] | RMS measured [N·m] |", "| --- | ---: | ---: |"]
        for joint in joint_names:
            lines.append(f"| {joint} | {metrics.get(f'rms/{joint}', float('nan')):.4g} | "
                         f"{metrics.get(f'rms_measured/{joint}', float('nan')):.4g} |")
        lines.append("")
    rest = {k: v for k, v in metrics.items()
            if k != "e_N" and not k.startswith(("rms/", "rms_measured/"))}
    for key, value in rest.items():
        lines.append(f"- {key}: {value:.6g}" if isinstance(value, (int, float)) else f"- {key}: {value}")
    return "\n".join(lines).rstrip() + "\n"


def log_metrics(rec: rr.RecordingStream, metrics: Mapping[str, float], prefix: str = "metrics",
                t: float | None = None) -> None:
    """Each numeric ``metrics[key]`` as a Scalar at ``{prefix}/{key}``; at time ``t`` [s] on the
    timeline, or static when ``t`` is None."""
    if t is not None:
        set_time(rec, t)
    for key, value in metrics.items():
        if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool):
            rec.log(f"{prefix}/{key}", rr.Scalars([float(value)]), static=t is None)


def log_text(rec: rr.RecordingStream, path: str, markdown: str, t: float | None = None) -> None:
    """A markdown TextDocument at ``path``; static unless ``t`` [s] is given."""
    if t is not None:
        set_time(rec, t)
    rec.log(path, rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN), static=t is None)


def log_event(rec: rr.RecordingStream, text: str, level: str = "INFO", t: float | None = None,
              path: str = "status/events") -> None:
    """One TextLog line (``level`` INFO, WARN, ERROR …) at ``path``, at time ``t`` if given."""
    if t is not None:
        set_time(rec, t)
    rec.log(path, rr.TextLog(text, level=level), static=t is None)
