"""Emulation of ur_rtde's control script (the URScript program ur_rtde 1.6.5 uploads to port 30003).

We do not interpret URScript. We recognise ur_rtde's program (it defines ``rtde_cmd`` and
``signal_ready``), read its register offsets (``reg_offset_int``/``reg_offset_float``: 0, or 24 with
ur_rtde's upper-range flag) and reproduce its main loop, one iteration per controller cycle:

* output_int_register[0] = 1 (ready) after start, 2 when a non-real-time command is done;
* command id in input_int_register[0]; arguments in input_double_register[0..] and
  input_int_register[1..];
* real-time commands (servoJ 11, speedJ 9, speedL 10, servoL 24, forceMode 6, toolContact 25,
  getStepTime 26, getActualJointPositionsHistory 27, getJointTorques 38, getActualToolFlangePose
  58, 66-71) are processed every cycle and leave the register at 1;
* any other command runs once; blocking ones (moveJ, stopJ, servoStop, speedStop, ...) keep the
  loop busy until the motion is at rest; then the register goes to 2 until the client clears the
  command (0), which sets it back to 1;
* 255 (stopScript) ends the program: runtime_state goes from 2 (PLAYING) to 1 (STOPPED).

As in the real script, servoJ and speedJ start a thread that keeps the robot servoing until
servoStop / speedStop. A moveJ (or stopJ) while that thread runs is a URScript runtime error
("another thread is already controlling the robot"): the program stops.

Programs other than ur_rtde's control script are accepted and "run" for ``OTHER_PROGRAM_S``.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass

import numpy as np

from urident.simcontroller.robot_state import RUNTIME_PLAYING, RUNTIME_STOPPED

READY = 1
DONE = 2
STOP_SCRIPT = 255
REALTIME_COMMANDS = frozenset({24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71})
MOTION_COMMANDS = frozenset({1, 2, 3, 4, 6, 9, 10, 11, 12, 24, 41, 45, 51})
COMMAND_NAMES = {
    0: "no_cmd", 1: "moveJ", 2: "moveJ_IK", 3: "moveL", 4: "moveL_FK", 6: "forceMode",
    7: "forceModeStop", 8: "zeroFtSensor", 9: "speedJ", 10: "speedL", 11: "servoJ", 12: "servoC",
    15: "speedStop", 16: "servoStop", 17: "setPayload", 18: "teachMode", 19: "endTeachMode",
    24: "servoL", 26: "getStepTime", 28: "getTargetWaypoint", 29: "setTcp", 31: "triggerProtectiveStop",
    33: "stopL", 34: "stopJ", 35: "setWatchdog", 36: "isPoseWithinSafetyLimits",
    37: "isJointsWithinSafetyLimits", 38: "getJointTorques", 40: "getTCPOffset",
    43: "getForwardKinematics", 44: "getForwardKinematics", 47: "isSteady",
    58: "getActualToolFlangePose", 65: "setTargetPayload", 255: "stopScript",
}
PROGRAM_START_DELAY_S = 0.05
OTHER_PROGRAM_S = 0.1


@dataclass(frozen=True)
class Program:
    text: str
    is_rtde_control: bool
    int_offset: int = 0
    float_offset: int = 0


def parse_program(text: str) -> Program:
    is_control = "rtde_cmd" in text and "signal_ready" in text
    int_offset = float_offset = 0
    m = re.search(r"reg_offset_int\s*=\s*(\d+)", text)
    if m:
        int_offset = int(m.group(1))
    m = re.search(r"reg_offset_float\s*=\s*(\d+)", text)
    if m:
        float_offset = int(m.group(1))
    return Program(text=text, is_rtde_control=is_control, int_offset=int_offset, float_offset=float_offset)


_NUM = r"\s*(-?[0-9.eE+-]+)\s*"
_LIST3 = r"\[" + ",".join([_NUM] * 3) + r"\]"
_LIST6 = r"\[" + ",".join([_NUM] * 6) + r"\]"
_PAYLOAD_CALL = re.compile(r"\b(set_target_payload|set_payload)\s*\(" + _NUM + r",\s*" + _LIST3
                           + r"(?:\s*,\s*" + _LIST6 + r")?[^)]*\)")


def declared_payloads(text: str) -> list[tuple[float, list[float], list[float]]]:
    """(mass, cog, [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]) of each ``set_target_payload`` /
    ``set_payload`` call with literal numbers in a program, in order."""
    out = []
    for m in _PAYLOAD_CALL.finditer(text):
        try:
            values = [float(v) for v in m.groups()[1:] if v is not None]
        except ValueError:
            continue
        out.append((values[0], values[1:4], values[4:10] if len(values) == 10 else [0.0] * 6))
    return out


class ScriptStream:
    """Cuts the bytes received on a script port into complete programs.

    A program starts with a top-level ``def NAME():`` or ``sec NAME():`` line and ends with the next
    top-level ``end`` line; any other top-level line is a one-line program.
    """

    def __init__(self) -> None:
        self._pending = ""
        self._lines: list[str] = []
        self._in_program = False

    def feed(self, data: bytes) -> list[str]:
        self._pending += data.decode("utf-8", errors="replace")
        programs = []
        while "\n" in self._pending:
            line, self._pending = self._pending.split("\n", 1)
            stripped = line.rstrip("\r")
            top_level = stripped[:1] not in (" ", "\t")
            if not self._in_program:
                if not stripped.strip() or stripped.lstrip().startswith("#"):
                    continue
                if re.match(r"^(def|sec)\s+\w+\s*\(.*\)\s*:", stripped):
                    self._in_program = True
                    self._lines = [stripped]
                else:
                    programs.append(stripped)
                continue
            self._lines.append(stripped)
            if top_level and stripped.strip() == "end":
                programs.append("\n".join(self._lines) + "\n")
                self._lines = []
                self._in_program = False
        return programs


class ScriptEmulator:
    """Runs (emulates) the current program; :meth:`tick` is one script-loop iteration."""

    def __init__(self, controller):
        self.c = controller
        self.runtime_state = RUNTIME_STOPPED
        self.program: Program | None = None
        self.last_program: Program | None = None
        self._start_at: float | None = None
        self._other_end_at = 0.0
        self._executing = False
        self._blocking: str | None = None
        self._servo_thread = False
        self._speed_thread = False
        self._async_move = False
        self._async_write_count = 0
        self._async_op_id = 0
        self._warned: set[int] = set()
        self.commands_seen: dict[int, int] = {}
        self.verbose = False

    # ------------------------------------------------------------ program life cycle
    def load(self, program: Program) -> None:
        """A program arrived on a script port: it replaces the running one after a short delay."""
        if self.runtime_state == RUNTIME_PLAYING:
            self.stop_program("replaced by a new program")
        self.program = program
        self.last_program = program
        self._start_at = self.c.time_s + PROGRAM_START_DELAY_S

    def stop_program(self, reason: str) -> None:
        if self.runtime_state == RUNTIME_PLAYING or self._start_at is not None:
            self.c.log(f"program stopped: {reason}")
        self._start_at = None
        self.runtime_state = RUNTIME_STOPPED
        self._servo_thread = self._speed_thread = self._async_move = False
        self._blocking = None
        self._executing = False
        self.c.plant.stop(None)

    def _start(self) -> None:
        self._start_at = None
        self.runtime_state = RUNTIME_PLAYING
        self._executing = False
        self._blocking = None
        self._servo_thread = self._speed_thread = self._async_move = False
        declared = declared_payloads(self.program.text)
        if declared:   # a program's payload lines take effect when it starts
            mass, cog, inertia = declared[-1]
            c = self.c
            c.payload_mass, c.payload_cog, c.payload_inertia = mass, cog, inertia
            c.plant.declare_payload(mass, cog, inertia)
        if self.program.is_rtde_control:
            self._write_async_progress(-1)
            self._signal(READY)
        else:
            self._other_end_at = self.c.time_s + OTHER_PROGRAM_S

    # ------------------------------------------------------------ registers
    def _in_int(self, k: int) -> int:
        return self.c.registers.input_int[self.program.int_offset + k]

    def _in_double(self, k: int) -> float:
        return self.c.registers.input_double[self.program.float_offset + k]

    def _in_doubles(self, k: int, n: int) -> np.ndarray:
        base = self.program.float_offset + k
        return np.array(self.c.registers.input_double[base:base + n])

    def _out_int(self, k: int, value: int) -> None:
        self.c.registers.output_int[self.program.int_offset + k] = int(value)

    def _out_doubles(self, k: int, values) -> None:
        base = self.program.float_offset + k
        for j, v in enumerate(values):
            self.c.registers.output_double[base + j] = float(v)

    def _signal(self, value: int) -> None:
        self._out_int(0, value)

    def _write_async_progress(self, value: int) -> None:
        """ur_rtde's async progress register (output int 2): change count, operation id, progress."""
        self._async_write_count = (self._async_write_count + 1) % 128
        if value == 0:
            self._async_op_id = (self._async_op_id + 1) % 128
        reg = self._async_write_count * 65536 + self._async_op_id * 16777216
        if value >= 0:
            reg += min(value, 32767) + 32768
        self._out_int(2, reg)

    # ------------------------------------------------------------ main loop
    def tick(self) -> None:
        if self._start_at is not None and self.c.time_s >= self._start_at:
            self._start()
        if self.runtime_state != RUNTIME_PLAYING:
            return
        if not self.program.is_rtde_control:
            if self.c.time_s >= self._other_end_at:
                self.stop_program("program finished")
            return
        plant = self.c.plant
        if self._async_move and plant.mode != "move":
            self._async_move = False
            self._write_async_progress(-1)
        with self.c.registers.lock:
            if self._blocking is not None:
                if plant.is_moving:
                    return
                self._blocking = None
                self._signal(DONE)
                return
            cmd = self._in_int(0)
            if cmd in REALTIME_COMMANDS:
                self._process(cmd)
                if self.runtime_state == RUNTIME_PLAYING:
                    self._signal(READY)
            elif cmd == 0:
                self._executing = False
                self._signal(READY)
            elif not self._executing:
                self._executing = True
                keep_running = self._process(cmd)
                if not keep_running:
                    self.stop_program("stopScript received")
                elif self._blocking is None and self.runtime_state == RUNTIME_PLAYING:
                    self._signal(DONE)

    def _conflict(self, name: str) -> bool:
        if self._servo_thread or self._speed_thread:
            thread = "servo" if self._servo_thread else "speed"
            self.c.log(f"runtime error: {name} while the {thread} thread controls the robot "
                       "(another thread is already controlling the robot); call servoStop/speedStop first")
            self.stop_program("URScript runtime error")
            return True
        return False

    def _process(self, cmd: int) -> bool:
        """One process_cmd call; returns False for stopScript."""
        c, plant = self.c, self.c.plant
        if self.verbose and cmd not in self.commands_seen:
            self.c.log(f"first command {cmd} ({COMMAND_NAMES.get(cmd, 'unknown')})")
        self.commands_seen[cmd] = self.commands_seen.get(cmd, 0) + 1
        if cmd in MOTION_COMMANDS:
            c.note_motion()
        if cmd == 1:                                              # moveJ
            q = self._in_doubles(0, 6)
            speed, acceleration = self._in_double(6), self._in_double(7)
            if self._conflict("movej"):
                return True
            plant.move_joints(q, speed, acceleration)
            if self._in_int(1) == 1:
                self._async_move = True
                self._write_async_progress(0)
            else:
                self._blocking = "movej"
        elif cmd == 11:                                           # servoJ
            plant.servo(self._in_doubles(0, 6), self._in_double(9), self._in_double(10))
            self._servo_thread = True
        elif cmd == 9:                                            # speedJ
            plant.speed_joints(self._in_doubles(0, 6), self._in_double(6))
            self._speed_thread = True
        elif cmd in (15, 16):                                     # speedStop / servoStop
            if cmd == 15:
                self._speed_thread = False
            else:
                self._servo_thread = False
            plant.stop(max(self._in_double(0), 1e-3))
            self._blocking = "stop"
        elif cmd in (33, 34):                                     # stopL / stopJ
            if self._conflict("stopj" if cmd == 34 else "stopl"):
                return True
            plant.stop(max(self._in_double(0), 1e-3))
            self._async_move = False
            if self._in_int(1) != 1:
                self._blocking = "stop"
        elif cmd == 17:                                           # setPayload
            c.payload_mass = self._in_double(0)
            c.payload_cog = list(self._in_doubles(1, 3))
            c.payload_inertia = [0.0] * 6
            plant.declare_payload(c.payload_mass, c.payload_cog)
        elif cmd == 65:                                           # setTargetPayload
            c.payload_mass = self._in_double(0)
            c.payload_cog = list(self._in_doubles(1, 3))
            c.payload_inertia = list(self._in_doubles(4, 6))
            plant.declare_payload(c.payload_mass, c.payload_cog, c.payload_inertia)
        elif cmd == 26:                                           # getStepTime
            self._out_doubles(0, [c.dt])
        elif cmd == 28:                                           # getTargetWaypoint
            self._out_doubles(0, c.kinematics.tcp(plant.q, plant.qd, c.tcp_offset)[0])
        elif cmd == 29:                                           # setTcp
            c.tcp_offset = list(self._in_doubles(0, 6))
        elif cmd == 31:                                           # triggerProtectiveStop
            c.protective_stop("protective_stop() called by the script")
        elif cmd == 37:                                           # isJointsWithinSafetyLimits
            q = self._in_doubles(0, 6)
            ok = bool(np.all(q >= plant.q_min) and np.all(q <= plant.q_max))
            self._out_int(1, 1 if ok else 0)
        elif cmd == 36:                                           # isPoseWithinSafetyLimits
            self._out_int(1, 1)
        elif cmd == 38:                                           # getJointTorques
            self._out_doubles(0, plant.measured_current * plant.drive_gains - plant.tau_model)
        elif cmd == 40:                                           # getTCPOffset
            self._out_doubles(0, c.tcp_offset)
        elif cmd == 43:                                           # getForwardKinematics()
            self._out_doubles(0, c.kinematics.tcp(plant.q, plant.qd, c.tcp_offset)[0])
        elif cmd == 44:                                           # getForwardKinematics(q, tcp)
            q = self._in_doubles(0, 6)
            self._out_doubles(0, c.kinematics.tcp(q, np.zeros(6), list(self._in_doubles(6, 6)))[0])
        elif cmd == 47:                                           # isSteady
            self._out_int(1, 1 if not plant.is_moving and np.all(np.abs(plant.qd) < 1e-4) else 0)
        elif cmd == 58:                                           # getActualToolFlangePose
            self._out_doubles(0, c.kinematics.tcp(plant.q, plant.qd, None)[0])
        elif cmd == STOP_SCRIPT:
            return False
        elif cmd not in (35, 8, 18, 19, 20, 21, 7) and cmd not in self._warned:
            self._warned.add(cmd)
            print(f"sim-controller: command {cmd} ({COMMAND_NAMES.get(cmd, 'unknown')}) is not emulated; "
                  "acknowledged without effect", file=sys.stderr, flush=True)
        return True
