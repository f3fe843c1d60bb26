"""Simulated controller against the unmodified ur_rtde 1.6.5 client (hosts 127.0.0.21-22)."""

from __future__ import annotations

import math
import re
import socket

import numpy as np
import pytest
from sim_helpers import dashboard

rtde_control = pytest.importorskip("rtde_control")
rtde_receive = pytest.importorskip("rtde_receive")

from urident.model import load_robot  # noqa: E402
from urident.simcontroller.controller import make_torque_model  # noqa: E402
from urident.simcontroller.process import SimControllerProcess  # noqa: E402

HOST_E = "127.0.0.21"
HOST_CB3 = "127.0.0.22"
START_Q = [0.2, -1.4, 1.4, -1.5, -1.5, 0.3]


@pytest.fixture(scope="module")
def sim_e():
    with SimControllerProcess(host=HOST_E, robot="ur5e", seed=3) as sim:
        yield sim
    assert sim.returncode == 0


def consistent_sample(receive):
    """Fields from one data package: retry until the timestamp did not change while reading."""
    for _ in range(20):
        ts = receive.getTimestamp()
        sample = (receive.getTargetQ(), receive.getTargetQd(), receive.getTargetQdd(),
                  receive.getActualCurrent(), receive.getActualQ())
        if receive.getTimestamp() == ts:
            return ts, sample
    return None


def test_dashboard_replies(sim_e):
    lines = dashboard(HOST_E, "PolyscopeVersion", "get serial number", "is in remote control",
                      "robotmode", "safetystatus", "frobnicate", "stop")
    assert lines[0] == "Connected: Universal Robots Dashboard Server"
    assert re.search(r"\d+\.\d+\.\d+\.\d+", lines[1]) and "5.11.0" in lines[1]
    assert lines[2].isdigit()
    assert lines[3] == "true"
    assert lines[4] == "Robotmode: RUNNING" and lines[5] == "Safetystatus: NORMAL"
    assert lines[6].startswith("could not understand")
    assert lines[7] == "Stopped"


def test_moveJ_servoJ_currents_and_stopScript(sim_e):
    spec = load_robot("ur5e")
    model = make_torque_model(spec)
    control = rtde_control.RTDEControlInterface(HOST_E)
    receive = rtde_receive.RTDEReceiveInterface(HOST_E)
    try:
        assert control.isProgramRunning() and receive.getRuntimeState() == 2
        assert control.moveJ(START_Q, 1.5, 3.0)
        assert np.allclose(receive.getActualQ(), START_Q, atol=2e-5)

        samples, errors = [], []
        n, period = 1000, 0.002
        for k in range(n + 150):
            t_cycle = control.initPeriod()
            s = min(k, n) * period
            target = [START_Q[j] + 0.15 * math.sin(2 * math.pi * 0.5 * s + j) - 0.15 * math.sin(j)
                      for j in range(6)]
            assert control.servoJ(target, 0.5, 0.5, period, 0.1, 300)
            if k % 4 == 0:
                sample = consistent_sample(receive)
                if sample is not None:
                    samples.append(sample)
                errors.append(np.max(np.abs(np.array(receive.getActualQ()) - target)))
            control.waitPeriod(t_cycle)
        # tracking: bounded lag while moving, converged after holding the last target
        assert max(errors) < 0.05
        assert np.max(np.abs(np.array(receive.getActualQ()) - target)) < 1e-3
        assert control.servoStop(10.0)

        # currents = TorqueModel torques / drive gains, within the 0.02 A noise
        unique = {ts: sample for ts, sample in samples}          # the client may read a package twice
        stamps = np.array(sorted(unique))
        residuals = np.array([np.array(cur) - model.torque(np.array(q), np.array(qd), np.array(qdd)) / spec.drive_gains
                              for q, qd, qdd, cur, _ in (unique[ts] for ts in stamps)])
        assert len(stamps) > 150
        steps = np.diff(stamps) / 0.002
        assert np.allclose(steps, np.round(steps), atol=1e-6)     # 500 Hz controller clock
        assert np.all(np.abs(residuals.mean(axis=0)) < 0.01)
        assert np.all((residuals.std(axis=0) > 0.01) & (residuals.std(axis=0) < 0.04))

        control.stopScript()
        assert not control.isProgramRunning() and receive.getRuntimeState() == 1
    finally:
        receive.disconnect()
        control.disconnect()


def test_reconnect_kills_running_script_and_reuploads(sim_e):
    first = rtde_control.RTDEControlInterface(HOST_E)
    first.disconnect()                       # leaves the script running, as on a real robot
    second = rtde_control.RTDEControlInterface(HOST_E)
    try:
        assert second.isProgramRunning()
        assert second.moveJ(START_Q, 1.0, 1.0)
    finally:
        second.stopScript()
        second.disconnect()


def test_cb3_version_runs_at_125_hz():
    with SimControllerProcess(host=HOST_CB3, robot="ur5") as sim:
        receive = rtde_receive.RTDEReceiveInterface(HOST_CB3)
        control = rtde_control.RTDEControlInterface(HOST_CB3)
        try:
            stamps = set()
            q0 = receive.getActualQ()
            for k in range(60):
                t_cycle = control.initPeriod()
                assert control.servoJ(q0, 0.5, 0.5, 0.008, 0.1, 300)
                stamps.add(receive.getTimestamp())
                control.waitPeriod(t_cycle)
            assert control.servoStop(10.0)
            stamps = np.array(sorted(stamps))
            steps = np.diff(stamps) / 0.008
            assert len(stamps) > 10 and np.allclose(steps, np.round(steps), atol=1e-6)
            assert np.min(np.diff(stamps)) == pytest.approx(0.008)
            control.stopScript()
        finally:
            control.disconnect()
            receive.disconnect()
    assert sim.returncode == 0 and sim.stats["cycles"] > 0


def test_sigterm_stops_cleanly_and_frees_the_ports():
    host = "127.0.0.23"
    sim = SimControllerProcess(host=host).start()
    assert sim.stop() == 0
    assert sim.stats is not None and "late_cycle_pct" in sim.stats
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind((host, 30004))
