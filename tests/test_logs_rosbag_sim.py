"""A bag from a run on the simulated controller: `urident run` (unmodified ur_rtde client) →
`urident convert` → the bag loads as the log it came from, safety and robot modes included, and
identify gives the same parameters from both."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rtde_control")

from test_logs_rosbag import _params  # noqa: E402
from test_session_family import small_trajectory  # noqa: E402
from test_session_sim import NEAR_START, RELAXED, run_cli  # noqa: E402

from urident.cli.main import main  # noqa: E402
from urident.logs import load_log  # noqa: E402
from urident.simcontroller.process import SimControllerProcess  # noqa: E402

HOST = "127.0.0.91"


def test_bag_of_a_simulated_run_loads_as_its_log(tmp_path, capsys):
    config = tmp_path / "relaxed.yaml"
    config.write_text(RELAXED)
    out = tmp_path / "run.csv"
    with SimControllerProcess(host=HOST, robot="ur3", initial_q=NEAR_START):
        r = run_cli(HOST, "ur3", small_trajectory(tmp_path / "t.yaml", "ur3"), out, config, "--yes")
    assert r.returncode == 0, r.stderr
    log = load_log(out)
    for storage in ("mcap", "sqlite3"):
        bag = tmp_path / f"run_{storage}"
        assert main(["convert", str(out), "--bag", str(bag), "--storage", storage]) == 0
        rec = load_log(bag, robot="ur3", effort="current")  # at rest near the vertical: no gravity to tell
        assert len(rec) == len(log) and rec.metadata["time_source"] == "header.stamp"
        np.testing.assert_array_equal(rec.t, log.t)  # ns stamps / 1e9: the CSV's times exactly
        for name in ("q", "qd", "current"):
            np.testing.assert_array_equal(getattr(rec, name), getattr(log, name))
        np.testing.assert_array_equal(rec.robot_mode, log.robot_mode)
        assert rec.metadata["excluded"] == []
        np.testing.assert_array_equal(rec.safety_status_bits, log.safety_status_bits)
    for path, params, extra in ((out, "c.yaml", []), (tmp_path / "run_sqlite3", "b.yaml",
                                                       ["--effort", "current"])):
        assert main(["identify", str(path), "--robot", "ur3", *extra,
                     "--out", str(tmp_path / params)]) == 0
    pc, pb = _params(tmp_path / "c.yaml"), _params(tmp_path / "b.yaml")
    assert pc.size > 30
    np.testing.assert_allclose(pb, pc, rtol=1e-9, atol=1e-12)
