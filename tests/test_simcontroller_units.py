"""Simulated controller: pieces tested without sockets (protocol, fields, faults, plant, script)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from urident.errors import ConfigError
from urident.model import load_robot
from urident.simcontroller import fields
from urident.rtde import protocol as rp
from urident.simcontroller.controller import Controller, ControllerConfig, make_torque_model, parse_version
from urident.simcontroller.faults import FaultSchedule, parse_fault
from urident.simcontroller.plant import MoveProfile, Plant, servo_bandwidth
from urident.simcontroller.robot_state import RUNTIME_PLAYING, RUNTIME_STOPPED
from urident.simcontroller.script_emulator import ScriptStream, parse_program

# ur_rtde 1.6.5 decodes outputs with its own table (src/robot_state.cpp): vector<double> is read as
# 6 doubles except these 3-vectors, double, int32, uint32, uint64, vector<int32> (6).
UR_RTDE_VECTOR3 = {"actual_tool_accelerometer", "payload_cog", "elbow_position", "elbow_velocity"}
UR_RTDE_TABLE = {
    **{n: "VECTOR6D" for n in (
        "target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q", "actual_qd",
        "actual_current", "joint_control_output", "actual_TCP_pose", "actual_TCP_speed", "actual_TCP_force",
        "target_TCP_pose", "target_TCP_speed", "joint_temperatures", "actual_joint_voltage", "ft_raw_wrench",
        "payload_inertia", "actual_current_as_torque")},
    **{n: "VECTOR3D" for n in UR_RTDE_VECTOR3},
    **{n: "DOUBLE" for n in (
        "timestamp", "actual_execution_time", "speed_scaling", "target_speed_fraction", "actual_momentum",
        "actual_main_voltage", "actual_robot_voltage", "actual_robot_current", "standard_analog_input0",
        "standard_analog_input1", "standard_analog_output0", "standard_analog_output1", "payload")},
    **{n: "INT32" for n in ("robot_mode", "safety_mode")},
    **{n: "UINT32" for n in ("runtime_state", "robot_status_bits", "safety_status_bits",
                             "output_bit_registers0_to_31", "output_bit_registers32_to_63")},
    **{n: "UINT64" for n in ("actual_digital_input_bits", "actual_digital_output_bits")},
    "joint_mode": "VECTOR6INT32",
    **{f"output_int_register_{k}": "INT32" for k in range(48)},
    **{f"output_double_register_{k}": "DOUBLE" for k in range(48)},
}
RECEIVE_DEFAULTS = [
    "timestamp", "target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q",
    "actual_qd", "actual_current", "joint_control_output", "actual_TCP_pose", "actual_TCP_speed",
    "actual_TCP_force", "target_TCP_pose", "target_TCP_speed", "actual_digital_input_bits",
    "joint_temperatures", "actual_execution_time", "robot_mode", "joint_mode", "safety_mode",
    "actual_tool_accelerometer", "speed_scaling", "target_speed_fraction", "actual_momentum",
    "actual_main_voltage", "actual_robot_voltage", "actual_robot_current", "actual_joint_voltage",
    "actual_digital_output_bits", "runtime_state", "standard_analog_input0", "standard_analog_input1",
    "standard_analog_output0", "standard_analog_output1", "robot_status_bits", "safety_status_bits",
    "ft_raw_wrench", "payload", "payload_cog", "payload_inertia", "output_int_register_2",
] + [f"output_int_register_{k}" for k in range(12, 20)] + [f"output_double_register_{k}" for k in range(12, 20)]


@pytest.fixture(scope="module")
def ur5e():
    return load_robot("ur5e")


def test_field_types_match_ur_rtde_decoder():
    for name, expected in UR_RTDE_TABLE.items():
        assert fields.OUTPUT_FIELDS[name].rtde_type == expected, name


def test_receive_defaults_are_served_by_5_11_and_unknown_names_are_not():
    version = (5, 11, 0, 1)
    for name in RECEIVE_DEFAULTS:
        assert fields.output_type(name, version) is not None, name
    assert fields.output_type("actual_qdd", version) is None           # ur_rtde knows it, UR does not
    assert fields.output_type("actual_current_as_torque", version) is None   # needs 5.23
    assert fields.output_type("actual_current_as_torque", (5, 23, 0, 1)) == "VECTOR6D"
    assert fields.output_type("ft_raw_wrench", (3, 15, 8, 1)) is None
    assert fields.input_type("input_int_register_0", version) == "INT32"
    assert fields.input_type("external_force_torque", version) == "VECTOR6D"


def test_message_framing_and_recipes():
    reader = rp.MessageReader()
    msg = rp.frame(rp.CONTROL_PACKAGE_START) + rp.frame(rp.DATA_PACKAGE, b"\x01abc")
    assert reader.feed(msg[:4]) == [(rp.CONTROL_PACKAGE_START, b"")]
    assert reader.feed(msg[4:]) == [(rp.DATA_PACKAGE, b"\x01abc")]
    recipe = rp.Recipe.build(3, ["timestamp", "actual_q", "robot_mode", "joint_mode"],
                             ["DOUBLE", "VECTOR6D", "INT32", "VECTOR6INT32"])
    packed = recipe.pack([1.5, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0], -1, [253] * 6])
    size, kind = struct.unpack(">HB", packed[:3])
    assert size == len(packed) == 3 + 1 + 8 + 48 + 4 + 24 and kind == rp.DATA_PACKAGE
    values = recipe.unpack(packed[3:])
    assert values["actual_q"] == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0] and values["robot_mode"] == -1
    inputs = rp.Recipe.build(2, ["input_int_register_0", "input_double_register_0"], ["INT32", "DOUBLE"])
    assert inputs.unpack(b"\x02" + struct.pack(">i", 11)) == {"input_int_register_0": 11}  # short package
    assert rp.parse_names(b"a,b,") == ["a", "b"]
    freq, names = rp.parse_output_setup(struct.pack(">d", 500.0) + b"timestamp,actual_q,", 2)
    assert freq == 500.0 and names == ["timestamp", "actual_q"]


@pytest.mark.parametrize("spec, expected", [
    ("drop@3", ("drop", 3.0, False)),
    ("protective_stop@2.5", ("protective_stop", 2.5, False)),
    ("emergency_stop@start+1", ("emergency_stop", 1.0, True)),
    ("latency@2.0:0.2", ("latency", 2.0, False)),
    ("stale@start+0.5", ("stale", 0.5, True)),
])
def test_fault_specs(spec, expected):
    fault = parse_fault(spec)
    assert (fault.kind, fault.at_s, fault.from_start) == expected
    assert parse_fault(fault.spec) == fault


@pytest.mark.parametrize("spec", ["bogus@1", "drop", "drop@x", "drop@1:2", "latency@-1", "no_remote@1"])
def test_bad_fault_specs_raise_config_error(spec):
    with pytest.raises(ConfigError, match="--fault"):
        parse_fault(spec)


def test_fault_schedule_counts_from_first_motion():
    schedule = FaultSchedule([parse_fault("drop@1.0"), parse_fault("latency@start+0.5:0.2"), parse_fault("no_remote")])
    assert schedule.no_remote
    assert [f.kind for f in schedule.due(5.0, None)] == ["latency"]   # drop waits for motion
    assert schedule.sending_paused(0.6, None) and not schedule.sending_paused(0.8, None)
    assert schedule.due(5.5, 5.0) == [] and [f.kind for f in schedule.due(6.0, 5.0)] == ["drop"]
    assert schedule.due(7.0, 5.0) == []                      # fires once


def test_versions():
    assert parse_version("5.11.0") == (5, 11, 0, 108249)
    assert parse_version("3.15")[:3] == (3, 15, 0)
    for bad in ("5", "x.y", "10.0.0", "5.1.2.3.4"):
        with pytest.raises(ConfigError):
            parse_version(bad)


def test_move_profile_reaches_goal_with_speed_and_acceleration_limits():
    profile = MoveProfile(np.zeros(6), np.array([1.0, -0.5, 0, 0, 0, 0.25]), speed=1.0, acceleration=2.0)
    t = np.arange(0.0, profile.duration + 0.01, 0.002)
    samples = [profile.sample(x) for x in t]
    qd = np.array([s[1] for s in samples])
    assert np.max(np.abs(qd[:, 0])) <= 1.0 + 1e-9
    assert np.allclose(samples[-1][0], profile.goal)
    assert profile.duration == pytest.approx(1.0 / 1.0 + 1.0 / 2.0)


def test_plant_servo_tracks_and_currents_follow_the_torque_model(ur5e):
    model = make_torque_model(ur5e)
    plant = Plant(ur5e, model, 500.0, np.random.default_rng(1))
    target = plant.q + np.array([0.1, -0.05, 0.05, 0.1, -0.1, 0.2])
    residuals = []
    for _ in range(1500):
        plant.servo(target, lookahead_time=0.1, gain=300)
        plant.step()
        expected = model.torque(plant.q, plant.qd, plant.qdd) / ur5e.drive_gains
        residuals.append(plant.measured_current - expected)
    assert np.max(np.abs(plant.q - target)) < 1e-4
    residuals = np.array(residuals)
    assert np.all(np.abs(residuals.mean(axis=0)) < 0.005)
    assert np.all(np.abs(residuals.std(axis=0) - 0.02) < 0.004)
    assert np.max(np.abs(plant.measured_q - plant.q)) <= 0.5e-5 + 1e-12
    assert np.all(plant.temperatures > 29.0)


def test_servo_bandwidth_from_gain_and_lookahead():
    assert servo_bandwidth(0.1, 300) == pytest.approx(30.0)
    assert servo_bandwidth(0.03, 2000) == pytest.approx(4 / 0.03)
    assert servo_bandwidth(0.2, 2000) < servo_bandwidth(0.05, 2000)


def test_plant_hooks_add_torque_and_change_measurement(ur5e):
    class Effects:
        def extra_torque(self, t, q, qd, qdd, tau_model, temperatures):
            return np.full(6, 1.0)

        def measure_current(self, t, current, q, qd, temperatures):
            return current + 10.0

    model = make_torque_model(ur5e)
    plant = Plant(ur5e, model, 500.0, np.random.default_rng(1), effects=Effects(), current_noise_a=0.0)
    plant.step()
    tau_model = model.torque(plant.q, plant.qd, plant.qdd)
    assert np.allclose(plant.tau, tau_model + 1.0)
    assert np.allclose(plant.measured_current, (tau_model + 1.0) / ur5e.drive_gains + 10.0)
    assert np.allclose(plant.target_current, tau_model / ur5e.drive_gains)


def test_script_stream_splits_programs():
    stream = ScriptStream()
    text = "def rtde_control():\n  global reg_offset_int = 24\n  def rtde_cmd():\n  end\nend\nstopj(2)\n"
    programs = stream.feed(text[:20].encode()) + stream.feed(text[20:].encode())
    assert len(programs) == 2 and programs[1] == "stopj(2)"
    program = parse_program(programs[0] + "signal_ready")
    assert program.is_rtde_control and program.int_offset == 24


def _controller(spec, **kw):
    return Controller(ControllerConfig(spec=spec, version=parse_version("5.11.0"), **kw))


def test_register_handshake_moveJ_then_clear(ur5e):
    c = _controller(ur5e)
    c.load_program("def rtde_control():\n rtde_cmd()\n signal_ready()\nend\n")
    for _ in range(30):
        c.tick()
    assert c.script.runtime_state == RUNTIME_PLAYING and c.registers.output_int[0] == 1
    goal = list(c.plant.q + 0.05)
    c.apply_inputs({"input_int_register_0": 1, **{f"input_double_register_{k}": goal[k] for k in range(6)},
                    "input_double_register_6": 1.0, "input_double_register_7": 2.0, "input_int_register_1": 0})
    c.tick()
    assert c.registers.output_int[0] == 1          # busy: blocking moveJ
    for _ in range(400):
        c.tick()
    assert c.registers.output_int[0] == 2 and np.allclose(c.plant.q, goal)
    c.apply_inputs({"input_int_register_0": 0})
    c.tick()
    assert c.registers.output_int[0] == 1
    c.apply_inputs({"input_int_register_0": 255})
    c.tick()
    assert c.script.runtime_state == RUNTIME_STOPPED


def test_protective_stop_fault_stops_script(ur5e):
    c = _controller(ur5e, faults=[parse_fault("protective_stop@start+0.1")])
    c.load_program("def rtde_control():\n rtde_cmd()\n signal_ready()\nend\n")
    for _ in range(100):
        c.tick()
    assert c.safety_status_bits & (1 << 2) and c.safety_mode == 3
    assert c.script.runtime_state == RUNTIME_STOPPED
    assert c.unlock_protective_stop() and c.safety_status_bits == 1


def test_bad_effects_file_gives_config_error(ur5e, tmp_path):
    with pytest.raises(ConfigError):
        _controller(ur5e, effects_path=str(tmp_path / "missing.yaml"))


def test_cli_errors_are_one_line(capsys):
    from urident.cli.main import main

    assert main(["sim-controller", "--robot", "nope"]) == 2
    assert main(["sim-controller", "--fault", "bogus@1"]) == 2
    assert main(["sim-controller", "--robot", "ur5", "--version", "5.11.0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(line.startswith("urident: error: ") for line in err)


def test_process_passes_negative_initial_pose_and_reports_startup_failure():
    from urident.simcontroller.process import SimControllerError, SimControllerProcess

    q = [-0.47, -2.13, -2.19, 1.06, -0.36, -1.06]
    with SimControllerProcess(host="127.0.0.39", robot="ur5e", initial_q=q) as sim:
        assert sim.is_running()
    with pytest.raises(SimControllerError, match="did not start"):
        SimControllerProcess(host="127.0.0.39", robot="ur5e", version="not-a-version").start()


@pytest.mark.parametrize("robot", ["ur5", "ur5e", "ur10e"])
def test_tcp_kinematics_match_the_dh_reference_and_differentiate_to_the_speed(robot):
    from urident.simcontroller.kinematics import DHKinematics, Kinematics

    spec = load_robot(robot)
    fast, reference = Kinematics.from_spec(spec), DHKinematics.from_spec(spec)
    rng = np.random.default_rng(7)
    for offset in (None, [0.0, 0.0, 0.1, 0.0, 0.0, 0.0], [0.01, -0.02, 0.15, 0.1, -0.2, 0.3]):
        for _ in range(50):
            q, qd = rng.uniform(-3.0, 3.0, 6), rng.uniform(-2.0, 2.0, 6)
            for got, want in zip(fast.tcp(q, qd, offset), reference.tcp(q, qd, offset)):
                np.testing.assert_allclose(got, want, atol=1e-10)
            # The reported speed is the time derivative of the reported position (and elbow).
            h = 1e-6
            ahead, behind = fast.tcp(q + h * qd, qd, offset), fast.tcp(q - h * qd, qd, offset)
            pose, speed, _, elbow_velocity, _ = fast.tcp(q, qd, offset)
            np.testing.assert_allclose((ahead[0][:3] - behind[0][:3]) / (2 * h), speed[:3], atol=1e-6)
            np.testing.assert_allclose((ahead[2] - behind[2]) / (2 * h), elbow_velocity, atol=1e-6)
