"""Gaps in a recording: controller samples that never reached the log.

One rule everywhere (the session recorder, the loaders, every consumer). A log's timestamps are a
uniform grid of nominal period T plus jitter (controller timestamps: none; a bag's header.stamp:
the ros2_control loop's wake-up latency, whose absolute schedule then catches up with cycles run
at once; DDS batching of receive times). Write r_k = (t_k − t_0)/T − k, the periods sample k runs
ahead of the grid: jitter moves r up and back, a lost sample steps it up by one for good. So an
interval longer than :data:`GAP_FACTOR`·T is only a candidate. The samples after it that follow
at less than :data:`CATCH_UP`·T are the catch-up; where they end the timing has settled. The
candidate is a gap of ``m`` missing periods when the level of r over :data:`LEVEL_WINDOW`
settled samples after it exceeds the level over those before it by ``m`` (rounded, ≥ 1, at most
what the stretch leaves room for; candidates in order, each gap's step removed from r after it).
A late sample followed by a short interval, a stall the loop catches up, a burst of bunched
receive times, is jitter, not a gap. A gap lies in its candidate interval when that interval
holds the missing periods and no catch-up follows; otherwise (a loss in a caught-up stall) the
samples from the candidate to where r steps are left out of the gap-free pieces (``Gap.resume``).
A window's level is its :data:`LEVEL_QUANTILE` quantile of r, since latency and batching delay
stamps and never advance them. With exact
timestamps this is the plain rule: missing = rounded spacing − 1 (:func:`missing_periods`, the
recorder's online count). The nominal period is the log's rate (sidecar) or, for a log without
one, the median spacing over :data:`SPAN` samples (robust to gaps and to bunched stamps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GAP_FACTOR = 1.5
#: samples each side whose level (see LEVEL_QUANTILE) judges a candidate
LEVEL_WINDOW = 25
#: the level of a window is this quantile of its r (jitter delays stamps far more than it advances them)
LEVEL_QUANTILE = 0.1
#: intervals shorter than this many periods right after a candidate are the loop catching up
CATCH_UP = 0.5
#: intervals per span of the nominal-period estimate
SPAN = 10


@dataclass(frozen=True)
class Gap:
    index: int          # the first sample after the gap
    t_before: float     # timestamp of the last sample before it [s]
    t_after: float      # timestamp of the sample the log resumes at [s]
    missing: int        # periods missing
    resume: int | None = None   # where the log resumes when the loss may lie anywhere in a
                                # stretch of jittered samples (index..resume-1, left out of pieces)

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
    short = dt < CATCH_UP * period_s
    events: list[list[int]] = []                 # [first interval, settled sample]
    for c in cand:
        settle = int(c) + 1
        while settle < dt.size and short[settle]:
            settle += 1
        if events and c < events[-1][1]:         # a candidate inside the previous catch-up
            events[-1][1] = max(settle, events[-1][1])
        else:
            events.append([int(c), settle])
    n = t.size
    raw = (t - t[0]) / period_s - np.arange(n)
    gaps: list[Gap] = []
    total = 0

    def level(a: int, b: int) -> np.ndarray:
        """r over samples a..b-1 with the steps of the gaps found so far removed."""
        seg = raw[a:b] - total
        for g in reversed(gaps):
            if g.index <= a:
                break
            seg[: g.index - a] += g.missing
        return seg

    for i, (first, settle) in enumerate(events):
        before = np.quantile(level(max(0, first + 1 - LEVEL_WINDOW), first + 1), LEVEL_QUANTILE)
        after = np.quantile(level(settle, min(n, settle + LEVEL_WINDOW)), LEVEL_QUANTILE)
        room = int(round((t[settle] - t[first]) / period_s)) - (settle - first)
        missing = min(int(round(after - before)), room)
        if missing < 1:
            continue
        if settle == first + 1 and round(dt[first] / period_s) - 1 >= missing:
            gaps.append(Gap(first + 1, float(t[first]), float(t[first + 1]), missing))
            total += missing
            continue
        # where r steps by ``missing`` (from its median level), between the neighbouring candidates
        lo = max(0, first + 1 - LEVEL_WINDOW, events[i - 1][1] if i else 0)
        hi = min(n, settle + LEVEL_WINDOW, events[i + 1][0] + 1 if i + 1 < len(events) else n)
        near = level(lo, hi)
        before = np.median(near[: first + 1 - lo])
        after = before + missing
        cost_b = np.concatenate(([0.0], np.cumsum(np.abs(near - before))))
        cost_a = np.concatenate((np.cumsum(np.abs(near - after)[::-1])[::-1], [0.0]))
        step = lo + int(np.argmin(cost_b + cost_a))
        start = max(min(first + 1, step), 1)
        resume = max(settle + 1 if settle > first + 1 else settle, step)
        resume = min(resume, n - 1)
        if start == first + 1 and resume == first + 1:
            gaps.append(Gap(first + 1, float(t[first]), float(t[first + 1]), missing))
        else:  # the loss lies somewhere in start..resume: jittered or caught-up samples
            gaps.append(Gap(start, float(t[start - 1]), float(t[resume]), missing, resume))
        total += missing
    return gaps


#: UR controller periods [s]: e-Series 500 Hz, CB3 125 Hz.
CONTROLLER_PERIODS = (0.002, 0.008)


def controller_period(t: np.ndarray) -> float | None:
    """The period of a UR controller's timestamps (exact multiples of it) however many samples a
    recorder skipped: the UR period nearest the 5th percentile of the positive intervals."""
    dt = np.diff(np.asarray(t, dtype=float))
    dt = dt[dt > 0]
    if dt.size == 0:
        return None
    short = float(np.quantile(dt, 0.05))
    return min(CONTROLLER_PERIODS, key=lambda p: abs(np.log(short / p)))


def single_misses(t: np.ndarray, period_s: float | None) -> np.ndarray:
    """Intervals k (t[k] → t[k+1]) that miss exactly one period (:func:`missing_periods`) and
    whose neighbouring intervals are on time (≤ GAP_FACTOR·T): the one controller sample that a
    recorder sampling the latest state on its own clock (ur_rtde's startFileRecording) skipped."""
    t = np.asarray(t, dtype=float)
    if period_s is None or t.size < 3:
        return np.zeros(0, dtype=int)
    dt = np.diff(t)
    one = (dt > GAP_FACTOR * period_s) & (np.round(dt / period_s) == 2)
    on_time = dt <= GAP_FACTOR * period_s
    neighbours = np.r_[False, on_time[:-1]] & np.r_[on_time[1:], False]
    return np.flatnonzero(one & neighbours)


def bridge_single_misses(arrays: dict[str, np.ndarray], period_s: float | None,
                         integer: frozenset[str] = frozenset()) -> tuple[dict[str, np.ndarray], int]:
    """``arrays`` (``t`` and per-sample arrays) with a sample inserted in every
    :func:`single_misses` interval: the mean of its two neighbours (linear interpolation at the
    midpoint, where the missing sample lies); arrays named in ``integer`` (codes, bits) repeat the
    sample before. Returns the new arrays and how many samples were inserted."""
    k = single_misses(arrays["t"], period_s)
    if k.size == 0:
        return arrays, 0
    out = {}
    for name, x in arrays.items():
        x = np.asarray(x)
        new = x[k] if name in integer else 0.5 * (x[k] + x[k + 1])
        out[name] = np.insert(x, k + 1, new.astype(x.dtype, copy=False), axis=0)
    return out, int(k.size)


def recording_gaps(recording) -> list[Gap]:
    """The gaps of a loaded :class:`~urident.logs.Recording` (after any row selection)."""
    return find_gaps(recording.t, nominal_period(recording.t, recording.rate_hz))


def piece_bounds(recording) -> list[tuple[int, int]]:
    """``[first, last)`` sample indices of the recording's gap-free pieces, in order."""
    gaps = recording_gaps(recording)
    starts = [0] + [g.index if g.resume is None else g.resume for g in gaps]
    ends = [g.index for g in gaps] + [len(recording)]
    return [(a, b) for a, b in zip(starts, ends) if b > a]


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
