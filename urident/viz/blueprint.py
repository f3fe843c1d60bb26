"""Default viewer layouts, so nothing needs arranging by hand.

Post-hoc (``urident view``)::

    +-------------------------+------------------+
    | torque grid, 2 × 3:     |  robot (3-D)     |
    | one time-series view    +------------------+
    | per joint: measured,    |  summary (text)  |
    | predicted, residual     +------------------+
    |                         |  metrics         |
    +-------------------------+------------------+

Live (``urident run``) adds tracking error and run status (samples, late cycles, dropped
visualisation samples, events log).
"""

from __future__ import annotations

from typing import Sequence

import rerun.blueprint as rrb

from urident.viz.recording import TIMELINE
from urident.viz.torque_views import DEFAULT_JOINT_NAMES


def _window(seconds: float | None) -> dict:
    """A scrolling time window of the last ``seconds`` (live views), or nothing."""
    if not seconds:
        return {}
    return {"time_ranges": rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.cursor_relative(seconds=-float(seconds)),
        end=rrb.TimeRangeBoundary.cursor_relative(seconds=0.0))}


def _torque_grid(prefix: str, joint_names: Sequence[str], window_s: float | None = None) -> rrb.Grid:
    return rrb.Grid(*[rrb.TimeSeriesView(origin=f"{prefix}/{joint}", name=f"{joint} τ [N·m]",
                                         **_window(window_s))
                      for joint in joint_names], grid_columns=2, name="joint torques")


def torque_blueprint(prefix: str = "torque", joint_names: Sequence[str] = DEFAULT_JOINT_NAMES,
                     robot_path: str = "robot", summary_path: str = "summary",
                     metrics_path: str = "metrics") -> rrb.Blueprint:
    """Layout for a post-hoc comparison: 6 torque plots, the robot in 3-D, summary text, and the
    metrics (e_N, per-joint RMS) as a time series."""
    return rrb.Blueprint(
        rrb.Horizontal(
            _torque_grid(prefix, joint_names),
            rrb.Vertical(
                rrb.Spatial3DView(origin=robot_path, name="robot"),
                rrb.TextDocumentView(origin=summary_path, name="summary"),
                rrb.TimeSeriesView(origin=metrics_path, name="metrics"),
                row_shares=[3, 2, 1],
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def live_blueprint(prefix: str = "torque", joint_names: Sequence[str] = DEFAULT_JOINT_NAMES,
                   robot_path: str = "robot", window_s: float | None = 10.0) -> rrb.Blueprint:
    """Layout for ``urident run``: torques, tracking error, robot, status and events; the time
    series scroll over the last ``window_s`` seconds (None: everything)."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                _torque_grid(prefix, joint_names, window_s),
                rrb.TimeSeriesView(origin="tracking", name="tracking error q_target − q [rad]",
                                   **_window(window_s)),
                row_shares=[3, 1],
            ),
            rrb.Vertical(
                rrb.Spatial3DView(origin=robot_path, name="robot"),
                rrb.TimeSeriesView(origin="status", name="run status", contents=[
                    "status/samples", "status/late_cycles", "status/dropped"]),
                rrb.TimeSeriesView(origin="metrics", name="running RMS / e_N"),
                rrb.TextLogView(origin="status/events", name="events"),
                row_shares=[3, 1, 1, 1],
            ),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )
