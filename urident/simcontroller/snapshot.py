"""One controller cycle's output values, by RTDE field name (see :mod:`.fields`).

A :class:`Snapshot` is built by the controller thread after each physics step that has a data
package due. The joint vectors are converted together when it is built; the Cartesian values
(forward kinematics) are computed on first use, so a recipe without them does not pay for them.
"""

from __future__ import annotations

import numpy as np

from urident.simcontroller.robot_state import (
    JOINT_MODE_POWER_OFF,
    JOINT_MODE_RUNNING,
    ROBOT_MODE_RUNNING,
    ROBOT_STATUS_POWER_ON,
    ROBOT_STATUS_PROGRAM_RUNNING,
    RUNTIME_PLAYING,
)

MAIN_VOLTAGE_V = 48.0


class Snapshot:
    def __init__(self, controller):
        c = controller
        p = c.plant
        self._c = c
        self._p = p
        self.timestamp = c.reported_timestamp
        self.runtime_state = c.script.runtime_state
        self.robot_mode = c.robot_mode
        self.safety_mode = c.safety_mode
        self.safety_status_bits = c.safety_status_bits
        self.output_int_registers = c.registers.output_int
        self.output_double_registers = c.registers.output_double
        self.output_bit_registers = c.registers.output_bits
        self.actual_execution_time = c.last_execution_time_s * 1000.0
        self.target_execution_time = c.dt * 1000.0
        self._tcp = None
        self._joint_vectors()

    # ------------------------------------------------------------ joints
    def _joint_vectors(self) -> None:
        # All joint vectors in one numpy call: per-field properties cost more than the arithmetic
        # (this runs every cycle for every recipe that has a package due).
        p = self._p
        (self.actual_q, self.target_q, self.actual_qd, self.target_qdd, self.actual_current,
         self.target_current, self.target_moment, self.joint_control_output,
         self.actual_current_as_torque, self.joint_temperatures) = np.stack([
            p.measured_q, p.q, p.qd, p.qdd, p.measured_current, p.target_current, p.target_moment,
            p.current, p.compensated_torque, p.temperatures]).tolist()
        self.target_qd = self.actual_qd

    @property
    def target_gravity(self):
        # UR's set_gravity convention (pointing away from the Earth's centre); sign unconfirmed
        return (-np.asarray(self._p.spec.gravity, dtype=float)).tolist()

    @property
    def actual_current_window(self):
        return (0.5 + 0.1 * np.abs(self._p.target_current)).tolist()

    @property
    def actual_joint_voltage(self):
        return [MAIN_VOLTAGE_V - 0.05 * abs(i) for i in self.joint_control_output]

    @property
    def joint_mode(self):
        powered = self.robot_mode == ROBOT_MODE_RUNNING
        return [JOINT_MODE_RUNNING if powered else JOINT_MODE_POWER_OFF] * 6

    # ------------------------------------------------------------ Cartesian
    @property
    def _actual_tcp(self):
        # One forward-kinematics evaluation serves actual and target: they differ only by the
        # encoder quantization (~1e-5 m at the TCP).
        if self._tcp is None:
            self._tcp = self._c.kinematics.tcp(self._p.q, self._p.qd, self._c.tcp_offset)
        return self._tcp

    @property
    def _target_tcp(self):
        return self._actual_tcp

    @property
    def actual_TCP_pose(self):
        return self._actual_tcp[0].tolist()

    @property
    def actual_TCP_speed(self):
        return self._actual_tcp[1].tolist()

    @property
    def target_TCP_pose(self):
        return self._target_tcp[0].tolist()

    @property
    def target_TCP_speed(self):
        return self._target_tcp[1].tolist()

    @property
    def elbow_position(self):
        return self._actual_tcp[2].tolist()

    @property
    def elbow_velocity(self):
        return self._actual_tcp[3].tolist()

    @property
    def actual_tool_accelerometer(self):
        rotation = self._actual_tcp[4]
        return (rotation.T @ np.array([0.0, 0.0, 9.81])).tolist()

    @property
    def tcp_offset(self):
        return list(self._c.tcp_offset)

    actual_TCP_force = property(lambda self: [0.0] * 6)
    ft_raw_wrench = property(lambda self: [0.0] * 6)
    tcp_force_scalar = 0.0
    actual_momentum = 0.0

    # ------------------------------------------------------------ status
    @property
    def robot_status_bits(self):
        bits = ROBOT_STATUS_POWER_ON if self.robot_mode == ROBOT_MODE_RUNNING else 0
        if self.runtime_state == RUNTIME_PLAYING:
            bits |= ROBOT_STATUS_PROGRAM_RUNNING
        return bits

    @property
    def safety_status(self):
        return self.safety_mode

    @property
    def speed_scaling(self):
        return self._c.io.speed_slider_fraction

    @property
    def target_speed_fraction(self):
        return self._c.io.speed_slider_fraction

    @property
    def control_step(self):
        return self._c.tick_count

    @property
    def script_control_line(self):
        return 1 if self.runtime_state == RUNTIME_PLAYING else 0

    # ------------------------------------------------------------ electrical / I/O
    actual_main_voltage = MAIN_VOLTAGE_V
    actual_robot_voltage = MAIN_VOLTAGE_V

    @property
    def actual_robot_current(self):
        return 0.4 + float(np.sum(np.abs(self._p.current))) * 0.1

    @property
    def actual_digital_output_bits(self):
        return self._c.io.digital_output_bits  # bits 0-7 standard, 8-15 configurable, 16-17 tool

    @property
    def actual_configurable_digital_output_bits(self):
        return self._c.io.digital_output_bits >> 8 & 0xFF

    actual_digital_input_bits = 0
    actual_configurable_digital_input_bits = 0
    standard_analog_input0 = 0.0
    standard_analog_input1 = 0.0

    @property
    def standard_analog_output0(self):
        return self._c.io.analog_output[0]

    @property
    def standard_analog_output1(self):
        return self._c.io.analog_output[1]

    @property
    def analog_io_types(self):
        return self._c.io.analog_output_types

    io_current = 0.05
    tool_mode = 0
    tool_temperature = 30.0
    tool_output_voltage = 0
    tool_output_current = 0.0
    tool_analog_input0 = 0.0
    tool_analog_input1 = 0.0
    tool_analog_input_types = 0

    # ------------------------------------------------------------ payload
    @property
    def payload(self):
        return self._c.payload_mass

    @property
    def payload_cog(self):
        return list(self._c.payload_cog)

    @property
    def payload_inertia(self):
        return list(self._c.payload_inertia)
