"""The simulated controller's state machine: one :meth:`Controller.tick` per control cycle.

The controller owns the plant, the registers, the script emulator, the safety state and the fault
schedule. Everything here runs on the controller thread; other threads (connections, dashboard)
hand work over with :meth:`Controller.call_soon` or write input registers with
:meth:`Controller.apply_inputs`.
"""

from __future__ import annotations

import queue
import sys
import threading
from concurrent.futures import Future
from dataclasses import dataclass, field

import numpy as np

from urident.errors import ConfigError
from urident.simcontroller.faults import Fault, FaultSchedule
from urident.simcontroller.kinematics import Kinematics
from urident.simcontroller.plant import Plant
from urident.simcontroller.robot_state import (
    ROBOT_MODE_IDLE,
    ROBOT_MODE_POWER_OFF,
    ROBOT_MODE_RUNNING,
    SAFETY_BIT_EMERGENCY_STOPPED,
    SAFETY_BIT_NORMAL,
    SAFETY_BIT_PROTECTIVE_STOPPED,
    SAFETY_BIT_ROBOT_EMERGENCY_STOPPED,
    SAFETY_BIT_STOPPED_DUE_TO_SAFETY,
    SAFETY_MODE_NORMAL,
    SAFETY_MODE_PROTECTIVE_STOP,
    SAFETY_MODE_ROBOT_EMERGENCY_STOP,
    IOState,
    Registers,
)
from urident.simcontroller.script_emulator import ScriptEmulator, parse_program

DEFAULT_BUILD = {3: 106331, 5: 108249}


def parse_version(text: str) -> tuple[int, int, int, int]:
    """``5.11.0`` or ``5.11.0.108249`` or ``3.15`` → (major, minor, bugfix, build)."""
    try:
        parts = [int(p) for p in str(text).strip().split(".")]
    except ValueError:
        raise ConfigError(f"--version '{text}': expected MAJOR.MINOR[.BUGFIX[.BUILD]], e.g. 5.11.0") from None
    if not 2 <= len(parts) <= 4 or any(p < 0 for p in parts):
        raise ConfigError(f"--version '{text}': expected MAJOR.MINOR[.BUGFIX[.BUILD]], e.g. 5.11.0")
    while len(parts) < 3:
        parts.append(0)
    if len(parts) == 3:
        parts.append(DEFAULT_BUILD.get(parts[0], 100000))
    if parts[0] not in (3, 5):
        raise ConfigError(f"--version '{text}': only CB3 (3.x) and e-Series (5.x) controllers are simulated")
    return tuple(parts)  # type: ignore[return-value]


def rate_for_version(version: tuple[int, ...]) -> float:
    """Control rate [Hz]: 125 for CB3 (3.x), 500 for e-Series (5.x)."""
    return 125.0 if version[0] <= 3 else 500.0


def load_effects(path: str, spec, rng: np.random.Generator):
    """The unmodelled effects of an effects file or preset name (``realistic``); the returned
    object provides the plant hooks ``extra_torque`` / ``measure_current``."""
    from urident.simcontroller.effects import load_effects as load

    return load(path, spec=spec, rng=rng)


def make_torque_model(spec):
    """The robot's single-sample torque model with its nominal parameters."""
    from urident.model.pinocchio_model import TorqueModel

    return TorqueModel(spec)


@dataclass
class ControllerConfig:
    spec: object
    version: tuple[int, int, int, int]
    faults: list[Fault] = field(default_factory=list)
    seed: int = 0
    effects_path: str | None = None
    initial_q: list[float] | None = None
    serial_number: str | None = None   # None: one that matches the robot (dashboard.serial_number)


class Controller:
    def __init__(self, config: ControllerConfig, torque_model=None, effects=None):
        self.config = config
        self.spec = config.spec
        self.version = config.version
        self.rate_hz = rate_for_version(config.version)
        self.dt = 1.0 / self.rate_hz
        plant_seed, effects_seed = np.random.SeedSequence(config.seed).spawn(2)
        if effects is None and config.effects_path:
            effects = load_effects(config.effects_path, self.spec, np.random.default_rng(effects_seed))
        self.plant = Plant(self.spec, torque_model if torque_model is not None else make_torque_model(self.spec),
                           self.rate_hz, np.random.default_rng(plant_seed), effects=effects,
                           initial_q=config.initial_q)
        self.kinematics = Kinematics.from_spec(self.spec)
        self.registers = Registers()
        self.io = IOState()
        self.script = ScriptEmulator(self)
        self.faults = FaultSchedule(config.faults)
        self.tick_count = 0
        self.time_s = 0.0
        self.motion_start_s: float | None = None
        self.frozen_timestamp: float | None = None
        self.last_execution_time_s = 0.0
        self.robot_mode = ROBOT_MODE_RUNNING
        self.safety_mode = SAFETY_MODE_NORMAL
        self.safety_status_bits = SAFETY_BIT_NORMAL
        self.tcp_offset = [0.0] * 6
        self.payload_mass = 0.0
        self.payload_cog = [0.0] * 3
        self.payload_inertia = [0.0] * 6
        self.drop_requested = False          # read and cleared by the server
        self._requests: "queue.SimpleQueue[tuple]" = queue.SimpleQueue()
        self._log_lock = threading.Lock()

    # ------------------------------------------------------------ cross-thread entry points
    def call_soon(self, fn, *args) -> Future:
        """Run ``fn(*args)`` on the controller thread at the start of the next cycle."""
        future: Future = Future()
        self._requests.put((future, fn, args))
        return future

    def apply_inputs(self, values: dict) -> None:
        """Write one RTDE input package (name → value) into the registers and I/O state."""
        regs = self.registers
        with regs.lock:
            io_values = None
            for name, value in values.items():
                if name.startswith("input_int_register_"):
                    regs.input_int[int(name[19:])] = int(value)
                elif name.startswith("input_double_register_"):
                    regs.input_double[int(name[22:])] = float(value)
                elif name.startswith("input_bit_register_"):
                    bit = int(name[19:])
                    regs.input_bits = (regs.input_bits & ~(1 << bit)) | (int(bool(value)) << bit)
                elif name == "input_bit_registers0_to_31":
                    regs.input_bits = (regs.input_bits & ~0xFFFFFFFF) | int(value)
                elif name == "input_bit_registers32_to_63":
                    regs.input_bits = (regs.input_bits & ~(0xFFFFFFFF << 32)) | (int(value) << 32)
                else:
                    io_values = values
            if io_values is not None:
                self.io.apply(io_values)

    def log(self, message: str) -> None:
        with self._log_lock:
            print(f"sim-controller [{self.time_s:9.3f} s]: {message}", file=sys.stderr, flush=True)

    # ------------------------------------------------------------ the cycle
    @property
    def reported_timestamp(self) -> float:
        return self.frozen_timestamp if self.frozen_timestamp is not None else self.time_s

    def tick(self) -> None:
        self.tick_count += 1
        self.time_s = self.tick_count * self.dt
        while True:
            try:
                future, fn, args = self._requests.get_nowait()
            except queue.Empty:
                break
            if future.set_running_or_notify_cancel():
                try:
                    future.set_result(fn(*args))
                except Exception as exc:  # handed to the waiting thread
                    future.set_exception(exc)
        for fault in self.faults.due(self.time_s, self.motion_start_s):
            self._fire(fault)
        if self.faults.timestamp_frozen(self.time_s, self.motion_start_s):
            if self.frozen_timestamp is None:
                self.frozen_timestamp = self.time_s
        else:
            self.frozen_timestamp = None
        self.script.tick()
        self.plant.step()
        if self.plant.fault_reason:
            reason, self.plant.fault_reason = self.plant.fault_reason, None
            self.protective_stop(reason)

    def sending_paused(self) -> bool:
        return self.faults.sending_paused(self.time_s, self.motion_start_s)

    def note_motion(self) -> None:
        if self.motion_start_s is None:
            self.motion_start_s = self.time_s

    def _fire(self, fault: Fault) -> None:
        self.log(f"fault {fault.spec} fires")
        if fault.kind == "drop":
            self.drop_requested = True
        elif fault.kind == "protective_stop":
            self.protective_stop(f"fault {fault.spec}")
        elif fault.kind == "emergency_stop":
            self.emergency_stop(f"fault {fault.spec}")

    # ------------------------------------------------------------ program / safety actions
    def load_program(self, text: str) -> None:
        program = parse_program(text)
        if self.safety_mode != SAFETY_MODE_NORMAL or self.robot_mode != ROBOT_MODE_RUNNING:
            self.log("program rejected: robot is not in normal running mode")
            return
        kind = "ur_rtde control script" if program.is_rtde_control else "program"
        self.log(f"received {kind} ({len(text)} bytes, register offsets int {program.int_offset} "
                 f"float {program.float_offset})")
        self.script.load(program)

    def stop_program(self, reason: str) -> None:
        self.script.stop_program(reason)

    def play(self) -> bool:
        if self.script.last_program is None or self.safety_mode != SAFETY_MODE_NORMAL:
            return False
        self.script.load(self.script.last_program)
        return True

    def protective_stop(self, reason: str) -> None:
        self.log(f"protective stop: {reason}")
        self.safety_mode = SAFETY_MODE_PROTECTIVE_STOP
        self.safety_status_bits = SAFETY_BIT_PROTECTIVE_STOPPED | SAFETY_BIT_STOPPED_DUE_TO_SAFETY
        self.script.stop_program("protective stop")
        self.plant.stop(None)

    def emergency_stop(self, reason: str) -> None:
        self.log(f"emergency stop: {reason}")
        self.safety_mode = SAFETY_MODE_ROBOT_EMERGENCY_STOP
        self.safety_status_bits = (SAFETY_BIT_ROBOT_EMERGENCY_STOPPED | SAFETY_BIT_EMERGENCY_STOPPED
                                   | SAFETY_BIT_STOPPED_DUE_TO_SAFETY)
        self.script.stop_program("emergency stop")
        self.plant.stop(None)
        self.robot_mode = ROBOT_MODE_POWER_OFF

    def unlock_protective_stop(self) -> bool:
        if self.safety_mode != SAFETY_MODE_PROTECTIVE_STOP:
            return False
        self.safety_mode = SAFETY_MODE_NORMAL
        self.safety_status_bits = SAFETY_BIT_NORMAL
        return True

    def restart_safety(self) -> None:
        self.safety_mode = SAFETY_MODE_NORMAL
        self.safety_status_bits = SAFETY_BIT_NORMAL
        if self.robot_mode == ROBOT_MODE_RUNNING:
            return
        self.robot_mode = ROBOT_MODE_POWER_OFF

    def power_on(self) -> None:
        if self.robot_mode == ROBOT_MODE_POWER_OFF and self.safety_mode == SAFETY_MODE_NORMAL:
            self.robot_mode = ROBOT_MODE_IDLE

    def power_off(self) -> None:
        self.script.stop_program("power off")
        self.robot_mode = ROBOT_MODE_POWER_OFF

    def brake_release(self) -> None:
        if self.robot_mode == ROBOT_MODE_IDLE:
            self.robot_mode = ROBOT_MODE_RUNNING
