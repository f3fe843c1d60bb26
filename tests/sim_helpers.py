"""Helpers shared by the simulated-controller tests."""

import socket


def dashboard(host: str, *commands: str) -> list[str]:
    """The dashboard's welcome line and its reply to each command (raw socket on port 29999)."""
    with socket.create_connection((host, 29999), timeout=5) as sock:
        reader = sock.makefile("r")
        lines = [reader.readline().strip()]
        for command in commands:
            sock.sendall((command + "\n").encode())
            lines.append(reader.readline().strip())
        return lines
