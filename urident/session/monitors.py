"""Run monitors: pure checks of each controller sample that decide whether a run must stop.

A :class:`RunMonitor` sees one sample per control cycle and returns ``None`` or the one-line
reason to abort. It does no I/O, so it is tested without a robot and costs a few µs per cycle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.session.config import MonitorConfig

# safety_status_bits (UR RTDE guide)
PROTECTIVE_STOP_BIT = 2
SAFEGUARD_STOP_BIT = 4
SYSTEM_EMERGENCY_STOP_BIT = 5
ROBOT_EMERGENCY_STOP_BIT = 6
EMERGENCY_STOP_BIT = 7
VIOLATION_BIT = 8
FAULT_BIT = 9
STOPPED_DUE_TO_SAFETY_BIT = 10

_SAFETY_REASONS = (
    (EMERGENCY_STOP_BIT, "emergency stop"),
    (SYSTEM_EMERGENCY_STOP_BIT, "system emergency stop"),
    (ROBOT_EMERGENCY_STOP_BIT, "robot emergency stop"),
    (PROTECTIVE_STOP_BIT, "protective stop"),
    (SAFEGUARD_STOP_BIT, "safeguard stop"),
    (VIOLATION_BIT, "safety violation"),
    (FAULT_BIT, "safety fault"),
    (STOPPED_DUE_TO_SAFETY_BIT, "stopped due to safety"),
)

RUNTIME_PLAYING = 2
ROBOT_MODE_RUNNING = 7

# runtime_state and safety_mode values (UR RTDE guide), for messages
RUNTIME_STATE_NAMES = {0: "stopping", 1: "stopped", 2: "playing", 3: "pausing", 4: "paused",
                       5: "resuming"}
SAFETY_MODE_NAMES = {1: "normal", 2: "reduced", 3: "protective stop", 4: "recovery",
                     5: "safeguard stop", 6: "system emergency stop", 7: "robot emergency stop",
                     8: "violation", 9: "fault", 10: "validate joint id", 11: "undefined",
                     12: "automatic mode safeguard stop", 13: "three-position enabling stop"}


def safety_problem(safety_status_bits: int) -> str | None:
    """The first abnormal condition in ``safety_status_bits``, or None."""
    for bit, reason in _SAFETY_REASONS:
        if safety_status_bits >> bit & 1:
            return f"{reason} (safety_status_bits=0x{safety_status_bits:x})"
    return None


@dataclass
class LateCycleCounter:
    """Counts control cycles whose work overran the period."""

    period_s: float
    tolerance_s: float
    late: int = 0
    consecutive: int = 0
    cycles: int = 0

    def record(self, work_s: float) -> bool:
        self.cycles += 1
        if work_s > self.period_s + self.tolerance_s:
            self.late += 1
            self.consecutive += 1
            return True
        self.consecutive = 0
        return False


class RunMonitor:
    """All per-cycle checks of a servo run."""

    def __init__(self, config: MonitorConfig, period_s: float):
        self.config = config
        self.period_s = period_s
        self.late = LateCycleCounter(period_s, config.late_tolerance_s)
        self._last_timestamp: float | None = None
        self._stale = 0
        self._frozen = False
        self._repeat_key: np.ndarray | None = None
        self.max_tracking_error = 0.0
        self.max_stale = 0

    def check(self, q_cmd: np.ndarray, q: np.ndarray, timestamp: float, safety_bits: int,
              runtime_state: int, work_s: float | None = None,
              current=None) -> str | None:
        """The reason to abort after this sample, or None. ``work_s`` is the previous cycle's
        work time (None before the first); ``current`` (the measured currents, noisy in every
        real package, or a function returning them, called only when the timestamp repeats)
        tells a frozen controller clock from a package that did not come."""
        problem = safety_problem(int(safety_bits))
        if problem:
            return problem
        if runtime_state != RUNTIME_PLAYING:
            return f"controller program stopped (runtime_state={runtime_state})"
        if not np.all(np.isfinite(q)):
            return "controller sent non-finite joint positions"
        error = np.abs(q_cmd - q)
        joint = int(np.argmax(error))
        self.max_tracking_error = max(self.max_tracking_error, float(error[joint]))
        if error[joint] > self.config.max_tracking_error_rad:
            return (f"tracking error {error[joint]:.3f} rad on joint {joint + 1} exceeds "
                    f"{self.config.max_tracking_error_rad} rad")
        if self._last_timestamp is not None and timestamp == self._last_timestamp:
            # The same timestamp with the same values is the same package: no new sample came
            # (late or lost); other values under the same timestamp mean the clock is frozen.
            if callable(current):
                current = current()
            key = np.array(q if current is None else current, dtype=float)
            if self._repeat_key is not None and not np.array_equal(key, self._repeat_key):
                self._frozen = True
            self._repeat_key = key
            self._stale += 1
            self.max_stale = max(self.max_stale, self._stale)
            if self._stale >= self.config.max_stale_periods:
                if self._frozen:
                    return (f"stale data: controller timestamp frozen at {timestamp:.3f} s for "
                            f"{self._stale} cycles")
                return (f"controller samples late: no sample for "
                        f"{self._stale * self.period_s:.2f} s")
        else:
            self._stale = 0
            self._frozen = False
            self._repeat_key = None
        self._last_timestamp = timestamp
        if work_s is not None:
            self.late.record(work_s)
            if self.late.consecutive >= self.config.max_consecutive_late:
                return f"{self.late.consecutive} late control cycles in a row"
            warmed_up = self.late.cycles * self.period_s >= 1.0
            if warmed_up and self.late.late > self.config.max_late_fraction * self.late.cycles:
                return (f"{self.late.late} of {self.late.cycles} control cycles late "
                        f"(budget {self.config.max_late_fraction:.0%})")
        return None
