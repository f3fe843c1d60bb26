"""The network side of the simulated controller and its real-time loop.

Ports (bound on the given address only): RTDE 30004, dashboard 29999, script 30003 (secondary,
also 30002 primary). One thread accepts connections, one thread per connection reads from it;
the controller loop runs in the calling (main) thread:

    sleep until 0.1 ms before the cycle's deadline, spin to the deadline,
    controller.tick()  (requests, faults, script emulator, plant step),
    send each started RTDE connection the data packages that are due.

A cycle is *late* when its data leave more than half a period after its deadline. If the loop
falls more than ``RESYNC_PERIODS`` behind (e.g. the machine was suspended) it re-anchors instead of
running the missed cycles back to back.
"""

from __future__ import annotations

import errno
import gc
import json
import selectors
import socket
import struct
import sys
import threading
import time

from urident.errors import UridentError
from urident.simcontroller import fields
from urident.rtde import protocol as rp
from urident.simcontroller.controller import Controller
from urident.simcontroller.dashboard import WELCOME, DashboardSession
from urident.simcontroller.script_emulator import ScriptStream
from urident.simcontroller.snapshot import Snapshot

RTDE_PORT = 30004
DASHBOARD_PORT = 29999
SECONDARY_PORT = 30003
PRIMARY_PORT = 30002
PORTS = {"rtde": RTDE_PORT, "dashboard": DASHBOARD_PORT, "script": SECONDARY_PORT, "primary": PRIMARY_PORT}

SPIN_S = 0.0001   # spinning costs CPU (5 % of a core at 500 Hz) but absorbs most wake-up jitter
LATE_FRACTION = 0.5
RESYNC_PERIODS = 50
MAX_PENDING_BYTES = 1 << 20


def raise_priority(priority: int = 10) -> str:
    """Give this process (and the threads it starts afterwards) real-time scheduling if allowed.

    SCHED_FIFO cuts the wake-up latency of the controller loop under load from milliseconds to tens
    of microseconds. The loop sleeps every cycle, so it cannot starve the machine. Falls back to a
    lower nice value, then to nothing. Returns what was applied.
    """
    import os

    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO priority {priority}"
    except (AttributeError, OSError, PermissionError):
        pass
    try:
        os.nice(-10)
        return "nice -10"
    except (AttributeError, OSError, PermissionError):
        return "normal priority"


class BindError(UridentError):
    """A port of the simulated controller cannot be bound."""


class _Connection:
    def __init__(self, server: "SimControllerServer", sock: socket.socket, kind: str):
        self.server = server
        self.sock = sock
        self.kind = kind
        self.closed = False
        try:
            self.peer = "%s:%d" % sock.getpeername()[:2]
        except OSError:
            self.peer = "?"

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        try:
            self.sock.close()
        except OSError:
            pass
        self.server._forget(self)

    def run(self) -> None:
        try:
            self.serve()
        except (ConnectionResetError, BrokenPipeError):
            pass                                   # the client went away: normal for ur_rtde
        except (OSError, rp.ProtocolError, ValueError) as exc:
            if not self.closed and not self.server.stopping:
                self.server.controller.log(f"{self.kind} connection {self.peer} ended: {exc}")
        finally:
            self.close()

    def serve(self) -> None:
        raise NotImplementedError


class RtdeConnection(_Connection):
    """One RTDE client: recipes are per connection; input recipe ids count 1, 2, 3, ..."""

    def __init__(self, server, sock):
        super().__init__(server, sock, "rtde")
        self.protocol_version = 1
        self.output_recipes: list[rp.Recipe] = []
        self.input_recipes: dict[int, rp.Recipe] = {}
        self.started = False
        self.send_lock = threading.Lock()
        self.pending = b""
        self.dropped_packages = 0
        self.owned_inputs: set[str] = set()

    # ------------------------------------------------------------ sending
    def send_reply(self, data: bytes) -> None:
        with self.send_lock:
            if self.pending:
                self.sock.sendall(self.pending)
                self.pending = b""
            self.sock.sendall(data)

    def send_data(self, data: bytes) -> None:
        """Called by the controller thread; never blocks on a slow client (packages are dropped)."""
        with self.send_lock:
            if not self.started or self.closed:
                return
            try:
                if self.pending:
                    sent = self.sock.send(self.pending, socket.MSG_DONTWAIT)
                    self.pending = self.pending[sent:]
                    if self.pending:
                        self.dropped_packages += 1
                        return
                sent = self.sock.send(data, socket.MSG_DONTWAIT)
                if sent < len(data):
                    self.pending = data[sent:]
            except BlockingIOError:
                self.dropped_packages += 1
            except OSError:
                self.close()

    # ------------------------------------------------------------ receiving
    def serve(self) -> None:
        reader = rp.MessageReader()
        while not self.closed:
            data = self.sock.recv(65536)
            if not data:
                return
            for message_type, payload in reader.feed(data):
                self.handle(message_type, payload)

    def handle(self, message_type: int, payload: bytes) -> None:
        controller = self.server.controller
        version = controller.version
        if message_type == rp.DATA_PACKAGE:
            if not payload:
                return
            recipe = self.input_recipes.get(payload[0])
            if recipe is not None:
                controller.apply_inputs(recipe.unpack(payload))
        elif message_type == rp.REQUEST_PROTOCOL_VERSION:
            (requested,) = struct.unpack(">H", payload[:2].rjust(2, b"\0"))
            accepted = requested in (1, 2)
            if accepted:
                self.protocol_version = requested
            self.send_reply(rp.success_reply(rp.REQUEST_PROTOCOL_VERSION, accepted))
        elif message_type == rp.GET_URCONTROL_VERSION:
            self.send_reply(rp.version_reply(*version))
        elif message_type == rp.CONTROL_PACKAGE_SETUP_OUTPUTS:
            frequency, names = rp.parse_output_setup(payload, self.protocol_version)
            types = [fields.output_type(n, version) or rp.NOT_FOUND for n in names]
            if not names or rp.NOT_FOUND in types:
                self.server.log_once(f"output setup with unknown names: "
                                     f"{[n for n, t in zip(names, types) if t == rp.NOT_FOUND]}")
                self.send_reply(rp.setup_reply(message_type, 0, types))
                return
            rate = controller.rate_hz
            frequency = rate if frequency is None or frequency <= 0 else min(frequency, rate)
            recipe = rp.Recipe.build(len(self.output_recipes) + 1, names, types,
                                     [fields.output_getter(n) for n in names],
                                     max(1, round(rate / frequency)))
            self.output_recipes.append(recipe)
            self.server.note_recipe("output", names)
            self.send_reply(rp.setup_reply(message_type, recipe.recipe_id, types))
        elif message_type == rp.CONTROL_PACKAGE_SETUP_INPUTS:
            names = rp.parse_names(payload)
            types = [fields.input_type(n, version) or rp.NOT_FOUND for n in names]
            owners = self.server.claim_inputs(self, names)
            types = [rp.IN_USE if owner is not None and t != rp.NOT_FOUND else t
                     for t, owner in zip(types, owners)]
            if not names or rp.NOT_FOUND in types or rp.IN_USE in types:
                self.server.release_inputs(self, names)
                self.send_reply(rp.setup_reply(message_type, 0, types))
                return
            recipe = rp.Recipe.build(len(self.input_recipes) + 1, names, types)
            self.input_recipes[recipe.recipe_id] = recipe
            self.server.note_recipe("input", names)
            self.send_reply(rp.setup_reply(message_type, recipe.recipe_id, types))
        elif message_type == rp.CONTROL_PACKAGE_START:
            with self.send_lock:
                self.sock.sendall(rp.success_reply(message_type, True))
                self.started = True
        elif message_type == rp.CONTROL_PACKAGE_PAUSE:
            with self.send_lock:
                self.started = False
                self.pending = b""
                self.sock.sendall(rp.success_reply(message_type, True))
        # text messages from clients and unknown types are ignored


class DashboardConnection(_Connection):
    def __init__(self, server, sock):
        super().__init__(server, sock, "dashboard")
        self.session = DashboardSession(server.controller)

    def serve(self) -> None:
        self.sock.sendall((WELCOME + "\n").encode())
        buffer = b""
        while not self.closed:
            data = self.sock.recv(4096)
            if not data:
                return
            buffer += data
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                reply = self.session.handle(line.decode("utf-8", errors="replace"))
                if reply is None:
                    self.sock.sendall(b"Disconnected\n")
                    return
                self.sock.sendall((reply + "\n").encode())


class ScriptConnection(_Connection):
    def __init__(self, server, sock, kind):
        super().__init__(server, sock, kind)

    def serve(self) -> None:
        stream = ScriptStream()
        while not self.closed:
            data = self.sock.recv(65536)
            if not data:
                return
            for program in stream.feed(data):
                self.server.controller.call_soon(self.server.controller.load_program, program)


class SimControllerServer:
    """Binds the ports, accepts clients and runs the controller loop (see the module docstring)."""

    def __init__(self, controller: Controller, host: str = "127.0.0.1", ports: dict[str, int] | None = None):
        self.controller = controller
        self.host = host
        self.ports = dict(PORTS if ports is None else ports)
        self.stopping = False
        self.verbose = False
        self._listeners: dict[socket.socket, str] = {}
        self._connections: set[_Connection] = set()
        self._rtde: list[RtdeConnection] = []
        self._lock = threading.Lock()
        self._input_owners: dict[str, RtdeConnection] = {}
        self._logged: set[str] = set()
        self.recipes_seen: dict[str, list[list[str]]] = {"output": [], "input": []}
        self.stats = {"cycles": 0, "late_cycles": 0, "late_wakeups": 0, "max_lateness_s": 0.0,
                      "max_work_s": 0.0, "resyncs": 0, "dropped_packages": 0}

    # ------------------------------------------------------------ sockets
    def bind(self) -> None:
        for kind, port in self.ports.items():
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind((self.host, port))
            except OSError as exc:
                sock.close()
                self.close_listeners()
                reason = "address in use (another controller?)" if exc.errno == errno.EADDRINUSE else exc.strerror
                raise BindError(f"cannot bind {self.host}:{port} ({kind}): {reason}") from None
            sock.listen(8)
            self._listeners[sock] = kind

    def close_listeners(self) -> None:
        for sock in list(self._listeners):
            try:
                sock.close()
            except OSError:
                pass
        self._listeners.clear()

    def _accept_loop(self) -> None:
        selector = selectors.DefaultSelector()
        for sock in self._listeners:
            selector.register(sock, selectors.EVENT_READ)
        while not self.stopping:
            for key, _ in selector.select(timeout=0.1):
                try:
                    client, _ = key.fileobj.accept()
                except OSError:
                    continue
                self._start_connection(client, self._listeners.get(key.fileobj, "script"))
        selector.close()

    def _start_connection(self, client: socket.socket, kind: str) -> None:
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if kind == "rtde":
            conn: _Connection = RtdeConnection(self, client)
        elif kind == "dashboard":
            conn = DashboardConnection(self, client)
        else:
            conn = ScriptConnection(self, client, kind)
        with self._lock:
            self._connections.add(conn)
            if isinstance(conn, RtdeConnection):
                self._rtde = self._rtde + [conn]
        threading.Thread(target=conn.run, name=f"{kind}-{conn.peer}", daemon=True).start()

    def _forget(self, conn: _Connection) -> None:
        with self._lock:
            self._connections.discard(conn)
            if isinstance(conn, RtdeConnection):
                self._rtde = [c for c in self._rtde if c is not conn]
                self.stats["dropped_packages"] += conn.dropped_packages
                for name in [n for n, owner in self._input_owners.items() if owner is conn]:
                    del self._input_owners[name]

    def claim_inputs(self, conn: RtdeConnection, names: list[str]) -> list[RtdeConnection | None]:
        """Register ``conn`` as owner of input ``names``; returns the other owner per name or None."""
        owners = []
        with self._lock:
            for name in names:
                owner = self._input_owners.get(name)
                if owner is not None and owner is not conn and not owner.closed:
                    owners.append(owner)
                else:
                    self._input_owners[name] = conn
                    owners.append(None)
        return owners

    def release_inputs(self, conn: RtdeConnection, names: list[str]) -> None:
        with self._lock:
            for name in names:
                if self._input_owners.get(name) is conn and not any(
                        name in r.names for r in conn.input_recipes.values()):
                    del self._input_owners[name]

    def drop_all_connections(self) -> None:
        with self._lock:
            connections = list(self._connections)
        for conn in connections:
            conn.close()

    def note_recipe(self, kind: str, names: list[str]) -> None:
        self.recipes_seen[kind].append(list(names))
        if self.verbose:
            self.controller.log(f"{kind} recipe {len(self.recipes_seen[kind])}: {','.join(names)}")

    def log_once(self, message: str) -> None:
        if message not in self._logged:
            self._logged.add(message)
            self.controller.log(message)

    # ------------------------------------------------------------ the loop
    def publish(self) -> None:
        controller = self.controller
        if controller.drop_requested:
            controller.drop_requested = False
            self.drop_all_connections()
            return
        if controller.sending_paused():
            return
        tick = controller.tick_count
        snapshot = None
        for conn in self._rtde:
            if not conn.started:
                continue
            for recipe in conn.output_recipes:
                if tick % recipe.ticks_per_package:
                    continue
                if snapshot is None:
                    snapshot = Snapshot(controller)
                conn.send_data(recipe.pack([get(snapshot) for get in recipe.getters]))

    def request_stop(self, *_args) -> None:
        self.stopping = True

    def serve_forever(self, ready_message: str | None = None, max_cycles: int | None = None) -> dict:
        """Run until :meth:`request_stop` (e.g. from a signal handler); returns the loop statistics."""
        if not self._listeners:
            self.bind()
        previous_interval = sys.getswitchinterval()
        sys.setswitchinterval(0.0005)
        acceptor = threading.Thread(target=self._accept_loop, name="accept", daemon=True)
        acceptor.start()
        if ready_message:
            print(ready_message, flush=True)
        controller = self.controller
        period = controller.dt
        late_after = LATE_FRACTION * period
        # Move everything allocated so far (models, tables) out of the collector's reach: a full
        # collection over it takes milliseconds, in whichever thread happens to trigger it.
        gc.collect()
        gc.freeze()
        stats = self.stats
        clock = time.perf_counter
        cpu_start = time.process_time()
        wall_start = clock()
        deadline = clock() + period
        try:
            while not self.stopping:
                remaining = deadline - clock()
                if remaining > SPIN_S:
                    time.sleep(remaining - SPIN_S)
                while clock() < deadline:
                    pass
                start = clock()
                controller.tick()
                self.publish()
                end = clock()
                controller.last_execution_time_s = end - start
                lateness = end - deadline
                stats["cycles"] += 1
                if lateness > late_after:
                    stats["late_cycles"] += 1
                    if start - deadline > late_after:
                        stats["late_wakeups"] += 1      # late before any work: the scheduler
                if end - start > stats["max_work_s"]:
                    stats["max_work_s"] = end - start
                if lateness > stats["max_lateness_s"]:
                    stats["max_lateness_s"] = lateness
                deadline += period
                if end - deadline > RESYNC_PERIODS * period:
                    stats["resyncs"] += 1
                    deadline = end + period
                if max_cycles is not None and stats["cycles"] >= max_cycles:
                    break
        finally:
            self.stopping = True
            self.close_listeners()
            self.drop_all_connections()
            acceptor.join(timeout=1.0)
            sys.setswitchinterval(previous_interval)
            wall = clock() - wall_start
            stats["wall_s"] = wall
            stats["cpu_s"] = time.process_time() - cpu_start
            stats["cpu_pct"] = 100.0 * stats["cpu_s"] / wall if wall > 0 else 0.0
            stats["late_cycle_pct"] = 100.0 * stats["late_cycles"] / max(stats["cycles"], 1)
        return stats


def format_stats(stats: dict) -> str:
    return "stats " + json.dumps({k: (round(v, 6) if isinstance(v, float) else v) for k, v in stats.items()})
