"""The simulated controller binds loopback only unless --allow-remote (and then warns on every
start); --start-near puts the arm next to a trajectory's start."""

from __future__ import annotations

import numpy as np
import pytest

from test_session_sim import files  # noqa: F401 - the module's trajectory fixture
from urident.cli.main import main
from urident.excitation import load_trajectory
from urident.simcontroller.launch import START_NEAR_OFFSET_RAD, loopback_problem
from urident.simcontroller.process import SimControllerProcess


@pytest.mark.parametrize("host", ["0.0.0.0", "10.1.2.3", "192.168.1.10"])
def test_non_loopback_address_is_refused(host, capsys):
    assert main(["sim-controller", "--host", host]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"urident: error: --host {host}:")
    assert "--allow-remote" in err[0]


def test_loopback_addresses():
    assert loopback_problem("127.0.0.1") is None and loopback_problem("127.0.0.77") is None
    assert loopback_problem("localhost") is None
    assert "not a loopback" in loopback_problem("0.0.0.0")


def test_allow_remote_binds_and_warns_on_every_start():
    # Inside the test's private network namespace, all interfaces are loopback only anyway.
    for _ in range(2):
        with SimControllerProcess(host="0.0.0.0", robot="ur5e", extra_args=["--allow-remote"]) as sim:
            assert sim.is_running()
        assert any(line.startswith("warning: --allow-remote") and "reachable from other machines"
                   in line for line in sim.log_lines), list(sim.log_lines)


def test_start_near_puts_the_arm_next_to_the_trajectory_start(files):  # noqa: F811
    import rtde_receive

    host = "127.0.0.71"
    q_start = load_trajectory(files["ur5e"]).trajectory.q_start
    with SimControllerProcess(host=host, robot="ur5e", extra_args=["--start-near", str(files["ur5e"])]):
        receive = rtde_receive.RTDEReceiveInterface(host)
        q = np.array(receive.getActualQ())
        receive.disconnect()
    offset = np.abs(q - q_start)
    assert np.all(offset > 0.5 * START_NEAR_OFFSET_RAD) and np.all(offset < 1.5 * START_NEAR_OFFSET_RAD)


def test_start_near_checks_the_robot_and_excludes_initial_q(files, capsys):  # noqa: F811
    assert main(["sim-controller", "--robot", "ur5", "--start-near", str(files["ur5e"])]) == 2
    assert "trajectory is for robot 'ur5e', not 'ur5'" in capsys.readouterr().err
    assert main(["sim-controller", "--start-near", str(files["ur5e"]), "--initial-q=0,0,0,0,0,0"]) == 2
    assert "not allowed with argument --start-near" in capsys.readouterr().err


def test_this_module_runs_in_the_controller_group(request):
    """Under pytest-xdist's groups every module that starts a controller shares one worker
    (tests/conftest.py); the group shows in the node id, or a plugin change lost it."""
    if not request.config.getvalue("loadgroup"):
        pytest.skip("not run by pytest-xdist with --dist loadgroup")
    assert request.node.nodeid.endswith("@controller"), request.node.nodeid
