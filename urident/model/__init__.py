"""Robot model: robot files, Pinocchio models, the paper's regressor and base parameters."""

from urident.model.parameters import parameter_names
from urident.model.regressor import DEFAULT_FRICTION_EPS, joint_torques, regressor, regressor_blocks
from urident.model.robot import RobotSpec, available_robots, load_robot

__all__ = [
    "DEFAULT_FRICTION_EPS",
    "RobotSpec",
    "available_robots",
    "joint_torques",
    "load_robot",
    "parameter_names",
    "regressor",
    "regressor_blocks",
]
