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
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from urident.errors import ConnectionLost
from urident.rtde import protocol as rp

RTDE_PORT = 30004
READ_TIMEOUT_S = 2.5
SESSION_STOP_WAIT_S = 15.0  # after a lost connection, wait this long for the session's verdict


@dataclass(frozen=True)
class RecorderStats:
    n_samples: int
    missed_samples: int          # gaps in the controller timestamps, in periods
    first_timestamp: float | None
    last_timestamp: float | None
    fields: tuple[str, ...]
    status: str
    abort_reason: str | None


class RtdeRecorder:
    """Start with :meth:`start` (returns once the first package is on disk), stop with
    :meth:`stop`, which finalises the log's sidecar with the session's status."""

    def __init__(self, host: str, rate_hz: float, out: Path, metadata: dict[str, Any],
                 fields: list[str] | None = None):
        self.fields = fields  # log field names to ask for (default: urident.logs.LOG_FIELDS)
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
                                          child, os.getpid(), self.fields))
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

    def stop(self, status: str, abort_reason: str | None, extra: dict[str, Any],
             timeout_s: float = 10.0) -> RecorderStats | None:
        if self._process is None:
            return None
        try:
            self._conn.send(("stop", status, abort_reason, extra))
            stats = self._conn.recv() if self._conn.poll(timeout_s) else None
        except (BrokenPipeError, EOFError, OSError):
            stats = None
        self._process.join(timeout_s)
        if self._process.is_alive():
            self._kill()
        self._process = None
        return stats

    def _kill(self) -> None:
        if self._process is not None and self._process.is_alive():
            self._process.terminate()
            self._process.join(5)


def _record_main(host: str, rate_hz: float, out: str, metadata: dict, conn, parent_pid: int,
                 names: list[str] | None = None) -> None:
    # Ctrl-C reaches the whole process group: the session decides when the recording ends.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from urident.logs import LOG_FIELDS, OPTIONAL_FIELDS, LogWriter

    names = names or [f.name for f in LOG_FIELDS]
    try:
        sock, recipe, reader = _connect(host, rate_hz, names)
    except (OSError, rp.ProtocolError, ConnectionLost) as exc:
        conn.send(("error", str(exc)))
        return
    known = {f.name: f for f in LOG_FIELDS + OPTIONAL_FIELDS}
    fields = [known[n] for n in names if n in recipe.names]
    writer = LogWriter(out, fields=fields, metadata=metadata, overwrite=True)
    period = 1.0 / rate_hz
    n = missed = 0
    first = last = None
    status, reason, extra = "aborted", None, {}
    ready_sent = False
    try:
        while True:
            if conn.poll():
                message = conn.recv()
                if message[0] == "stop":
                    _, status, reason, extra = message
                    _drain(sock, reader, recipe, writer)  # what arrived before the stop
                    break
            if os.getppid() != parent_pid:
                reason = "the session process ended without closing the log"
                break
            try:
                data = sock.recv(65536)
            except socket.timeout:
                continue
            except ConnectionError:
                data = b""
            if data == b"":  # the controller closed the connection
                reason = "the controller closed the recorder's RTDE connection"
                # The session's stop message carries the status and the real reason.
                if conn.poll(SESSION_STOP_WAIT_S):
                    message = conn.recv()
                    if message[0] == "stop":
                        _, status, session_reason, extra = message
                        reason = session_reason or reason
                break
            for kind, payload in reader.feed(data):
                if kind != rp.DATA_PACKAGE:
                    continue
                values = recipe.unpack(payload)
                stamp = values["timestamp"]
                if last is not None:
                    steps = round((stamp - last) / period)
                    if steps > 1:
                        missed += steps - 1
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
    finally:
        try:
            sock.sendall(rp.frame(rp.CONTROL_PACKAGE_PAUSE))
        except OSError:
            pass
        sock.close()
        extra = dict(extra or {})
        late = int(extra.pop("late_cycles", 0) or 0)
        if late:
            writer.mark_late_cycle(late)
        extra["recorder"] = {"missed_samples": missed, "first_timestamp": first, "last_timestamp": last}
        writer.close(status=status if status else "aborted", abort_reason=reason, extra=extra)
        stats = RecorderStats(n, missed, first, last, tuple(f.name for f in fields), status, reason)
        try:
            if not ready_sent:
                conn.send(("error", reason or "no data received"))
            conn.send(stats)
        except (BrokenPipeError, OSError):
            pass


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
