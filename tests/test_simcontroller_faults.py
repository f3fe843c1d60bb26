"""Faults of the simulated controller as ur_rtde 1.6.5 sees them (hosts 127.0.0.31-34)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from sim_helpers import dashboard

rtde_control = pytest.importorskip("rtde_control")
rtde_receive = pytest.importorskip("rtde_receive")

from urident.simcontroller.process import SimControllerProcess  # noqa: E402

MAX_POLLS = 4000      # bounds every wait loop (1 ms sleeps); tests never assert on wall time


def test_protective_stop_after_first_motion_is_seen_and_can_be_unlocked():
    host = "127.0.0.31"
    with SimControllerProcess(host=host, faults=["protective_stop@0.6"]):
        control = rtde_control.RTDEControlInterface(host)
        receive = rtde_receive.RTDEReceiveInterface(host)
        try:
            q0 = receive.getActualQ()
            assert control.moveJ([q0[0] + 0.1] + q0[1:], 1.0, 2.0)   # first motion: the clock starts
            accepted = True
            for _ in range(MAX_POLLS):
                t_cycle = control.initPeriod()
                accepted = control.servoJ(receive.getActualQ(), 0.5, 0.5, 0.002, 0.1, 300)
                control.waitPeriod(t_cycle)
                if receive.isProtectiveStopped():
                    break
            assert receive.isProtectiveStopped()
            assert receive.getSafetyStatusBits() & (1 << 2) and receive.getSafetyMode() == 3
            for _ in range(50):
                if not accepted:
                    break
                accepted = control.servoJ(receive.getActualQ(), 0.5, 0.5, 0.002, 0.1, 300)
                time.sleep(0.002)
            assert not accepted                              # the script stopped
            assert receive.getRuntimeState() == 1
            lines = dashboard(host, "safetystatus", "unlock protective stop", "safetystatus")
            assert lines[1:] == ["Safetystatus: PROTECTIVE_STOP", "Protective stop releasing",
                                 "Safetystatus: NORMAL"]
            for _ in range(MAX_POLLS):
                if not receive.isProtectiveStopped():
                    break
                time.sleep(0.001)
            assert receive.getSafetyStatusBits() & (1 << 2) == 0
            assert control.reuploadScript()
        finally:
            control.disconnect()
            receive.disconnect()


def test_emergency_stop_sets_bit_7_and_powers_off():
    host = "127.0.0.32"
    with SimControllerProcess(host=host, faults=["emergency_stop@start+0.3"]):
        receive = rtde_receive.RTDEReceiveInterface(host)
        try:
            for _ in range(MAX_POLLS):
                if receive.isEmergencyStopped():
                    break
                time.sleep(0.001)
            assert receive.getSafetyStatusBits() & (1 << 7)
            assert receive.getSafetyMode() == 7 and receive.getRobotMode() == 3
            assert dashboard(host, "robotmode")[1] == "Robotmode: POWER_OFF"
        finally:
            receive.disconnect()


def test_stale_timestamps_latency_gap_and_drop():
    host = "127.0.0.33"
    faults = ["stale@start+0.5:0.5", "latency@start+1.5:0.3", "drop@start+2.5"]
    with SimControllerProcess(host=host, faults=faults):
        receive = rtde_receive.RTDEReceiveInterface(host)
        samples = []
        try:
            for _ in range(20 * MAX_POLLS):
                if not receive.isConnected():
                    break
                samples.append((receive.getTimestamp(), tuple(receive.getActualCurrent())))
                time.sleep(0.0005)
        finally:
            connected_at_end = receive.isConnected()
            receive.disconnect()
    assert not connected_at_end                                  # drop: the client lost the connection
    stamps = np.array([s[0] for s in samples])
    # stale: one timestamp held while the data (current noise) kept changing
    frozen = [s for s in samples if abs(s[0] - 0.5) < 1e-9]
    assert len({current for _, current in frozen}) > 20
    assert stamps.max() > 2.0
    # latency: packages due in the 0.3 s pause were never sent, so controller time jumps
    distinct = np.unique(stamps)
    jumps = np.diff(distinct)
    late = distinct[1:][jumps > 0.25]
    assert any(1.7 < t < 1.9 for t in late)


def test_no_remote_control_refuses_ur_rtde_control():
    host = "127.0.0.34"
    with SimControllerProcess(host=host, faults=["no_remote"]):
        assert dashboard(host, "is in remote control")[1] == "false"
        with pytest.raises(Exception, match="remote control"):
            rtde_control.RTDEControlInterface(host)
