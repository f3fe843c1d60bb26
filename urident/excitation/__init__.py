"""Excitation trajectories (paper section III-E): Fourier series at rest at both ends, their
optimisation, trajectory files and the dense safety check run before any motion."""

from urident.excitation.check import CheckReport, Violation, check_trajectory
from urident.excitation.constraints import Limits, Margins
from urident.excitation.files import TrajectoryFile, load_trajectory, trajectory_document, write_trajectory
from urident.excitation.fourier import FourierTrajectory, sample, sample_times

__all__ = [
    "CheckReport",
    "FourierTrajectory",
    "Limits",
    "Margins",
    "TrajectoryFile",
    "Violation",
    "check_trajectory",
    "load_trajectory",
    "sample",
    "sample_times",
    "trajectory_document",
    "write_trajectory",
]
