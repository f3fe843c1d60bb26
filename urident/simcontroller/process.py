"""Run the simulated controller as a child process (it must not share a process with ur_rtde,
whose Python constructors hold the GIL).

    with SimControllerProcess(host="127.0.0.3", robot="ur5e", faults=["protective_stop@2.5"]) as sim:
        rtde_c = rtde_control.RTDEControlInterface(sim.host)
        ...
    print(sim.stats["late_cycle_pct"])
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections import deque
from pathlib import Path
from typing import Sequence

from urident.errors import UridentError

READY_PREFIX = "listening on "
STATS_PREFIX = "stats "


class SimControllerError(UridentError):
    """The simulated controller process failed to start or died."""


class SimControllerProcess:
    """Context manager around ``python -m urident.simcontroller``.

    ``start()`` (or ``with``) launches it and waits up to ``ready_timeout_s`` for its
    ``listening on HOST`` line; ``stop()`` (or leaving the ``with`` block) sends SIGTERM and waits.
    After stopping, ``stats`` holds the loop statistics the process printed (cycles, late_cycles,
    late_cycle_pct, cpu_pct, ...) and ``log_lines`` its stderr lines (also kept while it runs).
    """

    def __init__(self, host: str = "127.0.0.1", robot: str = "ur5e", *,
                 effects: str | os.PathLike | None = None, faults: Sequence[str] = (),
                 seed: int = 0, version: str | None = None,
                 initial_q: Sequence[float] | None = None, ready_timeout_s: float = 20.0,
                 extra_args: Sequence[str] = (), python: str | None = None,
                 echo_log: bool = False):
        self.host = host
        self.robot = robot
        self.effects = None if effects is None else str(effects)
        self.faults = list(faults)
        self.seed = int(seed)
        self.version = version
        self.initial_q = None if initial_q is None else [float(x) for x in initial_q]
        self.ready_timeout_s = float(ready_timeout_s)
        self.extra_args = list(extra_args)
        self.python = python or sys.executable
        self.echo_log = echo_log
        self.process: subprocess.Popen | None = None
        self.stats: dict | None = None
        self.log_lines: deque[str] = deque(maxlen=2000)
        self.returncode: int | None = None
        self._ready = threading.Event()
        self._listening = False
        self._threads: list[threading.Thread] = []

    # ------------------------------------------------------------ command line
    def command(self) -> list[str]:
        cmd = [self.python, "-m", "urident.simcontroller", "--robot", self.robot, "--host", self.host,
               "--seed", str(self.seed)]
        if self.version:
            cmd += ["--version", self.version]
        if self.effects:
            cmd += ["--effects", self.effects]
        for fault in self.faults:
            cmd += ["--fault", fault]
        if self.initial_q is not None:
            # "=" form: a value starting with "-" would otherwise be read as an option.
            cmd += ["--initial-q=" + ",".join(repr(x) for x in self.initial_q)]
        return cmd + self.extra_args

    @property
    def pid(self) -> int | None:
        return None if self.process is None else self.process.pid

    def is_running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    # ------------------------------------------------------------ life cycle
    def start(self) -> "SimControllerProcess":
        if self.process is not None:
            raise SimControllerError("simulated controller already started")
        env = dict(os.environ)
        package_root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = package_root + os.pathsep + env.get("PYTHONPATH", "")
        env.setdefault("PYTHONUNBUFFERED", "1")
        self.process = subprocess.Popen(self.command(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        stdin=subprocess.DEVNULL, text=True, env=env)
        self._threads = [threading.Thread(target=self._read_stdout, daemon=True),
                         threading.Thread(target=self._read_stderr, daemon=True)]
        for thread in self._threads:
            thread.start()
        if not self._ready.wait(self.ready_timeout_s) or not self._listening or not self.is_running():
            if self.process.poll() is not None:
                for thread in self._threads:
                    thread.join(timeout=2.0)
            detail = self._error_detail()
            self.stop()
            raise SimControllerError(f"simulated controller on {self.host} did not start: {detail}")
        return self

    def stop(self, timeout_s: float = 10.0) -> int | None:
        """SIGTERM, wait (SIGKILL after ``timeout_s``); returns the exit code."""
        process = self.process
        if process is None:
            return None
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self.returncode = process.returncode
        return self.returncode

    def __enter__(self) -> "SimControllerProcess":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------ output
    def _read_stdout(self) -> None:
        assert self.process is not None and self.process.stdout is not None
        for line in self.process.stdout:
            line = line.rstrip("\n")
            if line.startswith(READY_PREFIX):
                self._listening = True
                self._ready.set()
            elif line.startswith(STATS_PREFIX):
                try:
                    self.stats = json.loads(line[len(STATS_PREFIX):])
                except ValueError:
                    pass
        self._ready.set()  # process ended: wake start()

    def _read_stderr(self) -> None:
        assert self.process is not None and self.process.stderr is not None
        for line in self.process.stderr:
            line = line.rstrip("\n")
            self.log_lines.append(line)
            if self.echo_log:
                print(line, file=sys.stderr, flush=True)

    def _error_detail(self) -> str:
        errors = [line for line in self.log_lines if "error" in line.lower()]
        if errors:
            return errors[-1]
        if self.process is not None and self.process.poll() is not None:
            return f"exited with code {self.process.returncode}"
        return f"no '{READY_PREFIX}{self.host}' line within {self.ready_timeout_s:g} s"
