"""A CSV written by ur_rtde's own RTDEReceiveInterface.startFileRecording (the real recorder,
against urident's simulated controller) loads with --robot."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from urident.logs import load_log
from urident.simcontroller.process import SimControllerProcess

RECORD = textwrap.dedent("""
    import sys, time
    import rtde_receive
    host, path = sys.argv[1], sys.argv[2]
    r = rtde_receive.RTDEReceiveInterface(host)
    r.startFileRecording(path, ["timestamp", "actual_q", "actual_qd", "actual_current",
                                "target_q", "joint_temperatures", "robot_mode"])
    time.sleep(1.5)
    r.stopFileRecording()
    r.disconnect()
""")


def test_ur_rtde_file_recording_loads(tmp_path):
    path = tmp_path / "ur_rtde_recording.csv"
    with SimControllerProcess(host="127.0.0.38", robot="ur5e"):
        subprocess.run([sys.executable, "-c", RECORD, "127.0.0.38", str(path)], check=True,
                       capture_output=True, text=True, timeout=60)
    header = path.read_text().splitlines()[0]
    assert header.startswith("timestamp,actual_q_0,")
    rec = load_log(path, robot="ur5e")
    assert rec.robot == "ur5e" and len(rec.t) > 300
    assert np.all(np.diff(rec.t) > 0)                      # de-duplicated on timestamp
    assert rec.q.shape == (len(rec.t), 6) and rec.target_q is not None
    assert np.all(np.isfinite(rec.current))


def test_repeated_rows_dropped_single_skips_bridged_real_losses_kept(tmp_path):
    """ur_rtde's recorder samples the latest state on its own clock: rows repeat (dropped, counted)
    and single controller samples go missing (bridged by their neighbours' mean, counted); a
    longer loss stays a gap."""
    from urident.logs.gaps import recording_gaps

    t = np.arange(400) * 0.002 + 1.0
    q = np.column_stack([np.sin(t + j) for j in range(6)])
    rows = list(range(400))
    del rows[300:303]          # a real loss: 3 periods
    del rows[200]              # single skips, neighbours on time
    del rows[100]
    rows.insert(50, 50)        # a repeated row
    names = ["timestamp"] + [f"actual_q_{j}" for j in range(6)] + [f"actual_qd_{j}" for j in range(6)] \
        + [f"actual_current_{j}" for j in range(6)] + ["robot_mode"]
    path = tmp_path / "rec.csv"
    with open(path, "w") as f:
        f.write(",".join(names) + "\n")
        for k in rows:
            f.write(",".join([f"{t[k]:.6f}"] + [f"{v:.9g}" for v in q[k]] + [f"{v:.9g}" for v in q[k]]
                             + [f"{v:.9g}" for v in q[k]] + ["7"]) + "\n")
    rec = load_log(path, robot="ur5e")
    assert rec.metadata["duplicates_removed"] == 1 and rec.metadata["bridged"] == 2
    assert any("2 single missing period(s) bridged" in n for n in rec.metadata["notes"])
    k = np.searchsorted(rec.t, t[100])
    assert rec.t[k] == pytest.approx(t[100]) and np.allclose(rec.q[k], q[100], atol=1e-5)
    assert rec.robot_mode[k] == 7
    gaps = recording_gaps(rec)
    assert len(gaps) == 1 and gaps[0].missing == 3


RECORD_RUN = textwrap.dedent("""
    import sys, time
    import rtde_receive
    host, path = sys.argv[1], sys.argv[2]
    r = rtde_receive.RTDEReceiveInterface(host, 500.0)
    r.startFileRecording(path, ["timestamp", "actual_q", "actual_qd", "actual_current"])
    sys.stdin.readline()                  # until the run has ended
    r.stopFileRecording()
    r.disconnect()
""")


def check_ur_rtde_run_recording(path, robot, tmp_path, capsys) -> str:
    """A ur_rtde recording of a run (tests/test_signals.py records one beside `urident run`): its
    repeated rows dropped and single skips bridged exactly as counted from the raw file; without
    a real loss it identifies without --allow-gaps, with one it is refused. Returns which."""
    from urident.cli.main import main
    from urident.logs.gaps import GAP_FACTOR

    t = np.loadtxt(path, delimiter=",", skiprows=1, usecols=0)
    repeated = int(np.sum(np.diff(t) == 0))
    t = np.unique(t)
    steps = np.round(np.diff(t) / 0.002)
    on_time = np.diff(t) <= GAP_FACTOR * 0.002
    single = (steps == 2) & np.r_[False, on_time[:-1]] & np.r_[on_time[1:], False]
    real = int(np.sum(~on_time & ~single))
    rec = load_log(path, robot=robot)
    assert rec.metadata["duplicates_removed"] == repeated
    assert rec.metadata["bridged"] == int(single.sum())
    assert np.max(np.abs(rec.qd)) > 0.05                   # it saw the motion
    code = main(["identify", str(path), "--robot", robot, "--out", str(tmp_path / "ur_rtde.yaml")])
    err = capsys.readouterr().err
    if real == 0:
        assert code == 0, err
        return f"identified: {repeated} repeated, {int(single.sum())} bridged"
    assert code == 2 and "pass --allow-gaps" in err    # a real loss (a starved recorder) is kept
    return f"refused: {real} real losses ({repeated} repeated, {int(single.sum())} bridged)"
