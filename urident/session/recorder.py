"""The session recorder: every controller sample into the log, from a process of its own.

ur_rtde's receive interface keeps only the newest package, so a control loop that reads it once a
period misses or repeats samples whenever its clock drifts against the controller's. The recorder
opens its own RTDE connection (the controller serves several), asks for the log's fields at the
controller rate and writes every data package TCP delivers. Running in its own process, it costs
the control loop nothing, and it survives the session process: if that dies, the recorder closes
the log as aborted.

Protocol (our own codec, :mod:`urident.rtde.protocol`): request protocol version 2, set up the
outputs at the controller rate, start, read ``U`` packages until told to stop, pause.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import socket
import struct
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from urident.errors import ConnectionLost
from urident.rtde import protocol as rp
from urident.session.handover import generation, hold_watch

RTDE_PORT = 30004
READ_TIMEOUT_S = 2.5
SESSION_STOP_WAIT_S = 15.0  # after a lost connection, wait this long for the session's verdict
WATCH_PARENT_S = 10.0       # after the log is closed, wait this long for the session to exit …
WATCH_SETTLE_S = 2.0        # … then the program must report STOPPED this long
MAX_GAPS_LISTED = 1000      # the sidecar lists this many gaps; ``gap_count`` counts them all
CONTROLLER_CLOSED = "the controller closed the recorder's RTDE connection"


@dataclass(frozen=True)
class RecorderStats:
    n_samples: int
    missed_samples: int          # gaps in the controller timestamps, in periods
    gaps: tuple[dict, ...]       # where: after_s, resume_s, missing_periods
    first_timestamp: float | None
    last_timestamp: float | None
    fields: tuple[str, ...]
    status: str
    abort_reason: str | None


class RtdeRecorder:
    """Start with :meth:`start` (returns once the first package is on disk), stop with
    :meth:`stop`, which finalises the log's sidecar with the session's status."""

    def __init__(self, host: str, rate_hz: float, out: Path, metadata: dict[str, Any],
                 fields: list[str] | None = None, announce: bool = True):
        self.fields = fields  # log field names to ask for (default: urident.logs.LOG_FIELDS)
        # Say on stderr when the session process died; a supervisor of the session says it instead.
        self.announce = announce
        self.host = host
        self.rate_hz = rate_hz
        self.out = Path(out)
        self.metadata = metadata
        self._process: mp.Process | None = None
        self._conn = None

    def start(self, timeout_s: float = 20.0) -> tuple[str, ...]:
        ctx = mp.get_context("spawn")  # never fork a process that holds ur_rtde's threads
        parent, child = ctx.Pipe()
        self._process = ctx.Process(target=_record_main, name="urident-recorder", daemon=False,
                                    args=(self.host, self.rate_hz, str(self.out), self.metadata,
                                          child, os.getpid(), self.fields, self.announce))
        self._process.start()
        child.close()
        self._conn = parent
        if not parent.poll(timeout_s):
            self._kill()
            raise ConnectionLost(f"the log recorder did not start within {timeout_s:g} s")
        kind, payload = parent.recv()
        if kind != "ready":
            self._process.join(5)
            raise ConnectionLost(f"the log recorder could not start: {payload}")
        return tuple(payload)

    def note(self, abort_reason: str | None) -> None:
        """The session's reason to stop, before it stops the robot: the log keeps it even if the
        session process dies while stopping."""
        if self._process is None or not abort_reason:
            return
        try:
            self._conn.send(("note", abort_reason))
        except (BrokenPipeError, OSError):
            pass

    def stop(self, status: str, abort_reason: str | None, extra: dict[str, Any],
             timeout_s: float = 10.0) -> RecorderStats | None:
        """Close the log. A watcher forked from the recorder then outlives this process: ur_rtde's
        clients (a broken one's reconnect thread re-uploads the control script) live until it
        ends, so once it has ended the watcher makes sure the controller's program stays stopped."""
        if self._process is None:
            return None
        try:
            self._conn.send(("stop", status, abort_reason, extra))
            stats = self._conn.recv() if self._conn.poll(timeout_s) else None
        except (BrokenPipeError, EOFError, OSError):
            stats = None
        if stats is not None:
            # The log is closed: do not wait the ~0.3 s the recorder takes to exit (multiprocessing
            # reaps it later), since after a lost link every moment beside ur_rtde's reconnect
            # thread risks a crash.
            self._process = None
            return stats
        self._process.join(timeout_s)
        if self._process.is_alive():
            self._kill()
        self._process = None
        return stats

    def _kill(self) -> None:
        if self._process is not None and self._process.is_alive():
            self._process.kill()  # it ignores SIGTERM (see _record_main)
            self._process.join(5)


def _proc_stat(pid: int) -> list[str] | None:
    """Fields 3.. of ``/proc/PID/stat`` (state first), or None when there is no such process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat[stat.rindex(")") + 2:].split()


def _alive(pid: int) -> bool:
    """``pid`` runs (a zombie has ended: it only waits to be reaped)."""
    fields = _proc_stat(pid)
    return fields is not None and fields[0] != "Z"


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return "unknown signal"


def process_death(pid: int) -> str | None:
    """How the ended process ``pid`` died ("killed by signal 9, SIGKILL", "exit code 1"), as far
    as can be told: a dead process stays a zombie until its own parent reaps it, and
    ``/proc/PID/stat`` then holds its wait status (field 52, Linux ≥ 3.5)."""
    fields = _proc_stat(pid)
    if fields and fields[0] == "Z" and len(fields) >= 50 and fields[49].lstrip("-").isdigit():
        status = int(fields[49])
        if os.WIFSIGNALED(status):
            signum = os.WTERMSIG(status)
            return f"killed by signal {signum}, {signal_name(signum)}"
        if os.WIFEXITED(status):
            return f"exit code {os.WEXITSTATUS(status)}"
    return None


def session_death(pid: int) -> str:
    """Why the session process ``pid`` (our parent) is gone, as far as can be told."""
    how = process_death(pid)
    return f"session process died ({how})" if how else "session process died"


def _stop_orphaned_program(host: str) -> str:
    """The session died with the program possibly running: stop it through the dashboard."""
    from urident.session.dashboard import ensure_stopped

    notes = ensure_stopped(host, settle_s=1.0, stop_first=True)
    unsure = [n for n in notes if "check the robot" in n]
    return unsure[-1] if unsure else "program stopped through the dashboard"


def _record_main(host: str, rate_hz: float, out: str, metadata: dict, conn, parent_pid: int,
                 names: list[str] | None = None, announce: bool = True) -> None:
    # Ctrl-C, SIGTERM and SIGHUP reach the whole process group (or a terminal's): the session
    # decides when the recording ends, and if the session itself dies the recorder notices.
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, signal.SIG_IGN)
    from urident.logs import LOG_FIELDS, OPTIONAL_FIELDS, LogWriter
    from urident.logs.gaps import Gap, missing_periods

    names = names or [f.name for f in LOG_FIELDS]
    try:
        sock, recipe, reader = _connect(host, rate_hz, names)
    except (OSError, rp.ProtocolError, ConnectionLost) as exc:
        conn.send(("error", str(exc)))
        return
    # Held until the watcher forked below has ended: the next run waits for it (handover).
    watch_fd = hold_watch(host)
    since = generation(host)
    known = {f.name: f for f in LOG_FIELDS + OPTIONAL_FIELDS}
    fields = [known[n] for n in names if n in recipe.names]
    writer = LogWriter(out, fields=fields, metadata=metadata, overwrite=True)
    period = 1.0 / rate_hz
    n = missed = gap_count = 0
    gaps: list[dict] = []
    first = last = None
    status, reason, extra = "aborted", None, {}
    ready_sent = False
    orphaned = False
    session_reason = None  # the session's reason to stop, sent before it stops the robot
    controller_closed = False
    try:
        while True:
            if conn.poll():
                try:
                    message = conn.recv()
                except (EOFError, OSError):  # the session's end of the pipe closed: it died
                    orphaned = True
                    break
                if message[0] == "note":
                    session_reason = message[1]
                    continue
                if message[0] == "stop":
                    _, status, reason, extra = message
                    _drain(sock, reader, recipe, writer)  # what arrived before the stop
                    break
            if os.getppid() != parent_pid:
                orphaned = True
                break
            try:
                data = sock.recv(65536)
            except socket.timeout:
                continue
            except ConnectionError:
                data = b""
            if data == b"":  # the controller closed the connection
                controller_closed = True
                reason = CONTROLLER_CLOSED
                # The session's stop message carries the status and the real reason.
                deadline = time.monotonic() + SESSION_STOP_WAIT_S
                try:
                    while conn.poll(max(deadline - time.monotonic(), 0.0)):
                        message = conn.recv()
                        if message[0] == "note":
                            session_reason = message[1]
                            continue
                        if message[0] == "stop":
                            _, status, stop_reason, extra = message
                            reason = stop_reason or reason
                        break
                except (EOFError, OSError):
                    orphaned = True
                break
            for kind, payload in reader.feed(data):
                if kind != rp.DATA_PACKAGE:
                    continue
                values = recipe.unpack(payload)
                stamp = values["timestamp"]
                if last is not None:
                    lost = missing_periods(stamp - last, period)
                    if lost:
                        missed += lost
                        gap_count += 1
                        if len(gaps) < MAX_GAPS_LISTED:
                            gaps.append(Gap(n, last, stamp, lost).as_dict())
                if writer.append(values):
                    n += 1
                    first = stamp if first is None else first
                    last = stamp
                if not ready_sent:
                    writer.flush()
                    conn.send(("ready", [f.name for f in fields]))
                    ready_sent = True
    except Exception as exc:  # noqa: BLE001 - the log must be closed whatever happens
        reason = f"recorder error: {type(exc).__name__}: {exc}"
        status = "aborted"
        orphaned = orphaned or os.getppid() != parent_pid
    finally:
        if orphaned:
            # Nobody else will stop the robot: the session process is gone.
            status = "aborted"
            reason = f"{session_death(parent_pid)}; {_stop_orphaned_program(host)}"
            before = session_reason or (CONTROLLER_CLOSED if controller_closed else None)
            if before:
                reason = f"{before}; {reason}"
            _drain(sock, reader, recipe, writer)  # what the controller sent until the stop
            if announce:  # the session cannot say it any more: the recorder shares its terminal
                _say(f"urident: error: run aborted: {reason}; {writer.n_samples} samples kept in {out}")
        try:
            sock.sendall(rp.frame(rp.CONTROL_PACKAGE_PAUSE))
        except OSError:
            pass
        sock.close()
        extra = dict(extra or {})
        late = int(extra.pop("late_cycles", 0) or 0)
        if late:
            writer.mark_late_cycle(late)
        extra["recorder"] = {"missed_samples": missed, "gap_count": gap_count, "gaps": gaps,
                             "first_timestamp": first, "last_timestamp": last,
                             "controller_closed_connection": controller_closed}
        writer.close(status=status if status else "aborted", abort_reason=reason, extra=extra)
        stats = RecorderStats(n, missed, tuple(gaps), first, last, tuple(f.name for f in fields),
                              status, reason)
        try:
            if not ready_sent:
                conn.send(("error", reason or "no data received"))
            conn.send(stats)
        except (BrokenPipeError, OSError):
            pass
    if not orphaned and ready_sent and os.fork() == 0:
        try:
            # Keep only the terminal and the watch lock: an inherited copy of multiprocessing's
            # sentinel pipe would make the session's join() wait for this watcher instead of
            # the recorder.
            keep = watch_fd if watch_fd is not None else os.sysconf("SC_OPEN_MAX")
            os.closerange(3, keep)
            os.closerange(keep + 1, os.sysconf("SC_OPEN_MAX"))
            _watch_program(host, parent_pid, out, announce, since)
        finally:
            os._exit(0)


def _say(line: str) -> None:
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _watch_program(host: str, parent_pid: int, out: str, announce: bool = True,
                   since_generation: int | None = None) -> None:
    """After the session process exited (its ur_rtde clients with it), the controller's program
    must be stopped and stay so; what had to be done is added to the sidecar. A session process
    that lives on (the Python API) may start its next run: nothing is done then, and the watch
    ends as soon as that run announces itself (``since_generation``, :mod:`.handover`). A next run
    waits for this watch to end, so a program stopped here is never another run's."""
    from urident.logs import read_sidecar, sidecar_path
    from urident.logs.sidecar import write_sidecar
    from urident.session.dashboard import ensure_stopped

    deadline = time.monotonic() + WATCH_PARENT_S
    while _alive(parent_pid):
        if time.monotonic() > deadline:
            return
        if since_generation is not None and generation(host) != since_generation:
            return
        time.sleep(0.02)
    death = session_death(parent_pid)
    notes = ensure_stopped(host, WATCH_SETTLE_S)
    if announce and "signal" in death:  # it crashed after closing the log (ur_rtde can, after a lost link)
        stopped = [n for n in notes if "check the robot" in n] or ["program stopped"]
        _say(f"urident: error: {death} after the log was closed; {stopped[-1]}; the log "
             f"{out} is complete up to the stop")
    if notes:
        path = sidecar_path(out)
        data = read_sidecar(path)
        extra = data.setdefault("extra", {}) or {}
        extra["stop_problems"] = list(extra.get("stop_problems") or []) + [
            f"after the session exited: {n}" for n in notes]
        data["extra"] = extra
        write_sidecar(path, data)


def _drain(sock, reader, recipe, writer) -> None:
    sock.setblocking(False)
    try:
        while True:
            data = sock.recv(65536)
            if not data:
                break
            for kind, payload in reader.feed(data):
                if kind == rp.DATA_PACKAGE:
                    writer.append(recipe.unpack(payload))
    except (BlockingIOError, OSError):
        pass
    finally:
        sock.setblocking(True)
        sock.settimeout(0.1)


def _request(sock: socket.socket, reader: rp.MessageReader, message_type: int,
             payload: bytes) -> bytes:
    sock.sendall(rp.frame(message_type, payload))
    deadline = time.monotonic() + READ_TIMEOUT_S
    while time.monotonic() < deadline:
        data = sock.recv(65536)
        if not data:
            raise ConnectionLost("the controller closed the RTDE connection during set-up")
        for kind, reply in reader.feed(data):
            if kind == message_type:
                return reply
    raise ConnectionLost(f"no RTDE reply to '{chr(message_type)}' within {READ_TIMEOUT_S} s")


def _connect(host: str, rate_hz: float, names: list[str]):
    sock = socket.create_connection((host, RTDE_PORT), timeout=READ_TIMEOUT_S)
    reader = rp.MessageReader()
    reply = _request(sock, reader, rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2))
    if not reply or reply[0] != 1:
        raise ConnectionLost("the controller refused RTDE protocol version 2")
    for _ in range(2):
        reply = _request(sock, reader, rp.CONTROL_PACKAGE_SETUP_OUTPUTS,
                         struct.pack(">d", rate_hz) + ",".join(names).encode("ascii"))
        recipe_id, types = reply[0], reply[1:].decode("ascii").split(",")
        missing = [n for n, t in zip(names, types) if t == rp.NOT_FOUND]
        if not missing:
            break
        # Older controllers lack some outputs: record the others.
        names = [n for n, t in zip(names, types) if t != rp.NOT_FOUND]
    if "timestamp" not in names or "actual_q" not in names:
        raise ConnectionLost("the controller does not provide timestamp and actual_q over RTDE")
    recipe = rp.Recipe.build(recipe_id, names, types)
    reply = _request(sock, reader, rp.CONTROL_PACKAGE_START, b"")
    if not reply or reply[0] != 1:
        raise ConnectionLost("the controller refused to start the recorder's RTDE outputs")
    sock.settimeout(0.1)
    return sock, recipe, reader
