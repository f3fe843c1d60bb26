"""Checks made before anything moves: the controller is the robot we think it is, at the rate we
think it runs, in a normal state, and the trajectory and the approach to its start are safe.

Pure functions of plain values: the runner gathers the values over RTDE and the dashboard.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.errors import SafetyError
from urident.model import RobotSpec
from urident.session.monitors import ROBOT_MODE_RUNNING, safety_problem

SAFETY_MODE_NORMAL = 1
ROBOT_MODE_NAMES = {-1: "no controller", 0: "disconnected", 1: "confirm safety", 2: "booting",
                    3: "power off", 4: "power on", 5: "idle", 6: "backdrive", 7: "running",
                    8: "updating firmware"}


@dataclass(frozen=True)
class ApproachPlan:
    q_now: np.ndarray
    q_start: np.ndarray
    max_joint_distance_rad: float
    joint: int                      # joint (0-based) with the largest distance
    min_margin_m: float | None      # smallest (distance − required clearance) along the path [m]


def check_controller(spec: RobotSpec, version: tuple[int, ...], rate_hz: float,
                     robot_model: str | None) -> None:
    """The controller's generation, rate and model must match the robot file."""
    version_text = ".".join(map(str, version))
    is_cb3 = version[0] <= 3
    if spec.generation == "cb3" and not is_cb3:
        raise SafetyError(f"controller {version_text} is an e-Series controller, but robot "
                          f"'{spec.name}' is a CB3 robot: check --robot")
    if spec.generation == "e-series" and is_cb3:
        raise SafetyError(f"controller {version_text} is a CB3 controller, but robot "
                          f"'{spec.name}' is an e-Series robot: check --robot")
    if abs(rate_hz - spec.controller_rate_hz) > 1e-6:
        raise SafetyError(f"controller {version_text} runs RTDE at {rate_hz:g} Hz, the robot file "
                          f"of '{spec.name}' says {spec.controller_rate_hz:g} Hz")
    if robot_model:
        reported = robot_model.strip().lower().replace(" ", "")
        # The file's arm model ("UR5e"), as e-Series dashboards report it ("UR5").
        expected = (spec.model or spec.name).lower()
        if reported not in (expected, spec.dashboard_model.lower()):
            raise SafetyError(f"the controller reports robot model '{robot_model.strip()}', "
                              f"but --robot is '{spec.name}' ({spec.model or spec.name})")


#: A declared payload heavier than the checked one by more than this [kg] is refused (rounding).
DECLARED_PAYLOAD_TOLERANCE_KG = 1e-3


def check_declared_payload(declared_kg: float | None, checked_kg: float, trajectory: str) -> None:
    """The payload the controller was told (RTDE target payload) must not be heavier than the one
    the trajectory's torques were checked with (lighter loads are covered: the check holds with
    and without its load); ``declared_kg`` None: the controller publishes none."""
    if declared_kg is not None and declared_kg > checked_kg + DECLARED_PAYLOAD_TOLERANCE_KG:
        raise SafetyError(f"the controller declares a payload of {declared_kg:g} kg, heavier than the "
                          f"{checked_kg:g} kg {trajectory} was checked with: nothing was moved (check "
                          f"it with the mounted load: --payload-mass {declared_kg:g} or --payload FILE)")


def check_robot_state(robot_mode: int, safety_mode: int, safety_bits: int) -> None:
    if robot_mode != ROBOT_MODE_RUNNING:
        name = ROBOT_MODE_NAMES.get(robot_mode, str(robot_mode))
        raise SafetyError(f"robot mode is '{name}' ({robot_mode}), not 'running': power on and "
                          f"release the brakes first")
    problem = safety_problem(safety_bits)
    if problem:
        raise SafetyError(f"robot is not ready: {problem}")
    if safety_mode != SAFETY_MODE_NORMAL:
        raise SafetyError(f"safety mode is {safety_mode}, not normal (1)")


def plan_approach(spec: RobotSpec, q_now: np.ndarray, q_start: np.ndarray, max_distance_rad: float,
                  margin_fn=None) -> ApproachPlan:
    """Check the moveJ from the current pose to the trajectory start: joint distance within
    ``max_distance_rad`` and, when ``margin_fn`` (q (N, 6) → smallest distance minus required
    clearance (N,) [m]) is given, every pose of the straight joint-space path keeps its clearance."""
    q_now = np.asarray(q_now, dtype=float)
    q_start = np.asarray(q_start, dtype=float)
    if q_now.shape != (6,) or not np.all(np.isfinite(q_now)):
        raise SafetyError(f"the controller reports an invalid joint position {q_now}")
    for j in range(6):
        if not spec.q_min[j] <= q_now[j] <= spec.q_max[j]:
            raise SafetyError(f"joint {j + 1} is at {q_now[j]:.3f} rad, outside the robot file's "
                              f"limits [{spec.q_min[j]:.3f}, {spec.q_max[j]:.3f}]")
    distance = np.abs(q_start - q_now)
    joint = int(np.argmax(distance))
    if distance[joint] > max_distance_rad:
        raise SafetyError(f"the trajectory starts {distance[joint]:.2f} rad away on joint {joint + 1} "
                          f"(limit approach.max_distance_rad = {max_distance_rad}): move the robot "
                          f"closer to {np.round(q_start, 3).tolist()} first")
    margin = None
    if margin_fn is not None:
        steps = max(2, int(np.ceil(distance[joint] / 0.01)) + 1)  # every 0.01 rad
        path = q_now + np.linspace(0.0, 1.0, steps)[:, None] * (q_start - q_now)
        margins = np.asarray(margin_fn(path))
        k = int(np.argmin(margins))
        margin = float(margins[k])
        if margin < 0:
            raise SafetyError(f"the approach to the start violates the collision clearance by "
                              f"{-margin:.3f} m at {np.round(path[k], 3).tolist()}: move the robot "
                              f"to a pose near the start first")
    return ApproachPlan(q_now, q_start, float(distance[joint]), joint, margin)
