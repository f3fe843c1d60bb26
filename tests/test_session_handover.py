"""Runs back to back on one controller: a run's safety net stops only its own program.

After a session process ended, its recorder's watcher checks that the program stays stopped (ur_rtde
can re-upload its script until its process ends) and stops it when PLAYING. The next run waits for
that watch to end (urident.session.handover), so the watch never mistakes the next run's program
for a re-upload of its own. Each run below approaches its start slowly, so that its program plays
for seconds: inside the watch window of the run before it, had it not waited.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from test_session_sim import RELAXED, START
from urident.errors import SafetyError
from urident.excitation import FourierTrajectory, Limits, trajectory_document, write_trajectory
from urident.excitation.fourier import base_frequency
from urident.logs import load_log
from urident.model import load_robot
from urident.session import handover
from urident.simcontroller.process import SimControllerProcess

SHIFT = np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.0])  # the second trajectory's start, from the first's


def _trajectory(path, start) -> str:
    free = np.random.default_rng(3).normal(scale=0.08, size=(6, 4))
    traj = FourierTrajectory.from_free(free, base_frequency(1.5), np.asarray(start), 1.5)
    write_trajectory(path, trajectory_document("ur5e", traj, Limits.from_robot(load_robot("ur5e"))))
    return str(path)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("handover")
    config = d / "slow.yaml"
    # 0.25 rad/s over 0.6 rad: each second run approaches for about 3.5 s, longer than the
    # previous run's watch (its settle time is 2 s), so that its program plays inside it.
    config.write_text(RELAXED + "approach:\n  speed_rad_s: 0.25\n  max_distance_rad: 1.5\n")
    return {"a": _trajectory(d / "a.yaml", START), "b": _trajectory(d / "b.yaml", START + SHIFT),
            "config": config, "dir": d}


def _cli(host, trajectory, out, config) -> list[str]:
    return ["run", "--robot", "ur5e", "--host", host, "--trajectory", str(trajectory), "--out",
            str(out), "--config", str(config), "--yes"]


def _completed_and_clean(out) -> None:
    log = load_log(out)
    assert log.status == "completed", log.metadata.get("abort_reason")
    # the watcher of this run found the program stopped: nothing of another run was touched
    notes = [n for n in log.metadata["extra"]["stop_problems"] if "after the session exited" in n]
    assert notes == [], notes


def test_two_runs_in_one_process_back_to_back(files, capsys):
    """As `urident demo` and a notebook calling the run API twice do."""
    from urident.cli.main import main

    host = "127.0.0.83"
    outs = [files["dir"] / "one_a.csv", files["dir"] / "one_b.csv"]
    with SimControllerProcess(host=host, robot="ur5e", initial_q=START + SHIFT):
        assert main(_cli(host, files["a"], outs[0], files["config"])) == 0
        assert main(_cli(host, files["b"], outs[1], files["config"])) == 0
    for out in outs:
        _completed_and_clean(out)
    assert capsys.readouterr().out.count("completed:") == 2


def test_two_run_processes_back_to_back(files):
    """Two `urident run` processes with no pause between them, as a shell script runs them."""
    host = "127.0.0.84"
    outs = [files["dir"] / "two_a.csv", files["dir"] / "two_b.csv"]
    urident = [sys.executable, "-m", "urident.cli.main"]
    script = " && ".join(" ".join([*urident, *_cli(host, files[k], out, files["config"])])
                         for k, out in zip("ab", outs))
    with SimControllerProcess(host=host, robot="ur5e", initial_q=START + SHIFT):
        r = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=180,
                           stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("completed:") == 2
    for out in outs:
        _completed_and_clean(out)


def test_a_watch_under_way_never_stops_the_next_runs_program(files, tmp_path):
    """The race itself, made certain: a previous run's watcher (holding the watch lock as a
    recorder's does) whose session process ends only once the next run is under way. Without the
    hand-over the next run would be moving when the watcher looks, and be stopped; with it the run
    waits for the watch to end, then completes, and the watcher stopped nothing."""
    import shutil

    from test_logs_gaps import SAMPLES
    from urident.logs import read_sidecar, sidecar_path

    host = "127.0.0.86"
    watched = tmp_path / "previous.csv"
    shutil.copy(SAMPLES / "sample_ident.csv", watched)
    shutil.copy(SAMPLES / "sample_ident.yaml", tmp_path / "previous.yaml")
    session = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    code = ("import sys, urident.session.handover as h, urident.session.recorder as r; "
            "fd = h.hold_watch(sys.argv[1]); print('held' if fd is not None else 'none', flush=True); "
            "r._watch_program(sys.argv[1], int(sys.argv[2]), sys.argv[3], False, h.generation(sys.argv[1]))")
    out = files["dir"] / "after_watch.csv"
    with SimControllerProcess(host=host, robot="ur5e", initial_q=START):
        watcher = subprocess.Popen([sys.executable, "-c", code, host, str(session.pid), str(watched)],
                                   stdout=subprocess.PIPE, text=True)
        assert watcher.stdout.readline().strip() == "held"
        run = subprocess.Popen([sys.executable, "-m", "urident.cli.main",
                                *_cli(host, files["b"], out, files["config"])],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               stdin=subprocess.DEVNULL)
        lines = []
        for line in run.stdout:
            lines.append(line)
            if "waiting for the previous run" in line or "moving to the start" in line:
                session.kill()  # the previous session process ends now: its watcher looks
                session.wait()
        run.wait(timeout=120)
        watcher.wait(timeout=30)
    assert run.returncode == 0, "".join(lines) + run.stderr.read()
    _completed_and_clean(out)
    assert not (read_sidecar(sidecar_path(watched)).get("extra") or {}).get("stop_problems")


def test_a_refused_move_says_what_the_controller_reported():
    """ur_rtde refuses moveJ when the program was stopped under it: the message gives the
    controller's own state at that moment, not only the refusal."""
    from sim_helpers import dashboard
    from urident.errors import SessionAborted
    from urident.session.config import load_experiment_config
    from urident.session.rtde_io import RobotLink
    from urident.session.runner import _approach

    host = "127.0.0.87"
    with SimControllerProcess(host=host, robot="ur5e", extra_args=["--no-realtime"]):
        link = RobotLink(host)
        try:
            link.connect_receive()
            link.connect_control(500.0)
            assert "program PLAYING" in link.controller_report()
            dashboard(host, "stop")
            time.sleep(0.2)
            with pytest.raises(SessionAborted) as refused:
                _approach(link, np.asarray(START) + SHIFT, load_experiment_config(None), None)
        finally:
            link.close()
    message = str(refused.value)
    assert message.startswith("moveJ to the trajectory start was rejected by the controller "
                              "(controller reported: program STOPPED"), message
    for part in ("runtime state stopped (1)", "robot mode running (7)", "safety mode normal (1)",
                 "no safety stop bit set", "no async operation running", "nothing moved"):
        assert part in message, message


# ---------------------------------------------------------------------------- the locks alone
@pytest.fixture
def locks(tmp_path, monkeypatch):
    monkeypatch.setattr(handover, "lock_dir", lambda: tmp_path)
    return tmp_path


def _hold_watch_in_child(host: str, seconds: float) -> subprocess.Popen:
    """A recorder's watcher stand-in: another process holding the watch lock shared."""
    code = (f"import time, urident.session.handover as h; h.lock_dir = lambda: __import__('pathlib')"
            f".Path({str(handover.lock_dir())!r}); fd = h.hold_watch({host!r}); "
            f"print('held' if fd is not None else 'none', flush=True); time.sleep({seconds})")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_run_waits_for_the_previous_watch_and_says_so(locks):
    host = "127.0.0.85"
    watcher = _hold_watch_in_child(host, 1.2)
    said: list[str] = []
    start = time.monotonic()
    with handover.controller_turn(host, said.append):
        waited = time.monotonic() - start
        assert watcher.poll() is not None  # the watch had ended before the run went on
    watcher.wait()
    assert waited > 0.8
    assert said and "waiting for the previous run's stop check" in said[0]


def test_a_second_run_on_the_same_controller_is_refused(locks, monkeypatch):
    monkeypatch.setattr(handover, "RUN_WAIT_S", 0.3)
    host = "127.0.0.85"
    with handover.controller_turn(host):
        result: list[BaseException] = []

        def second():
            try:
                with handover.controller_turn(host):
                    pass
            except SafetyError as exc:
                result.append(exc)

        thread = threading.Thread(target=second)
        thread.start()
        thread.join(5)
    assert result and "another urident run is using the controller at 127.0.0.85" in str(result[0])
    assert f"process {os.getpid()}" in str(result[0]) and "nothing moved" in str(result[0])
    with handover.controller_turn(host):  # free again once the first ended
        pass


def test_a_watch_stuck_past_its_limit_refuses_the_run(locks, monkeypatch):
    monkeypatch.setattr(handover, "WATCH_WAIT_S", 0.3)
    host = "127.0.0.85"
    watcher = _hold_watch_in_child(host, 3.0)
    try:
        with pytest.raises(SafetyError, match="did not end within 0.3 s: nothing moved"):
            with handover.controller_turn(host):
                pass
    finally:
        watcher.kill()
        watcher.wait()


def test_the_next_run_announcing_itself_ends_a_watch_whose_session_lives_on(locks, tmp_path):
    """A session run in the caller's own process (the API with a link): its watcher waits for a
    process that does not end; the caller's next run announces itself and the watch ends at once,
    stopping nothing."""
    from urident.session.recorder import _watch_program

    host = "127.0.0.85"
    since = handover.generation(host)
    thread = threading.Thread(target=_watch_program,
                              args=(host, os.getpid(), str(tmp_path / "x.csv"), False, since))
    thread.start()
    time.sleep(0.2)
    assert thread.is_alive()  # waiting for its (living) session process
    start = time.monotonic()
    with handover.controller_turn(host):
        thread.join(2.0)
        assert not thread.is_alive()
    assert time.monotonic() - start < 2.0
    assert handover.generation(host) == since + 1
    assert np.isfinite(since)
