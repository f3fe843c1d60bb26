"""Visualisation: Rerun live and post-hoc views (this package is the only importer of ``rerun``)
and matplotlib PNG plots (``plots``).

Importing ``urident.viz`` is cheap; ``rerun`` is imported on first use of a name below.

Post-hoc / other commands::

    from urident.viz import open_recording, close_recording, log_torque_comparison, log_metrics
    rec = open_recording("urident_validate", save="out.rrd")          # or spawn=True / connect=URL
    log_torque_comparison(rec, t, tau_measured, tau_predicted, prefix="validate/torque")
    log_metrics(rec, {"e_N": 0.05}, prefix="validate/metrics")
    log_text(rec, "validate/summary", "# Validation\\n...")
    log_robot_motion(rec, spec, t, q)
    close_recording(rec)

Predicted torques come from ``urident.ident`` (``predict_recordings``, ``StreamPredictor``);
this package only draws them.

Live (``urident run``)::

    with LiveStreamer(spec, params, spawn=True, fallback_save="run.rrd") as live:
        live.push(t, q, qd, current, target_q, late_cycles)   # each control cycle, never blocks
    # or live.close(abort_reason="...") -> LiveStats
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "TIMELINE": "recording",
    "ViewerUnavailable": "recording",
    "close_recording": "recording",
    "open_recording": "recording",
    "viewer_unavailable_reason": "recording",
    "log_event": "torque_views",
    "log_joint_series": "torque_views",
    "log_metrics": "torque_views",
    "log_text": "torque_views",
    "log_torque_comparison": "torque_views",
    "metrics_markdown": "torque_views",
    "torque_metrics": "torque_views",
    "log_robot_motion": "robot3d",
    "robot_geometry": "robot3d",
    "live_blueprint": "blueprint",
    "torque_blueprint": "blueprint",
    "LiveStats": "live",
    "LiveStreamer": "live",
    "log_recording_comparison": "replay",
    "log_torque_results": "results",
    "read_rrd": "readback",
    "add_rerun_arguments": "cli_args",
    "check_rerun_args": "cli_args",
    "open_recording_from_args": "cli_args",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'urident.viz' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"urident.viz.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
