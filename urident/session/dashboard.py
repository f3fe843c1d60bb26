"""The controller's dashboard server (TCP 29999) as an operator tool sees it: plain text lines.

Used to stop the program and to check that it *stays* stopped, from the controller's own report
(``programState``) rather than from what a client believes. It opens a fresh connection for each
use, so it works when ur_rtde's clients are broken (they must then not be touched) and from the
recorder process, which has no ur_rtde client at all.
"""

from __future__ import annotations

import socket
import time

DASHBOARD_PORT = 29999
TIMEOUT_S = 2.5
POLL_S = 0.05


class Dashboard:
    """One dashboard connection: ``with Dashboard(host) as d: d.call("programState")``."""

    def __init__(self, host: str, timeout_s: float = TIMEOUT_S):
        self.sock = socket.create_connection((host, DASHBOARD_PORT), timeout=timeout_s)
        self.reader = self.sock.makefile("r", encoding="utf-8", errors="replace", newline="\n")
        self.reader.readline()  # welcome line

    def call(self, command: str) -> str:
        self.sock.sendall((command + "\n").encode("ascii"))
        reply = self.reader.readline()
        if not reply:
            raise ConnectionError("the dashboard server closed the connection")
        return reply.strip()

    def playing(self) -> bool:
        """The controller's own word: ``programState`` starts with PLAYING (or PAUSED)."""
        state = self.call("programState").split()
        return bool(state) and state[0].upper() in ("PLAYING", "PAUSED")

    def close(self) -> None:
        try:
            self.reader.close()
        finally:
            self.sock.close()

    def __enter__(self) -> "Dashboard":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def ensure_stopped(host: str, settle_s: float, timeout_s: float = 15.0,
                   stop_first: bool = False) -> list[str]:
    """Make sure the controller's program is stopped and stays stopped for ``settle_s``: poll
    ``programState``, send ``stop`` whenever it reports PLAYING (a client's automatic reconnect
    can re-upload its control script after a stop). Returns what it had to do or could not do,
    one line each; an empty list means the program was already stopped and stayed so."""
    notes: list[str] = []
    deadline = time.monotonic() + timeout_s
    stops = 0
    quiet_since = time.monotonic()
    problem = None
    while time.monotonic() <= deadline:
        try:
            with Dashboard(host) as dashboard:
                if stop_first and not stops:
                    dashboard.call("stop")
                    stops += 1
                    notes.append("program stopped through the dashboard")
                    quiet_since = time.monotonic()
                while True:
                    now = time.monotonic()
                    if dashboard.playing():
                        dashboard.call("stop")
                        notes.append("controller reported the program PLAYING after the stop: "
                                     "stopped it again through the dashboard" if stops else
                                     "controller reported the program PLAYING: stopped it "
                                     "through the dashboard")
                        stops += 1
                        quiet_since = now
                    elif now - quiet_since >= settle_s:
                        return notes
                    if now > deadline:
                        notes.append(f"the program kept restarting for {timeout_s:g} s: "
                                     f"check the robot")
                        return notes
                    time.sleep(POLL_S)
        except (OSError, ConnectionError) as exc:  # e.g. the controller dropped every connection
            problem = exc
            time.sleep(0.2)
    notes.append(f"cannot check the program state on the dashboard of {host} ({problem}): "
                 f"check the robot")
    return notes
