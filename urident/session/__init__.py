"""Sessions on a robot over RTDE (the only package that imports ur_rtde): pre-motion checks,
the servoJ loop with monitors, and the log."""

from urident.session.config import ExperimentConfig, load_experiment_config
from urident.session.runner import RunRequest, RunResult, run_session

__all__ = ["ExperimentConfig", "RunRequest", "RunResult", "load_experiment_config", "run_session"]
