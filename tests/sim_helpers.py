"""Helpers shared by the simulated-controller tests."""

import os
import socket
import subprocess
import sys
import time
from pathlib import Path


def dashboard(host: str, *commands: str) -> list[str]:
    """The dashboard's welcome line and its reply to each command (raw socket on port 29999)."""
    with socket.create_connection((host, 29999), timeout=5) as sock:
        reader = sock.makefile("r")
        lines = [reader.readline().strip()]
        for command in commands:
            sock.sendall((command + "\n").encode())
            lines.append(reader.readline().strip())
        return lines


def spawn_run(host: str, files: dict, out, **popen) -> subprocess.Popen:
    """`urident run` of ``files["ur5e"]`` with ``files["config"]`` in its own process (pipes open)."""
    cmd = [sys.executable, "-m", "urident.cli.main", "run", "--robot", "ur5e", "--host", host,
           "--trajectory", str(files["ur5e"]), "--out", str(out), "--config", str(files["config"]),
           "--yes"]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            stdin=subprocess.DEVNULL, **popen)


def children(pid: int, name: str) -> list[int]:
    """Pids of the processes called ``name`` (``/proc/PID/comm``) whose parent is ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        comm = stat[stat.index("(") + 1: stat.rindex(")")]
        ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        if ppid == pid and comm == name:
            found.append(int(entry.name))
    return found


def session_child(pid: int, timeout_s: float = 10.0) -> int:
    """The pid of the session process (ur_rtde's clients) that `urident run` ``pid`` supervises."""
    deadline = time.monotonic() + timeout_s
    while True:
        found = children(pid, "urident-session")
        if len(found) == 1:
            return found[0]
        assert time.monotonic() < deadline, f"no single urident-session child of {pid}: {found}"
        time.sleep(0.05)


def process_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True
