"""Gaps in a recording: controller samples that never reached the log.

One rule everywhere (the session recorder, the loaders, every consumer). A log's timestamps are a
uniform grid of nominal period T plus jitter (controller timestamps: none; a bag's header.stamp:
the ros2_control loop's wake-up latency, which its absolute schedule catches up; DDS batching of
receive times). Write r_k = (t_k − t_0)/T − k, the periods sample k runs ahead of the grid: jitter
moves r up and back, a lost sample steps it up by one for good. So an interval longer than
:data:`GAP_FACTOR`·T is only a candidate; it is a gap of ``m`` missing periods when the median of
r over the samples after it exceeds the median over the samples before it by ``m`` (rounded,
≥ 1, at most what the interval leaves room for). A late sample followed by short intervals, or a
stall the loop catches up, is jitter, not a gap. Candidates closer than :data:`MIN_PIECE` samples
are judged together, as one gap at their longest interval. With exact timestamps this is the
plain rule: missing = rounded spacing − 1 (:func:`missing_periods`, the recorder's online count).
The nominal period is the log's rate (sidecar) or, for a log without one, the median spacing
over :data:`SPAN` samples (robust to gaps and to bursts of bunched stamps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GAP_FACTOR = 1.5
#: samples each side (plus twice the candidate's length in periods) whose median level judges it
LEVEL_WINDOW = 25
#: candidates with fewer samples than this between them are one gap (a loss split by jitter)
MIN_PIECE = 3
#: intervals per span of the nominal-period estimate
SPAN = 10


@dataclass(frozen=True)
class Gap:
    index: int          # the first sample after the gap
    t_before: float     # timestamp of the last sample before it [s]
    t_after: float      # timestamp of the first sample after it [s]
    missing: int        # periods missing

    def as_dict(self) -> dict:
        return {"after_s": self.t_before, "resume_s": self.t_after, "missing_periods": self.missing}


def missing_periods(dt: float, period_s: float) -> int:
    """Periods missing between two exactly timed samples ``dt`` apart (0 unless
    ``dt > GAP_FACTOR·period``): the recorder's online count on controller timestamps."""
    if dt <= GAP_FACTOR * period_s:
        return 0
    return max(int(round(dt / period_s)) - 1, 1)


def nominal_period(t: np.ndarray, rate_hz: float | None = None) -> float | None:
    """1 / ``rate_hz``, else the median over k of (t[k+s] − t[k]) / s, s = min(SPAN, N−1) [s]."""
    if rate_hz:
        return 1.0 / float(rate_hz)
    t = np.asarray(t, dtype=float)
    s = min(SPAN, t.size - 1)
    if s < 1:
        return None
    span = (t[s:] - t[:-s]) / s
    span = span[span > 0]
    return float(np.median(span)) if span.size else None


def find_gaps(t: np.ndarray, period_s: float | None) -> list[Gap]:
    """The gaps of timestamps ``t`` at nominal period ``period_s`` (module doc)."""
    t = np.asarray(t, dtype=float)
    if period_s is None or len(t) < 2:
        return []
    dt = np.diff(t)
    cand = np.flatnonzero(dt > GAP_FACTOR * period_s)
    if cand.size == 0:
        return []
    # clusters of candidates: intervals [first, last] with fewer than MIN_PIECE samples between
    split = np.flatnonzero(np.diff(cand) >= MIN_PIECE) + 1
    clusters = [(int(c[0]), int(c[-1])) for c in np.split(cand, split)]
    level = (t - t[0]) / period_s - np.arange(t.size)
    gaps = []
    for i, (first, last) in enumerate(clusters):
        a, b = first, last + 1                       # samples just before / just after
        w = LEVEL_WINDOW + 2 * int(np.ceil((t[b] - t[a]) / period_s))
        lo = clusters[i - 1][1] + 1 if i else 0
        hi = clusters[i + 1][0] + 1 if i + 1 < len(clusters) else t.size
        before = np.median(level[max(lo, a + 1 - w): a + 1])
        after = np.median(level[b: min(hi, b + w)])
        room = int(round((t[b] - t[a]) / period_s)) - (b - a)
        missing = min(int(round(after - before)), room)
        if missing >= 1:
            k = first + int(np.argmax(dt[first: last + 1]))
            gaps.append(Gap(k + 1, float(t[k]), float(t[k + 1]), missing))
    return gaps


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
