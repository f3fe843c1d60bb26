"""The robot over RTDE: the one module of urident that imports ur_rtde.

:class:`RobotLink` wraps ur_rtde's receive, control and dashboard clients behind the few calls a
session needs, turns their failures into :class:`urident.errors.ConnectionLost`, and reads one
log sample per control cycle.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from urident.errors import ConnectionLost, ControllerUnreachable, SafetyError
from urident.session.dashboard import ensure_stopped
from urident.session.monitors import safety_problem

# ur_rtde clients whose connection broke: ur_rtde crashes (SIGSEGV) when such an object is sent
# commands, disconnected or destroyed while its reconnect thread runs, so they are kept here for
# the life of the process, which ends with os._exit (urident.session.supervisor's session
# process; urident.cli.main for a session run in the console script's own process).
_ABANDONED: list = []


def links_abandoned() -> bool:
    return bool(_ABANDONED)


# After a stop, the controller's program must report STOPPED for this long [s].
STOP_SETTLE_S = 0.3

# Output fields the session records (urident.logs.LOG_FIELDS), in ur_rtde's names.
RECEIVE_VARIABLES = [
    "timestamp", "actual_q", "actual_qd", "actual_current", "target_q", "target_qd", "target_qdd",
    "target_current", "target_moment", "joint_temperatures", "robot_mode", "safety_mode",
    "safety_status_bits", "runtime_state",
]


# The payload the controller was told (UR's RTDE guide: payload and payload_cog from 3.11 / 5.5,
# payload_inertia from 3.15 / 5.11); read once per run for the sidecar, not logged per sample.
PAYLOAD_FIELDS_SINCE = {"payload": {3: (3, 11), 5: (5, 5)}, "payload_cog": {3: (3, 11), 5: (5, 5)},
                        "payload_inertia": {3: (3, 15), 5: (5, 11)}}


def payload_field_names(version: tuple[int, ...]) -> list[str]:
    """The payload outputs a controller of ``version`` publishes (PolyScope X: all)."""
    if not version:
        return []
    return [name for name, since in PAYLOAD_FIELDS_SINCE.items()
            if version[0] >= 10 or (version[0] in since and tuple(version) >= since[version[0]])]


# The joint torque output: actual_current_as_torque, gravity-compensated (docs/signals.md), from
# PolyScope 5.23.0 / 10.11.0 (UR's ROS 2 driver, PR #1551, checks exactly these versions).
TORQUE_FIELD = "actual_current_as_torque"
TORQUE_FIELD_SINCE = {5: (5, 23), 10: (10, 11)}
# The gravity vector the controller uses (3 values, base frame), from 5.26.0 / 10.12.0
# (Universal_Robots_Client_Library PR #420).
GRAVITY_FIELD = "target_gravity"
GRAVITY_FIELD_SINCE = {5: (5, 26), 10: (10, 12)}


def _published(version: tuple[int, ...], since: dict[int, tuple[int, int]]) -> bool:
    """Whether a controller of ``version`` publishes a field first published at ``since``
    (per major version; majors above the last listed count as it)."""
    if not version:
        return False
    first = since.get(version[0])
    if first is None and version[0] > max(since):
        first = since[max(since)]
    return first is not None and tuple(version) >= first


def log_field_names(version: tuple[int, ...]) -> list[str]:
    """The log fields to record from a controller of ``version``: urident.logs.LOG_FIELDS, plus
    the joint torques and the gravity vector where that version publishes them."""
    from urident.logs import LOG_FIELDS

    names = [f.name for f in LOG_FIELDS]
    if _published(version, TORQUE_FIELD_SINCE):
        names.insert(names.index("actual_current") + 1, TORQUE_FIELD)
    if _published(version, GRAVITY_FIELD_SINCE):
        names.append(GRAVITY_FIELD)
    return names


@dataclass(frozen=True)
class ControllerInfo:
    version: tuple[int, ...]      # PolyScope / controller software version
    version_text: str
    rate_hz: float                # RTDE rate ur_rtde uses for this controller
    robot_model: str | None       # e.g. "UR5" (dashboard 'get robot model'), None if unsupported
    serial_number: str | None


def rate_for_version(major: int) -> float:
    """ur_rtde's rate rule: CB3 (major ≤ 3) 125 Hz, e-Series 500 Hz."""
    return 125.0 if major <= 3 else 500.0


def parse_polyscope_version(text: str) -> tuple[int, ...]:
    match = re.search(r"(\d+)\.(\d+)\.(\d+)(?:\.(\d+))?", text or "")
    if not match:
        raise SafetyError(f"cannot read the controller version from the dashboard reply {text!r}")
    return tuple(int(g) for g in match.groups() if g is not None)


class RobotLink:
    """Connections to one controller. Construct, then :meth:`connect_receive`, :meth:`info`,
    and only after every pre-motion check :meth:`connect_control` (which starts the control
    script on the robot). :meth:`close` always stops servoing and the script first."""

    def __init__(self, host: str):
        self.host = host
        self.receive = None
        self.control = None
        self.dashboard = None
        self._stopped = False
        self._lost = False
        self._payload_fields: list[str] = []

    # ------------------------------------------------------------------ connection
    def connect_receive(self) -> None:
        import dashboard_client
        import rtde_receive

        try:
            self.dashboard = dashboard_client.DashboardClient(self.host)
            self.dashboard.connect()
        except RuntimeError as exc:
            raise ControllerUnreachable(f"no controller at {self.host}: cannot reach its dashboard "
                                        f"server on port 29999 ({exc}); nothing moved") from None
        version = parse_polyscope_version(self._dashboard_call("polyscopeVersion"))
        self._payload_fields = payload_field_names(version)
        try:
            self.receive = rtde_receive.RTDEReceiveInterface(self.host, -1.0,
                                                             RECEIVE_VARIABLES + self._payload_fields)
        except RuntimeError as exc:
            raise ControllerUnreachable(f"no controller at {self.host}: cannot open RTDE on port "
                                        f"30004 ({exc}); nothing moved") from None

    def info(self) -> ControllerInfo:
        text = self._dashboard_call("polyscopeVersion")
        version = parse_polyscope_version(text)
        model = self._dashboard_call("getRobotModel", optional=True)
        serial = self._dashboard_call("getSerialNumber", optional=True)
        return ControllerInfo(version, text.strip(), rate_for_version(version[0]),
                              model.strip() if model else None, serial.strip() if serial else None)

    def in_remote_control(self) -> bool:
        return bool(self._dashboard_call("isInRemoteControl"))

    def connect_control(self, rate_hz: float) -> None:
        import rtde_control

        try:
            self.control = rtde_control.RTDEControlInterface(self.host, rate_hz)
        except RuntimeError as exc:
            # The script may have started before the failure: leave it stopped.
            notes = ensure_stopped(self.host, STOP_SETTLE_S)
            raise ControllerUnreachable(f"cannot start the control script on {self.host} ({exc}); "
                                        f"nothing moved" + "".join(f"; {n}" for n in notes)) from None

    def _dashboard_call(self, name: str, optional: bool = False):
        try:
            return getattr(self.dashboard, name)()
        except RuntimeError as exc:
            if optional:
                return None
            raise ConnectionLost(f"dashboard '{name}' failed on {self.host} ({exc})") from None

    # ------------------------------------------------------------------ state
    def state(self) -> dict[str, object]:
        """One sample of every recorded field (ur_rtde names), from the latest RTDE package."""
        r = self.receive
        if not r.isConnected():
            self._lost = True
            raise ConnectionLost(f"RTDE connection to {self.host} lost")
        return {
            "timestamp": r.getTimestamp(),
            "actual_q": r.getActualQ(),
            "actual_qd": r.getActualQd(),
            "actual_current": r.getActualCurrent(),
            "target_q": r.getTargetQ(),
            "target_qd": r.getTargetQd(),
            "target_qdd": r.getTargetQdd(),
            "target_current": r.getTargetCurrent(),
            "target_moment": r.getTargetMoment(),
            "joint_temperatures": r.getJointTemperatures(),
            "robot_mode": r.getRobotMode(),
            "safety_status_bits": r.getSafetyStatusBits(),
            "runtime_state": r.getRuntimeState(),
        }

    def declared_payload(self) -> dict[str, object] | None:
        """The payload the controller was told (``set_target_payload``, the installation), as
        :func:`urident.logs.sidecar.declared_payload` reads it, or None if it publishes none."""
        r = self.receive
        try:
            if "payload" not in self._payload_fields or r is None or not r.isConnected():
                return None
            return {"mass_kg": float(r.getPayload()), "cog_m": [float(v) for v in r.getPayloadCog()],
                    "inertia_kg_m2": ([float(v) for v in r.getPayloadInertia()]
                                      if "payload_inertia" in self._payload_fields else None)}
        except RuntimeError:  # a lost link: the log is still written, without it
            return None

    def monitor_state(self) -> tuple[float, list, int, int]:
        """(timestamp, actual_q, safety_status_bits, runtime_state): what the monitors need."""
        r = self.receive
        if not r.isConnected():
            self._lost = True
            raise ConnectionLost(f"RTDE connection to {self.host} lost")
        return r.getTimestamp(), r.getActualQ(), r.getSafetyStatusBits(), r.getRuntimeState()

    def stream_state(self) -> dict[str, object]:
        """The extra fields a live view needs."""
        r = self.receive
        return {"actual_qd": r.getActualQd(), "actual_current": r.getActualCurrent()}

    def actual_q(self) -> np.ndarray:
        return np.asarray(self.receive.getActualQ(), dtype=float)

    def actual_current(self) -> list:
        return self.receive.getActualCurrent()

    def modes(self) -> tuple[int, int, int]:
        """(robot_mode, safety_mode, safety_status_bits)."""
        r = self.receive
        return int(r.getRobotMode()), int(r.getSafetyMode()), int(r.getSafetyStatusBits())

    def controller_report(self) -> str:
        """What the controller reports at this moment, for a message saying why it refused a
        command: its program state (dashboard), runtime state, robot and safety mode and safety
        bits (RTDE), and ur_rtde's asynchronous operation progress. Each part that cannot be read
        says so; this never raises."""
        from urident.session.dashboard import Dashboard
        from urident.session.monitors import RUNTIME_STATE_NAMES, SAFETY_MODE_NAMES
        from urident.session.preflight import ROBOT_MODE_NAMES

        parts = []
        try:
            with Dashboard(self.host) as dashboard:
                parts.append(f"program {dashboard.call('programState')}")
        except (OSError, ConnectionError) as exc:
            parts.append(f"program state unreadable ({exc})")
        r = self.receive
        try:
            if r is None or not r.isConnected():
                parts.append("RTDE state unreadable (not connected)")
            else:
                runtime, robot_mode = int(r.getRuntimeState()), int(r.getRobotMode())
                safety_mode, bits = int(r.getSafetyMode()), int(r.getSafetyStatusBits())
                parts.append(f"runtime state {RUNTIME_STATE_NAMES.get(runtime, '?')} ({runtime})")
                parts.append(f"robot mode {ROBOT_MODE_NAMES.get(robot_mode, '?')} ({robot_mode})")
                parts.append(f"safety mode {SAFETY_MODE_NAMES.get(safety_mode, '?')} ({safety_mode})")
                parts.append(safety_problem(bits) or f"no safety stop bit set ({bits:#x})")
        except RuntimeError as exc:
            parts.append(f"RTDE state unreadable ({exc})")
        try:
            if self.control_connected():
                progress = self.move_progress()  # ur_rtde: < 0 when no asynchronous move runs
                parts.append(f"async operation progress {progress:g}" if progress >= 0
                             else f"no async operation running ({progress:g})")
            else:
                parts.append("control connection closed")
        except RuntimeError as exc:
            parts.append(f"async operation progress unreadable ({exc})")
        return "controller reported: " + ", ".join(parts)

    # ------------------------------------------------------------------ motion
    def move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> bool:
        """Start an asynchronous moveJ (the caller polls :meth:`move_progress`)."""
        return bool(self.control.moveJ(list(map(float, q)), speed, acceleration, True))

    def move_progress(self) -> float:
        """ur_rtde's async progress: < 0 when no asynchronous move is running."""
        return float(self.control.getAsyncOperationProgress())

    def stop_move(self, deceleration: float = 2.0) -> None:
        self.control.stopJ(deceleration)

    def init_period(self):
        return self.control.initPeriod()

    def wait_period(self, t_start) -> None:
        self.control.waitPeriod(t_start)

    def servo(self, q: np.ndarray, period_s: float, lookahead_time_s: float, gain: float) -> bool:
        return bool(self.control.servoJ(q.tolist(), 0.0, 0.0, period_s, lookahead_time_s, gain))

    def control_connected(self) -> bool:
        return self.control is not None and bool(self.control.isConnected())

    # ------------------------------------------------------------------ shutdown
    def stop(self) -> list[str]:
        """servoStop then stopScript, each attempted whatever happened before; returns what failed.

        ur_rtde must not be sent commands once its control connection is lost (it crashes the
        process later); the dashboard's ``stop`` (a separate connection) stops the program then.
        """
        if self._stopped or self.control is None:
            return []
        self._stopped = True
        problems = []
        # A lost receive link counts as lost control too: after a dropped connection ur_rtde's
        # control client may report "reconnected" and drop again a moment later, and a command
        # sent in between crashed the process (SIGSEGV, 2 of ~40 runs of the drop@ fault test).
        try:
            connected = not self._lost and bool(self.control.isConnected())
        except Exception:  # noqa: BLE001
            connected = False
        if connected:
            for name in ("servoStop", "stopScript"):
                try:
                    getattr(self.control, name)()
                except Exception as exc:  # noqa: BLE001 - shutdown must try every step
                    problems.append(f"{name}: {exc}")
        else:
            self._lost = True
            problems.append("control connection lost: servoStop/stopScript could not be sent")
        # The controller's word, not ours: its program must be stopped and stay stopped.
        # With broken clients, stop once and end the process soon (the recorder's watcher checks
        # after it ended): lingering beside ur_rtde's reconnect thread crashed the process.
        problems += ensure_stopped(self.host, STOP_SETTLE_S if connected else 0.0,
                                   stop_first=not connected)
        return problems

    def close(self) -> list[str]:
        problems = self.stop()
        if self._lost:
            # Never disconnect or destroy a broken ur_rtde client (see _ABANDONED).
            _ABANDONED.extend(c for c in (self.control, self.receive) if c is not None)
            self.control = self.receive = None
        for client in (self.control, self.receive):
            if client is not None:
                try:
                    client.disconnect()
                except Exception as exc:  # noqa: BLE001
                    problems.append(f"disconnect: {exc}")
        if self.dashboard is not None:
            try:
                self.dashboard.disconnect()
            except Exception as exc:  # noqa: BLE001
                problems.append(f"dashboard disconnect: {exc}")
        self.control = self.receive = self.dashboard = None
        return problems
