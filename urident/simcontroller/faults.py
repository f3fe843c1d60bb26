"""Faults injected on demand: ``--fault SPEC`` (repeatable).

SPEC syntax::

    KIND@TIME[:DURATION]       KIND one of drop, protective_stop, emergency_stop, stale, latency
    no_remote

TIME is in seconds of controller time, counted from the first motion command the control script
receives (moveJ, servoJ, speedJ, ...), so a fault lands at the same point of an experiment however
long the client took to connect. Write ``start+TIME`` to count from controller start instead
(e.g. ``stale@start+1.5``). A fault whose reference never happens never fires.

* ``drop@T`` - close every connection (RTDE, dashboard, script ports) at T. The controller keeps
  running and accepts new connections; the script keeps running.
* ``protective_stop@T`` - protective stop: safety_status_bits bit 2 (and bit 10 "stopped due to
  safety"), safety_mode 3; motion stops at maximum deceleration, the script stops (runtime_state 1).
  Dashboard ``unlock protective stop`` clears it.
* ``emergency_stop@T`` - emergency stop: safety_status_bits bits 6 and 7 (and 10), safety_mode 7,
  robot_mode 3 (power off); motion and script stop. Dashboard ``restart safety`` clears it.
* ``stale@T[:D]`` - from T on (for D seconds; default: for ever) data packages keep coming but
  their ``timestamp`` stays frozen.
* ``latency@T[:D]`` - a pause of D seconds (default 0.2) in sending data packages; packages due in
  the pause are not sent (the physics keeps running).
* ``no_remote`` - the dashboard answers ``false`` to ``is in remote control``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from urident.errors import ConfigError

TIMED_KINDS = ("drop", "protective_stop", "emergency_stop", "stale", "latency")
FLAG_KINDS = ("no_remote",)
DEFAULT_DURATION_S = {"latency": 0.2, "stale": float("inf")}

_SPEC = re.compile(r"^(?P<kind>[a-z_]+)@(?P<start>start\+)?(?P<at>[0-9.eE+-]+)(:(?P<duration>[0-9.eE+-]+))?$")


@dataclass(frozen=True)
class Fault:
    kind: str
    at_s: float = 0.0
    duration_s: float = 0.0
    from_start: bool = False      # True: TIME counts from controller start, else from first motion

    @property
    def spec(self) -> str:
        if self.kind in FLAG_KINDS:
            return self.kind
        ref = "start+" if self.from_start else ""
        finite = self.duration_s != float("inf")
        dur = f":{self.duration_s:g}" if self.kind in DEFAULT_DURATION_S and finite else ""
        return f"{self.kind}@{ref}{self.at_s:g}{dur}"


def parse_fault(text: str) -> Fault:
    """Parse one ``--fault`` SPEC; raises :class:`ConfigError` with a one-line message."""
    spec = text.strip()
    if spec in FLAG_KINDS:
        return Fault(kind=spec)
    match = _SPEC.match(spec)
    kinds = ", ".join(TIMED_KINDS + FLAG_KINDS)
    if not match:
        raise ConfigError(f"--fault '{text}': expected KIND@SECONDS[:DURATION] or no_remote (kinds: {kinds})")
    kind = match["kind"]
    if kind not in TIMED_KINDS:
        raise ConfigError(f"--fault '{text}': unknown fault kind '{kind}' (kinds: {kinds})")
    try:
        at_s = float(match["at"])
        duration = match["duration"]
        duration_s = float(duration) if duration is not None else DEFAULT_DURATION_S.get(kind, 0.0)
    except ValueError:
        raise ConfigError(f"--fault '{text}': time and duration must be numbers of seconds") from None
    if at_s < 0 or duration_s < 0:
        raise ConfigError(f"--fault '{text}': time and duration must not be negative")
    if duration is not None and kind not in DEFAULT_DURATION_S:
        raise ConfigError(f"--fault '{text}': '{kind}' takes no duration")
    return Fault(kind=kind, at_s=at_s, duration_s=duration_s, from_start=bool(match["start"]))


class FaultSchedule:
    """Decides, tick by tick, which faults fire and which windows are active."""

    def __init__(self, faults: list[Fault]):
        self.faults = list(faults)
        self.no_remote = any(f.kind == "no_remote" for f in self.faults)
        self._timed = [f for f in self.faults if f.kind in TIMED_KINDS]
        self._fired: set[int] = set()

    def _begin(self, fault: Fault, controller_time_s: float, motion_start_s: float | None) -> float | None:
        if fault.from_start:
            return fault.at_s
        return None if motion_start_s is None else motion_start_s + fault.at_s

    def due(self, controller_time_s: float, motion_start_s: float | None) -> list[Fault]:
        """Faults whose time has come since the last call (each fires once)."""
        fired = []
        for k, fault in enumerate(self._timed):
            if k in self._fired:
                continue
            begin = self._begin(fault, controller_time_s, motion_start_s)
            if begin is not None and controller_time_s >= begin:
                self._fired.add(k)
                fired.append(fault)
        return fired

    def _active(self, kind: str, controller_time_s: float, motion_start_s: float | None) -> bool:
        for fault in self._timed:
            if fault.kind != kind:
                continue
            begin = self._begin(fault, controller_time_s, motion_start_s)
            if begin is not None and begin <= controller_time_s < begin + fault.duration_s:
                return True
        return False

    def timestamp_frozen(self, controller_time_s: float, motion_start_s: float | None) -> bool:
        return self._active("stale", controller_time_s, motion_start_s)

    def sending_paused(self, controller_time_s: float, motion_start_s: float | None) -> bool:
        return self._active("latency", controller_time_s, motion_start_s)
