"""Dashboard server (TCP port 29999): one text line in, one text line out.

Covers what ur_rtde's DashboardClient sends (welcome line, ``PolyscopeVersion``,
``get serial number``, ``is in remote control``, ``stop``, ``play``, ``robotmode``, ``safetymode``,
``safetystatus``, ``programState``, ``running``, ``unlock protective stop``, ``power on/off``,
``brake release``, ...) with the replies of PolyScope 5 (CB3 differs only in details ur_rtde does
not look at). Unknown commands get ``could not understand: '<line>'``.
"""

from __future__ import annotations

from urident.simcontroller.robot_state import (
    ROBOT_MODE_NAMES,
    RUNTIME_PLAYING,
    SAFETY_MODE_NAMES,
)

WELCOME = "Connected: Universal Robots Dashboard Server"
REQUEST_TIMEOUT_S = 1.0


def serial_number(spec) -> str:
    """A plausible serial for the emulated arm: year, model number, generation digit (3 CB3,
    5 e-Series), sequence; a UR5e is 20235500001, a CB3 UR3 20163300001."""
    digits = "".join(ch for ch in spec.dashboard_model if ch.isdigit()) or "0"
    year, generation = ("2016", "3") if spec.generation == "cb3" else ("2023", "5")
    return f"{year}{digits}{generation}00001"


class DashboardSession:
    """Replies for one dashboard connection; state changes run on the controller thread."""

    def __init__(self, controller):
        self.c = controller

    def _on_controller(self, fn, *args):
        return self.c.call_soon(fn, *args).result(timeout=REQUEST_TIMEOUT_S)

    def polyscope_version(self) -> str:
        major, minor, bugfix, build = self.c.version
        return f"URSoftware {major}.{minor}.{bugfix}.{build} (Jan 01 2024)"

    def handle(self, line: str) -> str | None:
        """Reply to one command line; ``None`` means: answer ``Disconnected`` and close (``quit``)."""
        text = line.strip()
        cmd = text.lower()
        c = self.c
        running = c.script.runtime_state == RUNTIME_PLAYING
        if cmd == "polyscopeversion":
            return self.polyscope_version()
        if cmd == "version":
            return self.polyscope_version()
        if cmd == "get serial number":
            return c.config.serial_number or serial_number(c.spec)
        if cmd == "get robot model":
            return c.spec.dashboard_model
        if cmd == "is in remote control":
            return "false" if c.faults.no_remote else "true"
        if cmd == "stop":
            self._on_controller(c.stop_program, "dashboard stop")
            return "Stopped"
        if cmd == "play":
            return "Starting program" if self._on_controller(c.play) else "Failed to execute: play"
        if cmd == "pause":
            return "Pausing program" if running else "Failed to execute: pause"
        if cmd == "running":
            return f"Program running: {'true' if running else 'false'}"
        if cmd == "programstate":
            return f"{'PLAYING' if running else 'STOPPED'} <unnamed>"
        if cmd == "robotmode":
            return f"Robotmode: {ROBOT_MODE_NAMES.get(c.robot_mode, 'UNKNOWN')}"
        if cmd == "safetymode":
            return f"Safetymode: {SAFETY_MODE_NAMES.get(c.safety_mode, 'UNKNOWN')}"
        if cmd == "safetystatus":
            return f"Safetystatus: {SAFETY_MODE_NAMES.get(c.safety_mode, 'UNKNOWN')}"
        if cmd == "unlock protective stop":
            if self._on_controller(c.unlock_protective_stop):
                return "Protective stop releasing"
            return "Cannot unlock protective stop until 5s after occurrence. Always inspect cause of protective stop before unlocking"
        if cmd == "close safety popup":
            return "closing safety popup"
        if cmd == "restart safety":
            self._on_controller(c.restart_safety)
            return "Restarting safety"
        if cmd == "power on":
            self._on_controller(c.power_on)
            return "Powering on"
        if cmd == "power off":
            self._on_controller(c.power_off)
            return "Powering off"
        if cmd == "brake release":
            self._on_controller(c.brake_release)
            return "Brake releasing"
        if cmd == "get loaded program":
            return "No program loaded"
        if cmd == "isprogramsaved":
            return "true <unnamed>"
        if cmd.startswith("load "):
            return f"File not found: {text[5:]}"
        if cmd.startswith("popup "):
            return "showing popup"
        if cmd == "close popup":
            return "closing popup"
        if cmd.startswith("addtolog "):
            return "Added log message"
        if cmd.startswith("setuserrole "):
            return f"Setting user role: {text[12:]}"
        if cmd == "get operational mode":
            return "NONE"
        if cmd == "shutdown":
            return "Shutting down"
        if cmd == "quit":
            return None
        return f"could not understand: '{text}'"
