"""Helpers shared by the simulated-controller tests."""

import socket
import subprocess
import sys


def dashboard(host: str, *commands: str) -> list[str]:
    """The dashboard's welcome line and its reply to each command (raw socket on port 29999)."""
    with socket.create_connection((host, 29999), timeout=5) as sock:
        reader = sock.makefile("r")
        lines = [reader.readline().strip()]
        for command in commands:
            sock.sendall((command + "\n").encode())
            lines.append(reader.readline().strip())
        return lines


def spawn_run(host: str, files: dict, out) -> subprocess.Popen:
    """`urident run` of ``files["ur5e"]`` with ``files["config"]`` in its own process (pipes open)."""
    cmd = [sys.executable, "-m", "urident.cli.main", "run", "--robot", "ur5e", "--host", host,
           "--trajectory", str(files["ur5e"]), "--out", str(out), "--config", str(files["config"]),
           "--yes"]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            stdin=subprocess.DEVNULL)
