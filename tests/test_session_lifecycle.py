"""Every way a session can end leaves the controller's program stopped, and says why in one line.

Each test drives `urident run` (unmodified ur_rtde client) against urident's simulated controller
on its own loopback address, ends the session one way, then asks the controller itself — its
dashboard over TCP, as an operator tool would — whether the program is stopped, and keeps asking
for a while (ur_rtde's reconnect can re-upload its control script after a stop).

`urident run` supervises a child process, the session, which holds ur_rtde's clients; the
recorder is the session's child. Some tests end `urident run`, some the session process.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from sim_helpers import dashboard, session_child, spawn_run
from test_session_sim import RELAXED, NEAR_START, make_trajectory, one_line_error, run_cli
from urident.logs import load_log, read_sidecar, sidecar_path
from urident.simcontroller.process import SimControllerProcess


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("lifecycle")
    config = d / "relaxed.yaml"
    # A loaded machine starves ur_rtde's receive thread: these tests end runs on purpose.
    config.write_text(RELAXED.replace("rest_s:", "  max_stale_periods: 250\nrest_s:"))
    return {"ur5e": make_trajectory(d / "ur5e.yaml", "ur5e"), "config": config, "dir": d}


def program_states(host: str, watch_s: float = 2.0) -> set[str]:
    """Every ``programState`` the controller reports over ``watch_s`` seconds."""
    seen = set()
    deadline = time.monotonic() + watch_s
    while True:
        seen.add(dashboard(host, "programState")[1].split()[0])
        if time.monotonic() > deadline:
            return seen
        time.sleep(0.05)


def start_run(host, files, out, **popen):
    proc = spawn_run(host, files, out, **popen)
    deadline = time.monotonic() + 60
    line = ""
    while "running" not in line and time.monotonic() < deadline:
        line = proc.stdout.readline()
    assert "running" in line, proc.stderr.read() if proc.poll() is not None else "no servo phase"
    return proc


def playing(host: str) -> bool:
    return dashboard(host, "programState")[1].startswith("PLAYING")


def the_error_line(stderr: str) -> str:
    """`urident run`'s one error line: nothing else (the recorder, the session) adds another."""
    lines = [l for l in stderr.splitlines() if l.startswith("urident: error:")]
    assert len(lines) == 1, stderr
    return one_line_error(stderr)


def every_sample_kept(log) -> bool:
    recorder = log.metadata["extra"]["recorder"]
    return (len(log.t) > 400 and recorder["missed_samples"] == 0
            and bool(np.allclose(np.diff(log.t), 0.002, atol=1e-6)))


@pytest.mark.parametrize("signum, words, host", [
    (signal.SIGTERM, "terminated by SIGTERM", "127.0.0.61"),
    (signal.SIGHUP, "terminated by SIGHUP", "127.0.0.62"),
    (signal.SIGINT, "interrupted by the operator (Ctrl-C)", "127.0.0.63"),
])
def test_signal_during_servo_stops_the_program(files, signum, words, host):
    out = files["dir"] / f"signal_{signum}.csv"
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START):
        proc = start_run(host, files, out)
        time.sleep(1.0)
        assert playing(host)                      # the run is under way
        proc.send_signal(signum)
        _, stderr = proc.communicate(timeout=60)
        states = program_states(host)
    assert proc.returncode == 4, stderr
    line = one_line_error(stderr)
    assert words in line and "robot stopped" in line and "samples kept" in line
    assert states == {"STOPPED"}
    log = load_log(out)
    assert log.status == "aborted" and words in log.metadata["abort_reason"]
    assert len(log.t) > 400 and np.allclose(np.diff(log.t), 0.002, atol=1e-6)


def test_killed_urident_run_lets_the_session_stop_the_robot(files):
    """SIGKILL of `urident run` (as the OOM killer does): no handler runs there. Its child, the
    session process, sees its supervisor gone and stops the robot as SIGTERM would (servoStop,
    stopScript, the program checked on the controller); the log names the death."""
    host = "127.0.0.64"
    out = files["dir"] / "killed.csv"
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START):
        proc = start_run(host, files, out)
        time.sleep(1.0)
        assert playing(host)
        proc.send_signal(signal.SIGKILL)
        _, stderr = proc.communicate(timeout=60)  # once the session closed the inherited pipes too
        deadline = time.monotonic() + 30
        while read_sidecar(sidecar_path(out))["status"] == "running" and time.monotonic() < deadline:
            time.sleep(0.1)
        states = program_states(host)
    assert proc.returncode == -signal.SIGKILL
    log = load_log(out)
    reason = log.metadata["abort_reason"]
    assert log.status == "aborted"
    # the cause is named while the killed process is still a zombie; a reaper as fast as a shell's
    # leaves only the death itself
    assert reason in ("because the urident run process died (killed by signal 9, SIGKILL)",
                      "because the urident run process died"), reason
    line = the_error_line(stderr)  # the session's, on the terminal it shares
    assert line.startswith(f"urident: error: run aborted {reason}; robot stopped; "), line
    assert states == {"STOPPED"}
    assert every_sample_kept(log)


@pytest.mark.parametrize("signum, words, host", [
    (signal.SIGSEGV, "ur_rtde crashed (signal 11, SIGSEGV)", "127.0.0.73"),
    (signal.SIGKILL, "the session process was killed (signal 9, SIGKILL)", "127.0.0.74"),
    (signal.SIGSTOP, "the session process stopped responding for 5 s during the motion", "127.0.0.75"),
])
def test_session_process_crash_or_hang_is_reported_by_urident_run(files, signum, words, host):
    """The session process (ur_rtde's clients) dies mid-servo (a crash, a kill) or hangs:
    `urident run` stops the program through the dashboard, checks it stayed stopped, says so in
    one line and exits 4; the recorder keeps every sample up to its own stop."""
    out = files["dir"] / f"child_{signum}.csv"
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START):
        proc = start_run(host, files, out)
        child = session_child(proc.pid)
        time.sleep(1.0)
        assert playing(host)
        os.kill(child, signum)
        _, stderr = proc.communicate(timeout=120)
        states = program_states(host)
    assert proc.returncode == 4, stderr
    line = the_error_line(stderr)
    assert line.startswith(f"urident: error: run aborted: {words}"), line
    assert "program stopped (checked on the controller)" in line, line
    assert states == {"STOPPED"}
    log = load_log(out)
    reason = log.metadata["abort_reason"]
    assert log.status == "aborted"
    assert reason.startswith("session process died") and "program stopped through the dashboard" in reason
    assert line.endswith(f"; {len(log.t)} samples kept in {out}"), line
    assert every_sample_kept(log)


def test_ctrl_c_on_a_terminal_reaches_the_whole_process_group(files):
    """A terminal's Ctrl-C hits every process of its foreground group: the session still stops
    once, cleanly (servoStop, stopScript), and says so."""
    host = "127.0.0.76"
    out = files["dir"] / "group_sigint.csv"
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START):
        proc = start_run(host, files, out, start_new_session=True)
        time.sleep(1.0)
        assert playing(host)
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
        states = program_states(host)
    assert proc.returncode == 4, stderr
    line = the_error_line(stderr)
    assert "interrupted by the operator (Ctrl-C); robot stopped;" in line, line
    assert states == {"STOPPED"}
    log = load_log(out)
    assert log.status == "aborted" and log.metadata["abort_reason"] == "interrupted by the operator (Ctrl-C)"
    assert every_sample_kept(log)


def test_the_question_is_asked_on_the_terminal(files):
    """Without --yes, `urident run` asks on its terminal before any motion; "y" runs."""
    host = "127.0.0.78"
    out = files["dir"] / "asked.csv"
    master, slave = os.openpty()
    cmd = [sys.executable, "-m", "urident.cli.main", "run", "--robot", "ur5e", "--host", host,
           "--trajectory", str(files["ur5e"]), "--out", str(out), "--config", str(files["config"])]
    try:
        with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START):
            proc = subprocess.Popen(cmd, stdin=slave, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True)
            os.close(slave)
            os.write(master, b"y\n")  # typed ahead: the terminal keeps it until it is read
            stdout, stderr = proc.communicate(timeout=120)
    finally:
        os.close(master)
    assert proc.returncode == 0, stderr
    question = stdout.index("to the trajectory start and run")
    assert "[y/N]" in stdout and stdout.index("moving to the start") > question
    assert "completed:" in stdout and load_log(out).status == "completed"


@pytest.mark.parametrize("attempt", [1, 2])
def test_lost_link_program_stays_stopped(files, attempt):
    """drop@: every connection closes; ur_rtde reconnects on its own and may re-upload its
    script. After the session, the controller reports STOPPED and keeps doing so."""
    host = f"127.0.0.{64 + attempt}"
    out = files["dir"] / f"drop_{attempt}.csv"
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START,
                              faults=[f"drop@{1.5 + attempt}"]):
        r = run_cli(host, "ur5e", files["ur5e"], out, files["config"], "--yes")
        states = program_states(host, watch_s=3.0)
    # ur_rtde's reconnect thread may crash the session process after a lost link (its known
    # race): `urident run`, which supervises it, still stops the run with its own line
    assert r.returncode == 4, r.stdout + r.stderr
    line = the_error_line(r.stderr)
    assert line.startswith("urident: error: run aborted") and "samples kept in" in line, line
    assert "robot stopped" in line or "program stopped (checked on the controller)" in line, line
    assert states == {"STOPPED"}
    log = load_log(out)
    assert log.status == "aborted" and f"{len(log.t)} samples kept" in line
    if "servo_timestamps_s" in log.metadata["extra"]:
        assert log.t[-1] >= log.metadata["extra"]["servo_timestamps_s"][0]
    else:  # the session process died before closing the log: the recorder closed it
        assert "session process died" in log.metadata["abort_reason"]


class _FailingView:
    """A live view whose 200th push raises: an exception in the middle of the servo loop."""

    def __init__(self):
        self.pushes = 0
        self.closed_with = None

    def push(self, sample, q_cmd):
        self.pushes += 1
        if self.pushes == 200:
            raise ValueError("view exploded")

    def close(self, reason):
        self.closed_with = reason


def test_exception_in_the_loop_stops_the_program(files):
    from urident.errors import SessionAborted
    from urident.session import RunRequest, load_experiment_config, run_session

    host = "127.0.0.67"
    out = files["dir"] / "exception.csv"
    view = _FailingView()
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START):
        request = RunRequest(robot="ur5e", host=host, trajectory=files["ur5e"], out=out,
                             config=load_experiment_config(files["config"]), assume_yes=True)
        with pytest.raises(SessionAborted) as info:
            run_session(request, say=lambda _line: None, live=view)
        states = program_states(host)
    message = str(info.value)
    assert "internal error: ValueError: view exploded" in message and "robot stopped" in message
    assert "\n" not in message
    assert states == {"STOPPED"}
    log = load_log(out)
    assert log.status == "aborted" and "view exploded" in log.metadata["abort_reason"]
    assert view.closed_with and "view exploded" in view.closed_with


def test_no_controller_exits_3_and_moves_nothing(files):
    r = run_cli("127.0.0.68", "ur5e", files["ur5e"], files["dir"] / "none.csv", files["config"], "--yes")
    assert r.returncode == 3, r.stderr
    line = one_line_error(r.stderr)
    assert "no controller at 127.0.0.68" in line and "nothing moved" in line
    assert not (files["dir"] / "none.csv").exists()


def test_ensure_stopped_stops_a_program_that_restarts():
    """A program re-started right after the stop (as ur_rtde's reconnect re-uploads its script)
    is stopped again, and the helper reports it."""
    from urident.session.dashboard import ensure_stopped

    host = "127.0.0.69"
    with SimControllerProcess(host=host, robot="ur5e", extra_args=["--no-realtime"]):
        import rtde_control

        control = rtde_control.RTDEControlInterface(host)   # uploads ur_rtde's control script
        assert playing(host)
        restarter = threading.Timer(0.4, lambda: dashboard(host, "play"))  # the script again
        restarter.start()
        notes = ensure_stopped(host, settle_s=1.5, stop_first=True)
        restarter.join()
        states = program_states(host, watch_s=0.5)
        control.disconnect()
    assert notes[0] == "program stopped through the dashboard"
    assert any("PLAYING after the stop: stopped it again" in n for n in notes), notes
    assert states == {"STOPPED"}


def test_watcher_stops_a_program_restarted_after_the_session_ended(tmp_path):
    """What the recorder's watcher does once the session process is gone: a program PLAYING then
    (ur_rtde re-uploaded its script before the process ended) is stopped, and the sidecar says so."""
    import shutil

    from test_logs_gaps import SAMPLES
    from urident.session.recorder import _watch_program

    host = "127.0.0.70"
    out = tmp_path / "watched.csv"
    shutil.copy(SAMPLES / "sample_ident.csv", out)
    shutil.copy(SAMPLES / "sample_ident.yaml", tmp_path / "watched.yaml")
    with SimControllerProcess(host=host, robot="ur5e", extra_args=["--no-realtime"]):
        import rtde_control

        control = rtde_control.RTDEControlInterface(host)   # its control script is PLAYING
        assert playing(host)
        session = subprocess.Popen([sys.executable, "-c", "pass"])  # a session that has ended
        session.wait()
        _watch_program(host, session.pid, str(out))
        states = program_states(host, watch_s=0.5)
        control.disconnect()
    assert states == {"STOPPED"}
    notes = read_sidecar(sidecar_path(out))["extra"]["stop_problems"]
    assert any(n.startswith("after the session exited: controller reported the program PLAYING")
               for n in notes), notes


def test_latency_spike_is_named_late_samples_and_recorded_as_a_gap(files):
    """latency@: the controller sends nothing for 0.2 s, then resumes with advancing timestamps.
    That is not a frozen clock: the run stops on "controller samples late", the log records the
    gap, and identify refuses the log."""
    from urident.cli.main import main

    host = "127.0.0.72"
    out = files["dir"] / "latency.csv"
    config = files["dir"] / "latency_config.yaml"  # not latency.yaml: that is the log's sidecar
    config.write_text(files["config"].read_text().replace("max_stale_periods: 250", "max_stale_periods: 50"))
    with SimControllerProcess(host=host, robot="ur5e", initial_q=NEAR_START, faults=["latency@2.5:0.2"]):
        r = run_cli(host, "ur5e", files["ur5e"], out, config, "--yes")
        states = program_states(host, watch_s=0.5)
    assert r.returncode == 4, r.stdout + r.stderr
    line = one_line_error(r.stderr)
    assert "controller samples late: no sample for 0.10 s" in line and "frozen" not in line, line
    assert states == {"STOPPED"}
    log = load_log(out)
    recorder = log.metadata["extra"]["recorder"]
    assert recorder["gap_count"] == 1 and 95 <= recorder["missed_samples"] <= 105
    gap = recorder["gaps"][0]
    assert gap["missing_periods"] == recorder["missed_samples"]
    assert gap["resume_s"] - gap["after_s"] == pytest.approx(0.002 * (gap["missing_periods"] + 1), abs=1e-6)
    assert main(["identify", str(out), "--robot", "ur5e", "--allow-aborted",
                 "--out", str(files["dir"] / "latency_params.yaml")]) == 2
