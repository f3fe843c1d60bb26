"""``urident run``: execute a checked trajectory over RTDE and record everything.

Order of a session: load and check the robot file, trajectory and configuration; read the
controller (version → rate, model, modes, pose); check the trajectory densely at that rate and the
approach to its start; ask the operator (unless ``--yes``); start the control script; moveJ to the
start; servoStop; the servoJ loop paced by ``initPeriod``/``waitPeriod`` with the monitors and the
log; rest at the final point; then — always, in a ``finally`` — servoStop and stopScript.

:func:`run_local` runs all of it in the calling process; ``urident run`` runs it in a child
process supervised by :mod:`urident.session.supervisor`, told what happens through
:class:`SessionEvents`.
"""

from __future__ import annotations

import io
import os
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

import numpy as np

from urident.errors import (ConfigError, ConnectionLost, ControllerUnreachable, Interrupted,
                            SafetyError, SessionAborted)
from urident.fileio import write_bytes_atomic
from urident.logs.sidecar import sha256_file
from urident.model import RobotSpec, load_robot
from urident.session.config import ExperimentConfig
from urident.session.monitors import RunMonitor, safety_problem
from urident.session.preflight import (ApproachPlan, check_controller, check_declared_payload,
                                       check_robot_state, plan_approach)
from urident.session.rtde_io import ControllerInfo, RobotLink, log_field_names


@dataclass(frozen=True)
class RunRequest:
    robot: str
    host: str
    trajectory: Path
    out: Path
    config: ExperimentConfig = field(default_factory=ExperimentConfig)
    repeat: int = 1
    check_only: bool = False
    assume_yes: bool = False
    record_periods: bool = False   # save every control period to LOG.periods.npy
    payload: object = None         # the load to check the torques with (urident.model.payload.Payload);
                                   # None: the one the trajectory file records, if any


@dataclass
class RunResult:
    status: str                   # "completed", "aborted" or "checked"
    log_path: Path | None = None
    n_samples: int = 0
    abort_reason: str | None = None
    late_cycles: int = 0
    info: ControllerInfo | None = None
    approach: ApproachPlan | None = None
    period_error_s: dict[str, float] = field(default_factory=dict)
    max_tracking_error_rad: float = 0.0

    def to_dict(self) -> dict:
        """The session's outcome as plain values (SI units; the controller and approach when known)."""
        info = self.info
        approach = self.approach
        return {"status": self.status, "log_path": None if self.log_path is None else str(self.log_path),
                "n_samples": int(self.n_samples), "abort_reason": self.abort_reason,
                "late_cycles": int(self.late_cycles), "max_tracking_error_rad": float(self.max_tracking_error_rad),
                "period_error_s": {k: float(v) for k, v in self.period_error_s.items()},
                "controller": None if info is None else {
                    "version": info.version_text, "rate_hz": info.rate_hz, "robot_model": info.robot_model,
                    "serial_number": info.serial_number},
                "approach": None if approach is None else {
                    "max_joint_distance_rad": float(approach.max_joint_distance_rad),
                    "joint": int(approach.joint) + 1,
                    "min_margin_m": None if approach.min_margin_m is None else float(approach.min_margin_m)}}

    def to_json(self, indent: int | None = 2) -> str:
        import json

        return json.dumps(self.to_dict(), indent=indent)


@dataclass(frozen=True)
class PlannedMotion:
    spec: RobotSpec
    trajectory_file: object
    t: np.ndarray        # (K,) command times [s]
    q_cmd: np.ndarray    # (K, 6) servo targets, trajectory repeated, then rest
    payload: object = None   # the load the torque check included (None: the empty flange)


def plan_motion(spec: RobotSpec, trajectory_path: Path, rate_hz: float, repeat: int,
                rest_s: float, payload=None) -> PlannedMotion:
    """Load the trajectory, check every constraint at ``rate_hz`` (the torques with ``payload``,
    else with the load the file records) and build the servo targets."""
    from urident.excitation import check_trajectory, load_trajectory, sample

    traj_file = load_trajectory(trajectory_path)
    if traj_file.robot != spec.name:
        raise ConfigError(f"{trajectory_path}: trajectory is for robot '{traj_file.robot}', "
                          f"not '{spec.name}'")
    spec = traj_file.checked_spec(spec)  # a trajectory designed for a tool keeps it in every check
    payload = traj_file.payload if payload is None else payload
    if payload is not None:
        spec.check_rated_payload(payload.mass_kg, "payload to check the trajectory with")
    report = check_trajectory(spec, traj_file.trajectory, rate_hz, traj_file.limits, payload=payload)
    report.raise_if_unsafe(f"{trajectory_path} (checked at {rate_hz:g} Hz)")
    if repeat < 1:
        raise ConfigError(f"--repeat must be at least 1, not {repeat}")
    _, q, _, _ = sample(traj_file.trajectory, rate_hz)
    period = 1.0 / rate_hz
    # One period of a rest-to-rest trajectory ends where the next begins: drop the duplicate.
    parts = [q] + [q[1:]] * (repeat - 1)
    n_rest = int(round(rest_s * rate_hz))
    parts.append(np.repeat(q[-1:], n_rest, axis=0))
    q_cmd = np.concatenate(parts)
    return PlannedMotion(spec, traj_file, np.arange(len(q_cmd)) * period, q_cmd, payload)


class Terminated(BaseException):
    """SIGTERM or SIGHUP reached the session; raised in the main thread like KeyboardInterrupt
    (a BaseException, so no ``except Exception`` on the way swallows it). ``what`` is the reason
    as the session reports it."""

    def __init__(self, signum: int, cause: str | None = None):
        super().__init__(signum)
        self.name = signal.Signals(signum).name
        self.what = cause or f"terminated by {self.name}"


class SessionEvents:
    """What a session tells a supervising process (:mod:`urident.session.supervisor`) as it
    goes; these defaults do nothing, for a session run in the calling process."""

    announce = True  # the recorder says it itself when the session process dies

    def ready(self) -> None:
        """The session's signal handlers are in place; no robot connection exists yet."""

    def control_starting(self) -> None:
        """Sent before the control script is started: from here on the program may run."""

    def log_started(self, path: Path) -> None:
        """The recorder writes the log at ``path``."""

    def motion(self) -> None:
        """The approach starts; :meth:`alive` is called every poll or control period from now."""

    def alive(self) -> None:
        """The session's main thread is still turning (once per period: keep it cheap)."""

    def stopping(self, reason: str | None) -> None:
        """The run ends (``reason`` None: completed); the robot is stopped next."""

    def signal_cause(self, signum: int) -> str | None:
        """The reason to report for ``signum`` instead of "terminated by SIG…", if any."""
        return None


class _SessionSignals:
    """Ctrl-C, SIGTERM and SIGHUP end a session the same way: an exception in the main thread
    that the session turns into a stop. While the robot is being stopped (:meth:`shielded`) a
    further signal is only noted, so it cannot cut servoStop/stopScript short."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self, cause: Callable[[int], str | None] = lambda _signum: None):
        self.stopping = False
        self.raised = False
        self.cause = cause
        self.previous: dict[int, object] = {}

    def _handle(self, signum, _frame) -> None:
        # One exception ends the session; a second signal (a terminal's Ctrl-C reaches the whole
        # process group, a supervisor forwards it too) must not cut its stop short.
        if self.stopping or self.raised:
            return
        self.raised = True
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(signum, self.cause(signum))

    def __enter__(self) -> "_SessionSignals":
        if threading.current_thread() is threading.main_thread():
            for signum in self.SIGNALS:
                self.previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)

    @contextmanager
    def shielded(self):
        stopping, self.stopping = self.stopping, True
        try:
            yield
        finally:
            self.stopping = stopping


def run_local(request: RunRequest, say: Callable[[str], None] = print,
              confirm: Callable[[str], bool] | None = None, live=None,
              link: RobotLink | None = None, events: SessionEvents | None = None) -> RunResult:
    """Run one session in this process; raise :class:`SafetyError` before any motion when a check
    fails and :class:`SessionAborted` (after the robot was stopped and the log closed) when a run
    stops early."""
    events = events or SessionEvents()
    config = request.config
    link = link or RobotLink(request.host)
    result = RunResult(status="checked")
    with _SessionSignals(events.signal_cause) as signals:
        events.ready()
        try:
            spec = load_robot(request.robot)
            return _check_and_run(request, spec, config, link, result, say, confirm, live, signals,
                                  events)
        except Terminated as exc:  # before the run started (a run turns it into SessionAborted)
            raise Interrupted(f"{exc.what} before any motion: nothing was moved") from None
        except ConnectionLost as exc:  # before any motion: no run started
            raise ControllerUnreachable(f"{exc}; nothing moved") from None
        finally:
            with signals.shielded():
                problems = link.close()
            for problem in problems:
                say(f"warning: while stopping: {problem}")


def _check_and_run(request: RunRequest, spec: RobotSpec, config: ExperimentConfig,
                   link: RobotLink, result: RunResult, say, confirm, live,
                   signals: _SessionSignals, events: SessionEvents) -> RunResult:
    link.connect_receive()
    info = link.info()
    result.info = info
    check_controller(spec, info.version, info.rate_hz, info.robot_model)
    robot_mode, safety_mode, safety_bits = link.modes()
    check_robot_state(robot_mode, safety_mode, safety_bits)
    if spec.generation == "e-series" and not link.in_remote_control():
        raise SafetyError(f"{request.host} is in local control: switch the teach pendant to "
                          f"remote control")
    motion = plan_motion(spec, request.trajectory, info.rate_hz, request.repeat, config.rest_s,
                         request.payload)
    declared = link.declared_payload()
    checked_kg = 0.0 if motion.payload is None else float(motion.payload.mass_kg)
    check_declared_payload(None if declared is None else declared["mass_kg"], checked_kg,
                           str(request.trajectory))
    approach = plan_approach(spec, link.actual_q(), motion.q_cmd[0],
                             config.approach.max_distance_rad,
                             _clearance_function(motion.spec, motion.trajectory_file.limits))
    result.approach = approach
    say(f"{spec.description} at {request.host}: controller {info.version_text}, "
        f"{info.rate_hz:g} Hz; trajectory {request.trajectory} passed every check at "
        f"{info.rate_hz:g} Hz ({len(motion.q_cmd)} servo periods, {motion.t[-1]:.1f} s)")
    say(f"payload: torques checked with {checked_kg:g} kg and without; the controller declares "
        + ("none (it publishes no payload before software 3.11 / 5.5)" if declared is None
           else f"{declared['mass_kg']:g} kg"))
    say(f"approach: {approach.max_joint_distance_rad:.3f} rad on joint {approach.joint + 1} at "
        f"{config.approach.speed_rad_s} rad/s"
        + (f", collision margin {approach.min_margin_m:.3f} m" if approach.min_margin_m is not None else ""))
    if request.check_only:
        return result
    if not request.assume_yes:
        question = (f"Move the robot at {request.host} to the trajectory start and run "
                    f"{motion.t[-1]:.1f} s of servoJ?")
        if confirm is None or not confirm(question):
            raise SafetyError("not confirmed: nothing was moved (pass --yes to skip the question)")
    events.control_starting()
    link.connect_control(info.rate_hz)
    return _execute(request, spec, info, motion, link, result, say, live, signals, events)


def _clearance_function(spec: RobotSpec, limits):
    """q (N, 6) → smallest (distance − required clearance) over the checked capsule pairs [m]."""
    from urident.excitation.collision import capsule_model

    capsules = capsule_model(spec, limits.clearance_m, limits.floor_height_m)
    return lambda q: capsules.margins(spec, q).min(axis=1)


APPROACH_TOLERANCE_RAD = 1e-3
APPROACH_POLL_S = 0.01


def _approach(link: RobotLink, q_start: np.ndarray, config: ExperimentConfig,
              plan: ApproachPlan | None, alive: Callable[[], None] = lambda: None) -> None:
    """moveJ to the start, asynchronously, so that Ctrl-C and the safety bits are seen at once:
    poll every 10 ms until the robot stands at the start; stop the move on any problem."""
    speed, acceleration = config.approach.speed_rad_s, config.approach.acceleration_rad_s2
    distance = plan.max_joint_distance_rad if plan is not None else np.pi
    # Trapezoidal profile time, then a generous margin for a slower controller.
    deadline = time.monotonic() + 3.0 * (distance / speed + speed / acceleration) + 5.0
    if not link.move_joints(q_start, speed, acceleration):
        raise SessionAborted(f"moveJ to the trajectory start was rejected by the controller "
                             f"({link.controller_report()}): nothing moved")
    try:
        while True:
            time.sleep(APPROACH_POLL_S)
            alive()
            _, q, safety_bits, runtime_state = link.monitor_state()
            problem = safety_problem(int(safety_bits))
            if problem:
                raise SessionAborted(f"during the approach: {problem}")
            if runtime_state != 2:
                raise SessionAborted(f"during the approach: control program stopped "
                                     f"(runtime_state={runtime_state})")
            at_start = np.max(np.abs(np.asarray(q) - q_start)) < APPROACH_TOLERANCE_RAD
            if at_start and link.move_progress() < 0:
                return
            if time.monotonic() > deadline:
                raise SessionAborted("the approach to the start did not finish in time")
    except BaseException:
        try:
            link.stop_move()
        except Exception:  # noqa: BLE001 - the finally of the session still stops the script
            pass
        raise


def _rejection_cause(link: RobotLink, period: float) -> str:
    """Why the controller refused a command: the control connection can see a stop a few
    packages before the receive connection does, so give the latter up to 20 periods."""
    for _ in range(20):
        _, _, safety_bits, runtime_state = link.monitor_state()
        problem = safety_problem(int(safety_bits))
        if problem:
            return problem
        if runtime_state != 2:
            return f"control program stopped, runtime_state={runtime_state}"
        time.sleep(period)
    return link.controller_report()


RT_PRIORITY = 20  # above the simulated controller's 10, below kernel threads


@contextmanager
def _realtime_scheduling():
    """Run the control loop thread with SCHED_FIFO when the OS allows it (root or CAP_SYS_NICE);
    yields a description for the log. The previous policy is restored afterwards."""
    if not hasattr(os, "sched_setscheduler"):
        yield "unchanged (not supported on this OS)"
        return
    previous = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(RT_PRIORITY))
    except OSError:
        yield "normal (no permission for real-time scheduling)"
        return
    try:
        yield f"SCHED_FIFO priority {RT_PRIORITY}"
    finally:
        os.sched_setscheduler(0, previous[0], previous[1])


def stop_outcome(problems: list[str]) -> str:
    """What the abort line says about the robot, from what stopping it reported."""
    unsure = [p for p in problems if "check the robot" in p]
    if unsure:
        return f"robot NOT confirmed stopped: {unsure[-1]}"
    if any("dashboard" in p for p in problems):
        return "robot stopped through the dashboard"
    return "robot stopped"


def _execute(request: RunRequest, spec: RobotSpec, info: ControllerInfo, motion: PlannedMotion,
             link: RobotLink, result: RunResult, say: Callable[[str], None], live,
             signals: _SessionSignals, events: SessionEvents) -> RunResult:
    from urident.session.recorder import RtdeRecorder

    config = request.config
    period = 1.0 / info.rate_hz
    metadata = {
        "robot": spec.name,
        "controller_version": info.version_text,
        "rate_hz": info.rate_hz,
        "trajectory_file": str(request.trajectory),
        "trajectory_sha256": sha256_file(request.trajectory),
        "gear_ratios": spec.gear_ratios.tolist(),
        "torque_constants": spec.torque_constants.tolist(),
        "start_time": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "host": request.host,
        "repeat": request.repeat,
        "servo": {"lookahead_time_s": config.servo.lookahead_time_s, "gain": config.servo.gain},
        "robot_model_reported": info.robot_model,
    }
    request.out.parent.mkdir(parents=True, exist_ok=True)
    recorder = RtdeRecorder(request.host, info.rate_hz, request.out, metadata,
                            fields=log_field_names(info.version), announce=events.announce)
    try:
        recorder.start()  # every controller sample from here on is in the log
    except BaseException as exc:
        with signals.shielded():
            recorder.stop("aborted", f"before any motion: {type(exc).__name__}: {exc}", {})
        raise
    events.log_started(request.out)
    monitor = RunMonitor(config.monitors, period)
    periods = np.full(len(motion.q_cmd), np.nan)
    abort_reason: str | None = None
    servo_timestamps: list[float] = []
    scheduling = _realtime_scheduling()
    scheduling_note = scheduling.__enter__()
    try:
        say(f"moving to the start at {config.approach.speed_rad_s} rad/s …")
        events.motion()
        _approach(link, motion.q_cmd[0], config, result.approach, events.alive)
        link.control.servoStop()
        say(f"running {len(motion.q_cmd)} servo periods at {info.rate_hz:g} Hz …")
        lookahead, gain = config.servo.lookahead_time_s, config.servo.gain
        work_s = None
        last_start = None
        alive = events.alive
        for k, q_cmd in enumerate(motion.q_cmd):
            t_start = link.init_period()
            now = time.perf_counter()
            alive()
            if last_start is not None:
                periods[k] = now - last_start
            last_start = now
            if not link.servo(q_cmd, period, lookahead, gain):
                abort_reason = (f"at t = {k * period:.3f} s: the controller rejected servoJ "
                                f"({_rejection_cause(link, period)})")
                break
            timestamp, q, safety_bits, runtime_state = link.monitor_state()
            if k == 0:
                servo_timestamps.append(timestamp)
            abort_reason = monitor.check(q_cmd, np.asarray(q), timestamp, safety_bits, runtime_state,
                                         work_s, link.actual_current)
            if live is not None:
                live.push({"timestamp": timestamp, "actual_q": q, **link.stream_state()}, q_cmd)
            if abort_reason:
                abort_reason = f"at t = {k * period:.3f} s: {abort_reason}"
                break
            work_s = time.perf_counter() - now
            link.wait_period(t_start)
        else:
            servo_timestamps.append(timestamp)
    except KeyboardInterrupt:
        abort_reason = "interrupted by the operator (Ctrl-C)"
    except Terminated as exc:
        abort_reason = exc.what
    except ConnectionLost as exc:
        abort_reason = str(exc)
    except RuntimeError as exc:  # ur_rtde raises RuntimeError when the link breaks
        abort_reason = f"connection lost: {exc}"
    except SessionAborted as exc:
        abort_reason = str(exc)
    except Exception as exc:  # noqa: BLE001 - a bug must still stop the robot and close the log
        abort_reason = f"internal error: {type(exc).__name__}: {exc}"
    finally:
        # Stop the robot first; the recorder then writes what the controller sent until the stop.
        signals.stopping = True
        events.stopping(abort_reason)
        recorder.note(abort_reason)  # in the log even if this process dies while stopping
        problems = link.stop()
        scheduling.__exit__(None, None, None)
        valid = periods[np.isfinite(periods)]
        errors = np.abs(valid - period) if len(valid) else np.zeros(1)
        result.period_error_s = {"p50": float(np.percentile(errors, 50)),
                                 "p99": float(np.percentile(errors, 99)), "max": float(errors.max())}
        status = "aborted" if abort_reason else "completed"
        over = int(np.sum(valid > period + config.monitors.late_tolerance_s))
        extra = {"period_error_s": result.period_error_s, "scheduling": scheduling_note,
                 "periods_over_tolerance": over,
                 "max_tracking_error_rad": monitor.max_tracking_error,
                 "servo_timestamps_s": servo_timestamps, "stop_problems": problems,
                 "late_cycles": monitor.late.late, "declared_payload": link.declared_payload(),
                 "checked_payload_kg": 0.0 if motion.payload is None else float(motion.payload.mass_kg)}
        stats = recorder.stop(status, abort_reason, extra)
        if live is not None:
            live.close(abort_reason)
        if request.record_periods:  # after the log is closed: a failure here cannot leave it open
            buffer = io.BytesIO()
            np.save(buffer, valid)
            # the CLI refused an existing or linked target before motion; never follow a link now
            write_bytes_atomic(request.out.with_suffix(".periods.npy"), buffer.getvalue(), overwrite=True)
    n_samples = stats.n_samples if stats else 0
    result.status = status
    result.log_path = request.out
    result.n_samples = n_samples
    result.abort_reason = abort_reason
    result.late_cycles = monitor.late.late
    result.max_tracking_error_rad = monitor.max_tracking_error
    if abort_reason:
        raise SessionAborted(f"run aborted {abort_reason}; {stop_outcome(problems)}; {n_samples} "
                             f"samples kept in {request.out}", reason=abort_reason, log_path=request.out,
                             n_samples=n_samples)
    missed = stats.missed_samples if stats else 0
    say(f"completed: {n_samples} samples in {request.out} ({missed} missed, {monitor.late.late} "
        f"late cycles, max tracking error {monitor.max_tracking_error:.4f} rad)")
    for problem in problems:
        say(f"warning: while stopping: {problem}")
    return result
