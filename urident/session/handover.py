"""One run at a time per controller, and a run's safety net never stops the next run's program.

After a session process exited, its recorder's watcher checks for a while that the controller's
program stays stopped (ur_rtde's reconnect thread can re-upload its control script until the
process that holds it ends), and stops it when it reports PLAYING. Without a hand-over, the next
run's program, started inside that window, looks the same to it. Two advisory file locks per
controller (``flock``: the kernel releases them when their holder dies, however it dies) tell the
two apart:

- the *run lock*, held exclusively by a run from its first word to the controller until it ends;
- the *watch lock*, held shared by a run's recorder from its start and by the watcher it forks,
  until that watcher's check has ended.

A run holding the run lock announces itself, then takes the watch lock exclusively for a moment:
it waits until every earlier run's watcher has finished, so every program a watcher stops is one
its own run left behind. The announcement ends at once the watch of a session that lives on in
the caller's process (the Python API): its next run is this one.
"""

from __future__ import annotations

import fcntl
import os
import socket
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

from urident.errors import SafetyError

RUN_WAIT_S = 5.0       # a run still ending (its supervisor's own stop check) may take this long …
WATCH_WAIT_S = 45.0    # … and the previous run's watcher this long (its parent wait and stop check)
POLL_S = 0.02
SAY_AFTER_S = 0.5      # say why the run waits once it has waited this long


def lock_dir() -> Path:
    """Where the locks live: one folder for every user of this machine."""
    return Path(tempfile.gettempdir()) / "urident-controllers"


def _key(host: str) -> str:
    """One name per controller, whichever way its address is written."""
    try:
        address = socket.gethostbyname(host)
    except OSError:
        address = host
    return "".join(c if c.isalnum() or c in ".-" else "_" for c in address)


def _open(host: str, kind: str) -> int:
    folder = lock_dir()
    if not folder.is_dir():
        folder.mkdir(exist_ok=True)
        try:
            os.chmod(folder, 0o1777)  # every user's runs share it (umask would narrow mkdir's mode)
        except OSError:
            pass
    path = folder / f"{_key(host)}.{kind}"
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        os.fchmod(fd, 0o666)  # another user's run must be able to take it too
    except OSError:
        pass
    return fd


def _lock(fd: int, mode: int, timeout_s: float, waiting: Callable[[], None] | None = None) -> bool:
    deadline = time.monotonic() + timeout_s
    said = False
    start = time.monotonic()
    while True:
        try:
            fcntl.flock(fd, mode | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            pass
        now = time.monotonic()
        if now > deadline:
            return False
        if waiting is not None and not said and now - start > SAY_AFTER_S:
            waiting()
            said = True
        time.sleep(POLL_S)


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
    except OSError:
        return ""
    return f" (process {text})" if text.isdigit() else ""


def generation(host: str) -> int:
    """How many runs have announced themselves to ``host`` (a watcher compares it)."""
    fd = _open(host, "announce")
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    finally:
        os.close(fd)
    return int(text) if text.isdigit() else 0


def _announce(host: str) -> None:
    fd = _open(host, "announce")
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        count = (int(text) if text.isdigit() else 0) + 1
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(count).encode("ascii"), 0)
    finally:
        os.close(fd)


@contextmanager
def controller_turn(host: str, say: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold ``host`` for one run: refuse when another run is using it, wait for the previous
    run's watcher to finish its stop check; raise :class:`SafetyError` (nothing moved) when
    either does not end in time."""
    run_fd = _open(host, "run")
    try:
        if not _lock(run_fd, fcntl.LOCK_EX, RUN_WAIT_S):
            raise SafetyError(f"another urident run is using the controller at {host}"
                              f"{_holder(run_fd)}: nothing moved")
        os.ftruncate(run_fd, 0)
        os.pwrite(run_fd, str(os.getpid()).encode("ascii"), 0)
        _announce(host)
        watch_fd = _open(host, "watch")
        try:
            waited = _lock(watch_fd, fcntl.LOCK_EX, WATCH_WAIT_S, waiting=None if say is None else (
                lambda: say(f"waiting for the previous run's stop check on {host} to end …")))
            if not waited:
                raise SafetyError(f"the previous run's check that its program stays stopped on "
                                  f"{host} did not end within {WATCH_WAIT_S:g} s: nothing moved")
        finally:
            os.close(watch_fd)  # releases it: this run's own recorder takes it shared
        yield
    finally:
        os.close(run_fd)


def hold_watch(host: str, timeout_s: float = RUN_WAIT_S) -> int | None:
    """A shared hold on ``host``'s watch lock for a recorder and the watcher it forks (the
    descriptor is inherited by the fork; the lock lasts while either keeps it open). None when it
    could not be taken (a run that did not pass :func:`controller_turn`, e.g. a test driving
    the recorder alone, holds none)."""
    try:
        fd = _open(host, "watch")
    except OSError:
        return None
    if _lock(fd, fcntl.LOCK_SH, timeout_s):
        return fd
    os.close(fd)
    return None
