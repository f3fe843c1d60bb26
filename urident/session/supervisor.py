"""``urident run`` as two processes: ur_rtde's clients live only in a child, the caller supervises.

ur_rtde's threads can crash the process that holds its clients (SIGSEGV after a lost link, while
its reconnect thread runs), abort it, or hang in a call. So :func:`run_session` runs the session
(:func:`urident.session.runner.run_local`) in a child process started with ``spawn`` (a fresh
interpreter: the caller's threads are never forked, and the clients are created in the child
only) and in a process group of its own (a terminal's Ctrl-C reaches the caller, which forwards
it once). Whatever becomes of the child, the caller makes sure the controller's program is
stopped (:func:`urident.session.dashboard.ensure_stopped`: the controller's word), says why in
one line, and raises :class:`SessionAborted` once a run had started.

What crosses the process boundary: the request (pickled); from the child, its output lines, the
confirmation question (the caller asks the operator on its own terminal and sends the answer
back), stage messages (the control script may start, the log path, the stop reason), a
heartbeat during motion, the live view's samples (fixed-size records written without blocking
to a pipe of their own: the control loop never waits for the caller, and no thread of ours runs
beside ur_rtde's, which made its crashes after a lost link more frequent) and finally the result
or the error; to the child, the answer and a stop request when the caller's live view fails. The log's recorder is the
child's own child and keeps its guarantees (:mod:`urident.session.recorder`).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import queue
import signal
import struct
import sys
import threading
import time
import traceback
from multiprocessing.connection import wait as wait_for
from pathlib import Path
from typing import Callable

from urident.errors import (Interrupted, SafetyError, SessionAborted, UridentError)
from urident.session.dashboard import ensure_stopped
from urident.session.handover import controller_turn
from urident.session.recorder import process_death, signal_name
from urident.session.runner import RunRequest, RunResult, SessionEvents, run_local

PROCESS_NAME = "urident-session"  # the child's name in ps/top (/proc/PID/comm)
SILENCE_S = 5.0          # during motion, the child's main thread must turn at least this often
STOP_GRACE_S = 45.0      # after a stop began (or a signal was forwarded), the child must end
EXIT_GRACE_S = 10.0      # after its result, the child must exit
LOG_CLOSE_WAIT_S = 30.0  # after the child died, wait this long for the recorder to close the log
SETTLE_S = 0.3           # the program must report STOPPED this long after a completed run …
SETTLE_ABORTED_S = 1.0   # … and after any other end (ur_rtde may have re-uploaded its script)
BEAT_INTERVAL_S = 0.2
LIVE_RECORD = struct.Struct("<25d")  # t, q, qd, current, q_cmd: one live sample (200 bytes)
NATIVE_CRASH = (signal.SIGSEGV, signal.SIGABRT, signal.SIGBUS, signal.SIGILL, signal.SIGFPE)


def run_session(request: RunRequest, say: Callable[[str], None] | None = None,
                confirm: Callable[[str], bool] | None = None, live=None,
                link=None) -> RunResult:
    """Run one session with ur_rtde in a supervised child process (see the module docstring).

    Raises as :func:`run_local` does: :class:`SafetyError` before any motion, :class:`SessionAborted`
    once a run started and ended early. ``live`` stays in this process. With ``link`` (a
    :class:`urident.session.rtde_io.RobotLink` or a stand-in) the session runs here instead."""
    say = say or _print
    with controller_turn(request.host, say):  # after the previous run's watch, never inside it
        if link is not None:
            return run_local(request, say, confirm, live, link)
        return _Supervisor(request, say, confirm, live).run()


def _print(line: str) -> None:
    print(line, flush=True)


# --------------------------------------------------------------------------- caller side
class _Supervisor:
    def __init__(self, request: RunRequest, say, confirm, live):
        self.request = request
        self.say = say
        self.confirm = confirm
        self.live = live
        self.ready = False            # the child's signal handlers are in place
        self.script_may_run = False   # the child started (or is starting) the control script
        self.moving = False
        self.log_path: Path | None = None
        self.stop_reason: str | None = None
        self.stopping = False
        self.verdict: tuple | None = None
        self.verdict_at: float | None = None
        self.last_beat = 0.0
        self.stop_deadline: float | None = None
        self.kill_reason: str | None = None
        self.signals: list[int] = []
        self.signal_before_ready: int | None = None
        self.prompting = False
        self.live_failed = False
        self.reaping = False          # from here on the child's pid may be reaped: never signal it

    # ------------------------------------------------------------------ run
    def run(self) -> RunResult:
        ctx = mp.get_context("spawn")  # a fresh interpreter: never fork this process's threads
        self.events, events_w = ctx.Pipe(duplex=False)
        control_r, self.control = ctx.Pipe(duplex=False)
        live_r = live_w = None
        if self.live is not None:
            live_r, live_w = ctx.Pipe(duplex=False)
        self.process = ctx.Process(target=_child_main, name=PROCESS_NAME, daemon=False,
                                   args=(self.request, events_w, control_r, live_w))
        # Until the child has its own process group and handlers, a terminal's Ctrl-C must not
        # raise KeyboardInterrupt there (a traceback): it starts with SIGINT ignored.
        previous = _set_handler(signal.SIGINT, signal.SIG_IGN)
        try:
            self.process.start()
        finally:
            if previous is not None:
                _set_handler(signal.SIGINT, previous)
        for end in (events_w, control_r, live_w):
            if end is not None:
                end.close()
        self.live_conn = live_r
        self.live_buffer = b""
        # Signals are forwarded (or, once the child ended, only noted) until the end: a second
        # Ctrl-C must not cut the final check of the program state short.
        with _ParentSignals(self._on_signal):
            try:
                self._supervise()
            except BaseException:
                # A failure here must still end the run: stop the child, then the program.
                self._end_child_after_failure()
                raise
            return self._conclude()

    def _supervise(self) -> None:
        sources = [self.events, self.process.sentinel]
        if self.live_conn is not None:
            sources.append(self.live_conn)
        ended_at = None
        while self.events in sources or self.process.sentinel in sources:
            ready = wait_for(sources, timeout=0.25)
            for source in ready:
                if source is self.process.sentinel:
                    sources.remove(source)
                    ended_at = time.monotonic()
                    continue
                if source is self.live_conn:
                    if not self._read_live():
                        sources.remove(source)
                    continue
                for _ in range(500):  # drain, but come back to the watchdog now and then
                    try:
                        message = source.recv()
                    except (EOFError, OSError):
                        sources.remove(source)
                        break
                    self._handle(message)
                    if not source.poll():
                        break
            if ended_at is not None and time.monotonic() - ended_at > 5.0:
                break  # the child is gone; nothing else should hold its pipes
            if ended_at is None:
                self._watchdog(time.monotonic())

    def _handle(self, message: tuple) -> None:
        kind = message[0]
        if kind == "beat":
            self.last_beat = time.monotonic()
        elif kind == "say":
            self.say(message[1])
        elif kind == "ready":
            self.ready = True
        elif kind == "confirm":
            answer = self._ask(message[1])
            try:
                self.control.send(("answer", answer))
            except OSError:  # the child is gone; its end is handled below
                pass
        elif kind == "control":
            self.script_may_run = True
        elif kind == "log":
            self.log_path = Path(message[1])
        elif kind == "motion":
            self.moving = True
            self.last_beat = time.monotonic()
        elif kind == "stopping":
            self.stop_reason = message[1]
            self.stopping = True
            self._stop_within(STOP_GRACE_S)
        elif kind in ("result", "raise"):
            self.verdict = message
            self.verdict_at = time.monotonic()

    def _ask(self, question: str) -> bool:
        if self.confirm is None or self.signals:
            return False
        self.prompting = True
        try:
            return bool(self.confirm(question))
        except (KeyboardInterrupt, _PromptInterrupted, EOFError):
            return False  # the child got the signal too and ends with it
        finally:
            self.prompting = False

    def _read_live(self) -> bool:
        """Push the live samples that arrived; False once the child's end closed."""
        try:
            data = os.read(self.live_conn.fileno(), 65536)
        except OSError:
            return False
        if not data:
            return False
        self.live_buffer += data
        n = len(self.live_buffer) // LIVE_RECORD.size
        for k in range(n):
            self._push_live(LIVE_RECORD.unpack_from(self.live_buffer, k * LIVE_RECORD.size))
        self.live_buffer = self.live_buffer[n * LIVE_RECORD.size:]
        return True

    def _push_live(self, record: tuple) -> None:
        if self.live_failed:
            return
        t, q, qd, current, q_cmd = (record[0], list(record[1:7]), list(record[7:13]),
                                    list(record[13:19]), list(record[19:25]))
        try:
            self.live.push({"timestamp": t, "actual_q": q, "actual_qd": qd,
                            "actual_current": current}, q_cmd)
        except Exception as exc:  # noqa: BLE001 - an exception anywhere ends the run
            self.live_failed = True
            try:
                self.control.send(("abort", f"the live view failed (internal error: "
                                            f"{type(exc).__name__}: {exc})"))
            except OSError:
                pass

    # ------------------------------------------------------------------ signals and watchdog
    def _on_signal(self, signum: int) -> None:
        self.signals.append(signum)
        if self.reaping:
            return
        if not self.ready:
            # Nothing was connected yet: end the child outright.
            self.signal_before_ready = self.signal_before_ready or signum
            self._kill(None)
        else:
            try:
                os.kill(self.process.pid, signum)  # not reaped before the loop ends: no reuse
            except ProcessLookupError:
                pass
            self._stop_within(STOP_GRACE_S)
        if self.prompting:
            raise KeyboardInterrupt if signum == signal.SIGINT else _PromptInterrupted()

    def _stop_within(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        self.stop_deadline = deadline if self.stop_deadline is None else min(self.stop_deadline,
                                                                             deadline)

    def _watchdog(self, now: float) -> None:
        if self.kill_reason is not None:
            return
        if self.verdict is not None:
            if now - self.verdict_at > EXIT_GRACE_S:
                self._kill(f"the session process did not exit within {EXIT_GRACE_S:g} s of "
                           f"its result")
            return
        if self.moving and not self.stopping and now - self.last_beat > SILENCE_S:
            self._kill(f"the session process stopped responding for {SILENCE_S:g} s during "
                       f"the motion (ur_rtde hung?): killed it")
        elif self.stop_deadline is not None and now > self.stop_deadline:
            self._kill(f"the session process did not end within {STOP_GRACE_S:g} s of the "
                       f"stop: killed it")

    def _kill(self, reason: str | None) -> None:
        if reason is not None and self.kill_reason is None:
            self.kill_reason = reason
        if self.reaping:
            return
        try:
            os.kill(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    def _end_child_after_failure(self) -> None:
        self.reaping = True
        if self.process.is_alive():
            if self.ready:
                os.kill(self.process.pid, signal.SIGTERM)
                self.process.join(STOP_GRACE_S)
            if self.process.is_alive():
                os.kill(self.process.pid, signal.SIGKILL)
        self.process.join(5)
        if self.script_may_run:
            ensure_stopped(self.request.host, SETTLE_ABORTED_S, stop_first=True)

    # ------------------------------------------------------------------ the end
    def _conclude(self) -> RunResult:
        self.reaping = True
        self.process.join(10)
        code = self.process.exitcode
        death = self._death(code)
        completed = (self.verdict is not None and self.verdict[0] == "result"
                     and self.verdict[1].status != "aborted")
        notes: list[str] = []
        if self.script_may_run:
            # The controller's word, now that no ur_rtde client of this run exists any more.
            notes = ensure_stopped(self.request.host, SETTLE_S if completed else SETTLE_ABORTED_S,
                                   stop_first=self.verdict is None)
        if self.verdict is None:
            error = self._no_verdict_error(death, notes)
            self._close_live(str(error) or "interrupted")
            raise error
        extra = ([f"then {death}"] if death and self.kill_reason is None else []) + [
            f"after the session process ended: {n}" for n in notes]
        kind = self.verdict[0]
        if kind == "result":
            self._close_live(None)
            for line in extra:
                self.say(f"warning: {line}")
            return self.verdict[1]
        error = _rebuild(self.verdict)
        self._close_live(self.stop_reason if self.stop_reason else str(error))
        if extra and isinstance(error, UridentError):
            error.args = ("; ".join([str(error), *extra]),)
        raise error

    def _death(self, code: int | None) -> str | None:
        """What became of the child, when it did not simply exit 0."""
        if self.kill_reason is not None:
            return self.kill_reason
        if code is None:
            return "the session process did not end"
        if code < 0:
            signum = -code
            if signum in NATIVE_CRASH:
                return f"ur_rtde crashed (signal {signum}, {signal_name(signum)})"
            return f"the session process was killed (signal {signum}, {signal_name(signum)})"
        if code > 0:
            return f"the session process exited with code {code}"
        return None

    def _no_verdict_error(self, death: str | None, notes: list[str]) -> BaseException:
        death = death or "the session process ended without a result"
        if not self.script_may_run:
            if self.signal_before_ready is not None:
                if self.signal_before_ready == signal.SIGINT:
                    return KeyboardInterrupt()
                return Interrupted(f"terminated by {signal_name(self.signal_before_ready)} before "
                                   f"any motion: nothing was moved")
            return SafetyError(f"{death} before the control script started: nothing moved")
        unsure = [n for n in notes if "check the robot" in n]
        outcome = (f"robot NOT confirmed stopped: {unsure[-1]}" if unsure
                   else "program stopped (checked on the controller)")
        kept, sidecar = self._log_kept()
        reason = self.stop_reason
        recorder = (sidecar.get("extra") or {}).get("recorder") or {}
        if reason is None and recorder.get("controller_closed_connection"):
            reason = "after the controller closed the RTDE connection (link lost)"
        head = f"run aborted {reason}; " if reason else "run aborted: "
        return SessionAborted(f"{head}{death}; {outcome}; {kept}", reason=reason or death,
                              log_path=self.request.out)

    def _log_kept(self) -> tuple[str, dict]:
        """The recorder outlives the child and closes the log: wait for it, then say what it kept
        (and return the log's sidecar)."""
        if self.log_path is None:
            return "no log was started", {}
        from urident.logs import read_sidecar, sidecar_path

        deadline = time.monotonic() + LOG_CLOSE_WAIT_S
        while True:
            try:
                data = read_sidecar(sidecar_path(self.log_path))
            except UridentError:
                data = {}
            if data.get("status") not in (None, "running"):
                return f"{data.get('n_samples', 0)} samples kept in {self.log_path}", data
            if time.monotonic() > deadline:
                return (f"the recorder did not close the log {self.log_path} within "
                        f"{LOG_CLOSE_WAIT_S:g} s: check it"), {}
            time.sleep(0.1)

    def _close_live(self, reason: str | None) -> None:
        if self.live is not None:
            self.live.close(reason)


class _PromptInterrupted(Exception):
    """SIGTERM or SIGHUP while the operator is asked: the question is answered "no"."""


class _ParentSignals:
    """SIGINT, SIGTERM and SIGHUP to the caller are handed to ``forward`` (main thread only)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self, forward: Callable[[int], None]):
        self.forward = forward
        self.previous: dict[int, object] = {}

    def __enter__(self) -> "_ParentSignals":
        if threading.current_thread() is threading.main_thread():
            for signum in self.SIGNALS:
                self.previous[signum] = signal.signal(signum, lambda s, _f: self.forward(s))
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)


def _set_handler(signum: int, handler):
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signum, handler)


def _rebuild(verdict: tuple) -> BaseException:
    _, payload, text = verdict
    if payload is not None:
        try:
            return pickle.loads(payload)
        except Exception:  # noqa: BLE001 - an exception that does not unpickle: its text
            pass
    return SessionProcessError(text)


class SessionProcessError(Exception):
    """An unexpected error in the session process, as text (``TypeName: message``)."""


# --------------------------------------------------------------------------- child side
def _child_main(request: RunRequest, events_conn, control_conn, live_conn) -> None:
    try:
        os.setpgid(0, 0)  # the caller forwards signals; a terminal's reach only it
    except OSError:
        pass
    try:
        Path("/proc/self/comm").write_text(PROCESS_NAME)
    except OSError:
        pass
    channel = _Channel(events_conn, live_conn)
    events = _ChildEvents(channel, os.getppid())
    inbox = _Inbox(control_conn, events)
    live = _LiveRelay(channel, inbox) if live_conn is not None else None
    try:
        result = run_local(request, say=events.say, confirm=inbox.confirm(channel), live=live,
                           events=events)
        channel.finish(("result", result))
    except BaseException as exc:  # noqa: BLE001 - every end is reported to the caller
        if os.environ.get("URIDENT_DEBUG") and not isinstance(exc, (UridentError, KeyboardInterrupt)):
            traceback.print_exc()
        channel.finish(("raise", _pickled(exc), f"{type(exc).__name__}: {exc}"))
    # Never run ur_rtde's destructors (a broken client's can crash): leave at once.
    os._exit(0)


def _pickled(exc: BaseException) -> bytes | None:
    try:
        payload = pickle.dumps(exc)
        pickle.loads(payload)
        return payload
    except Exception:  # noqa: BLE001
        return None


class _Channel:
    """The child's side of the pipes, all written from the main thread. Stage messages and the
    heartbeat are small writes to a pipe the caller keeps draining; live samples are fixed-size
    records, each written whole or not at all to a non-blocking pipe (a caller behind on them
    loses view samples, never a control period). With the caller gone, output lines and the final
    error go to this process's own stdout and stderr."""

    def __init__(self, events_conn, live_conn):
        self.conn = events_conn
        self.lock = threading.Lock()
        self.broken = False
        self.next_beat = 0.0
        self.dropped = 0
        self.live_fd = None
        if live_conn is not None:
            self.live_conn = live_conn  # keeps the descriptor open
            self.live_fd = live_conn.fileno()
            os.set_blocking(self.live_fd, False)

    def send(self, message: tuple) -> None:
        if not self.broken:
            try:
                with self.lock:
                    self.conn.send(message)
                return
            except (BrokenPipeError, OSError):
                self.broken = True
        kind = message[0]
        if kind == "say":
            _write(sys.stdout, message[1])
        elif kind == "raise":
            error = _rebuild(message)
            _write(sys.stderr, "urident: interrupted" if isinstance(error, KeyboardInterrupt)
                   else f"urident: error: {error}")

    def beat(self) -> None:
        """Called by the main thread every period: a heartbeat every BEAT_INTERVAL_S."""
        now = time.monotonic()
        if now >= self.next_beat:
            self.next_beat = now + BEAT_INTERVAL_S
            self.send(("beat",))

    def live(self, values: list[float]) -> None:
        if self.live_fd is None:
            return
        try:
            os.write(self.live_fd, LIVE_RECORD.pack(*values))  # ≤ PIPE_BUF: whole or EAGAIN
        except BlockingIOError:
            self.dropped += 1
        except OSError:
            self.live_fd = None

    def finish(self, verdict: tuple) -> None:
        self.send(verdict)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass


def _write(stream, line: str) -> None:
    try:
        print(line, file=stream, flush=True)
    except (OSError, ValueError):
        pass


class _ChildEvents(SessionEvents):
    announce = False  # the caller reports the session process's death

    def __init__(self, channel: _Channel, parent_pid: int):
        self.channel = channel
        self.parent_pid = parent_pid
        self.parent_gone: str | None = None

    def say(self, line: str) -> None:
        self.channel.send(("say", line))

    def ready(self) -> None:
        self.channel.send(("ready",))

    def control_starting(self) -> None:
        self.channel.send(("control",))

    def log_started(self, path: Path) -> None:
        self.channel.send(("log", str(path)))

    def motion(self) -> None:
        self.channel.send(("motion",))

    def alive(self) -> None:
        self.channel.beat()

    def stopping(self, reason: str | None) -> None:
        self.channel.send(("stopping", reason))

    def signal_cause(self, signum: int) -> str | None:
        return self.parent_gone if signum == signal.SIGTERM else None

    def caller_died(self) -> None:
        """The caller's end of the pipe closed: end the session as SIGTERM would, saying why."""
        how = process_death(self.parent_pid)
        # once its own parent (a shell, a test) has reaped it, how it died can no longer be read
        self.parent_gone = ("because the urident run process died" + (f" ({how})" if how else ""))
        os.kill(os.getpid(), signal.SIGTERM)


class _Inbox:
    """The caller's messages, read by a thread: answers to the question, a request to stop."""

    def __init__(self, conn, events: _ChildEvents):
        self.conn = conn
        self.events = events
        self.answers: queue.SimpleQueue = queue.SimpleQueue()
        self.abort_reason: str | None = None
        threading.Thread(target=self._read, name="urident-session-inbox", daemon=True).start()

    def _read(self) -> None:
        while True:
            try:
                message = self.conn.recv()
            except (EOFError, OSError):
                self.events.caller_died()
                return
            if message[0] == "answer":
                self.answers.put(bool(message[1]))
            elif message[0] == "abort":
                self.abort_reason = message[1]

    def confirm(self, channel: _Channel) -> Callable[[str], bool]:
        def ask(question: str) -> bool:
            channel.send(("confirm", question))
            while True:  # with a timeout, so that a signal's handler runs at once
                try:
                    return self.answers.get(timeout=0.2)
                except queue.Empty:
                    continue
        return ask


class _LiveRelay:
    """The session's live view in the child: samples go to the caller's view; a failure there
    ends the run like an exception in the loop."""

    def __init__(self, channel: _Channel, inbox: _Inbox):
        self.channel = channel
        self.inbox = inbox

    def push(self, sample: dict, q_cmd) -> None:
        if self.inbox.abort_reason:
            raise SessionAborted(self.inbox.abort_reason)
        self.channel.live([sample["timestamp"], *sample["actual_q"], *sample["actual_qd"],
                           *sample["actual_current"], *q_cmd])

    def close(self, reason: str | None) -> None:
        """The caller closes the view, with the run's final reason."""
