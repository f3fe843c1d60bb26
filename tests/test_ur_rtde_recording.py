"""A CSV written by ur_rtde's own RTDEReceiveInterface.startFileRecording (the real recorder,
against urident's simulated controller) loads with --robot."""

import subprocess
import sys
import textwrap

import numpy as np

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
