"""Gaps in a recording: controller samples that never reached the log.

One rule everywhere (the session recorder, the loaders, every consumer): two consecutive samples
more than :data:`GAP_FACTOR` nominal periods apart enclose a gap; the number of missing periods is
the rounded spacing minus one. The nominal period is the log's rate (sidecar) or, for a foreign log
without one, the median sample spacing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GAP_FACTOR = 1.5


@dataclass(frozen=True)
class Gap:
    index: int          # the first sample after the gap
    t_before: float     # timestamp of the last sample before it [s]
    t_after: float      # timestamp of the first sample after it [s]
    missing: int        # periods missing

    def as_dict(self) -> dict:
        return {"after_s": self.t_before, "resume_s": self.t_after, "missing_periods": self.missing}


def missing_periods(dt: float, period_s: float) -> int:
    """Periods missing between two samples ``dt`` apart (0 unless ``dt > GAP_FACTOR·period``)."""
    if dt <= GAP_FACTOR * period_s:
        return 0
    return max(int(round(dt / period_s)) - 1, 1)


def nominal_period(t: np.ndarray, rate_hz: float | None = None) -> float | None:
    if rate_hz:
        return 1.0 / float(rate_hz)
    dt = np.diff(np.asarray(t, dtype=float))
    dt = dt[dt > 0]
    return float(np.median(dt)) if len(dt) else None


def find_gaps(t: np.ndarray, period_s: float | None) -> list[Gap]:
    t = np.asarray(t, dtype=float)
    if period_s is None or len(t) < 2:
        return []
    dt = np.diff(t)
    where = np.flatnonzero(dt > GAP_FACTOR * period_s)
    return [Gap(int(k + 1), float(t[k]), float(t[k + 1]), missing_periods(float(dt[k]), period_s))
            for k in where]


def recording_gaps(recording) -> list[Gap]:
    """The gaps of a loaded :class:`~urident.logs.Recording` (after any row selection)."""
    return find_gaps(recording.t, nominal_period(recording.t, recording.rate_hz))


def piece_bounds(recording) -> list[tuple[int, int]]:
    """``[first, last)`` sample indices of the recording's gap-free pieces, in order."""
    bounds = [0] + [g.index for g in recording_gaps(recording)] + [len(recording)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def split_at_gaps(recording) -> list:
    """The recording cut into its gap-free pieces (the recording itself when it has no gap), so
    that nothing is differentiated or filtered across a gap."""
    bounds = piece_bounds(recording)
    if len(bounds) == 1:
        return [recording]
    return [recording.select(slice(a, b)) for a, b in bounds]


def describe_gaps(gaps: list[Gap]) -> str:
    """``3 gaps, 105 periods missing (first after t = 2.514 s: 100 periods)``."""
    total = sum(g.missing for g in gaps)
    first = gaps[0]
    return (f"{len(gaps)} gap{'s' if len(gaps) != 1 else ''}, {total} period"
            f"{'s' if total != 1 else ''} missing (first after t = {first.t_before:.3f} s: "
            f"{first.missing} period{'s' if first.missing != 1 else ''})")
