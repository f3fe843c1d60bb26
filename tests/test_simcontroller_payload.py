"""The simulated controller takes a payload declared by ur_rtde's setTargetPayload / setPayload
and reports it in the target moment, as a real controller's model does (issue 17); the
``payload_error`` effect is a full ten-parameter rigid body."""

from __future__ import annotations

import time

import numpy as np
import pytest

rtde_control = pytest.importorskip("rtde_control")
rtde_receive = pytest.importorskip("rtde_receive")

from urident.ident.payload import payload_torque  # noqa: E402
from urident.model.payload import Payload  # noqa: E402
from urident.model import load_robot  # noqa: E402
from urident.simcontroller.process import SimControllerProcess  # noqa: E402

HOST = "127.0.0.41"
START_Q = [0.2, -1.4, 1.4, -1.5, -1.5, 0.3]


def _moment(receive, n=10):
    time.sleep(0.05)
    return np.mean([receive.getTargetMoment() for _ in range(n)], axis=0)


def test_declared_payload_shows_in_the_target_moment():
    spec = load_robot("ur5e")
    with SimControllerProcess(host=HOST, robot="ur5e", seed=3) as sim:
        control = rtde_control.RTDEControlInterface(HOST)
        receive = rtde_receive.RTDEReceiveInterface(HOST)
        try:
            assert control.moveJ(START_Q, 1.5, 3.0)
            q = np.array(receive.getActualQ())
            before = _moment(receive)
            mass, cog, inertia = 2.0, [0.01, 0.02, 0.08], [0.01, 0.012, 0.008, 0.0, 0.0, 0.0]
            assert control.setTargetPayload(mass, cog, inertia)
            after = _moment(receive)
            expected = payload_torque(spec, Payload("ur5e", mass, cog, np.diag(inertia[:3])),
                                      q[None], np.zeros((1, 6)), np.zeros((1, 6)))[0]
            assert np.max(np.abs(expected)) > 1.0          # a real change on the shoulder and elbow
            np.testing.assert_allclose(after - before, expected, atol=0.02)
            assert control.setPayload(0.5, [0.0, 0.0, 0.05])
            half = _moment(receive)
            expected = payload_torque(spec, Payload("ur5e", 0.5, [0, 0, 0.05], np.zeros((3, 3))),
                                      q[None], np.zeros((1, 6)), np.zeros((1, 6)))[0]
            np.testing.assert_allclose(half - before, expected, atol=0.02)
            control.stopScript()
        finally:
            receive.disconnect()
            control.disconnect()
    assert sim.returncode == 0


def test_payload_error_is_a_rigid_body():
    from urident.model import joint_torques
    from urident.simcontroller.effects import payload_params
    from urident.simcontroller.effects.dynamics import inertia_matrix

    spec = load_robot("ur10e")
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-1, 1, (50, 6)) for _ in range(3))
    inertia = inertia_matrix([0.02, 0.025, 0.015], [0.001, -0.002, 0.0005])
    p = Payload("ur10e", 3.0, [0.02, -0.01, 0.08], inertia)
    tau_effect = joint_torques(spec, payload_params(spec, 3.0, p.com_m, inertia), q, qd, qdd, 0.01)
    np.testing.assert_allclose(tau_effect, payload_torque(spec, p, q, qd, qdd), atol=1e-9)
    point = joint_torques(spec, payload_params(spec, 3.0, p.com_m), q, qd, qdd, 0.01)
    assert np.max(np.abs(tau_effect - point)) > 0.01      # the inertia matters


def test_urident_run_records_the_declared_payload_and_reports_show_it(tmp_path):
    import argparse
    import io
    import subprocess
    import sys

    from urident.excitation import FourierTrajectory, Limits, trajectory_document, write_trajectory
    from urident.excitation.fourier import base_frequency
    from urident.logs import load_log
    from urident.cli.log_args import load_log_from_args
    from urident.logs.sidecar import declared_payload

    host, start = "127.0.0.42", [0.0, -1.5708, 0.0, -1.5708, 0.0, 0.0]
    spec = load_robot("ur5e")
    free = np.random.default_rng(1).normal(scale=0.1, size=(6, 4))
    traj = tmp_path / "t.yaml"
    write_trajectory(traj, trajectory_document("ur5e", FourierTrajectory.from_free(
        free, base_frequency(2.0), np.array(start), 2.0), Limits.from_robot(spec)))
    config = tmp_path / "relaxed.yaml"
    config.write_text("monitors:\n  max_late_fraction: 0.9\n  max_consecutive_late: 100000\nrest_s: 0.2\n")
    out = tmp_path / "run.csv"
    mass, cog, inertia = 1.5, [0.0, 0.01, 0.07], [0.004, 0.005, 0.003, 0.0, 0.0, 0.0]
    with SimControllerProcess(host=host, robot="ur5e", initial_q=start):
        control = rtde_control.RTDEControlInterface(host)
        try:   # the installation's payload, set before the session (it persists across programs)
            assert control.setTargetPayload(mass, cog, inertia)
            control.stopScript()
        finally:
            control.disconnect()
        run = [sys.executable, "-m", "urident.cli.main", "run", "--robot", "ur5e", "--host", host,
               "--trajectory", str(traj), "--config", str(config)]
        # checked for the empty flange, the controller told 1.5 kg: refused before any motion
        refused = subprocess.run([*run, "--check-only"], capture_output=True, text=True, timeout=120,
                                 stdin=subprocess.DEVNULL)
        r = subprocess.run([*run, "--out", str(out), "--yes", "--payload-mass", "1.5", "--payload-com", "0,0.01,0.07"],
                           capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert refused.returncode == 3, refused.stderr
    line = refused.stderr.strip().splitlines()
    assert len(line) == 1 and "declares a payload of 1.5 kg, heavier than the 0 kg" in line[0]
    assert r.returncode == 0, r.stderr
    assert "torques checked with 1.5 kg" in r.stdout
    recorded = declared_payload(load_log(out).metadata)
    assert recorded is not None
    assert recorded.mass_kg == pytest.approx(mass) and recorded.cog_m == pytest.approx(cog)
    assert recorded.inertia_kg_m2 == pytest.approx(inertia)
    assert load_log(out).metadata["extra"]["checked_payload_kg"] == 1.5   # what the torque check included
    report = io.StringIO()   # what validate, gap, identify and payload print for every log they load
    load_log_from_args(out, argparse.Namespace(), robot="ur5e", report=report)
    assert "payload declared to the controller" in report.getvalue() and "1.5 kg" in report.getvalue()
