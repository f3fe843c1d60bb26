"""Sessions on a robot over RTDE (the only package that imports ur_rtde): pre-motion checks,
the servoJ loop with monitors, and the log. ``run_session`` runs ur_rtde in a supervised child
process (``supervisor``); ``runner.run_local`` runs a session in the calling process."""

from urident.session.config import ExperimentConfig, load_experiment_config
from urident.session.runner import RunRequest, RunResult
from urident.session.supervisor import run_session

__all__ = ["ExperimentConfig", "RunRequest", "RunResult", "load_experiment_config", "run_session"]
