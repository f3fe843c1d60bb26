"""Synthetic identification data: a smooth multi-sine trajectory, torques from the model
(:func:`urident.model.joint_torques`) and Gaussian current noise, with no unmodelled effect.
Used by the tests and the benchmark (the offline simulator lives in ``urident.simcontroller``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MultiSine:
    """q_j(t) = q0_j + Σ_l a_jl sin(2π l f0 t + φ_jl), with analytic q̇ and q̈."""

    q0: np.ndarray          # (6,)
    amplitude: np.ndarray   # (6, L) [rad]
    phase: np.ndarray       # (6, L)
    f0: float               # base frequency [Hz]

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)[:, None, None]
        w = 2 * np.pi * self.f0 * np.arange(1, self.amplitude.shape[1] + 1)
        arg = w * t + self.phase
        q = self.q0 + np.sum(self.amplitude * np.sin(arg), axis=2)
        qd = np.sum(self.amplitude * w * np.cos(arg), axis=2)
        qdd = -np.sum(self.amplitude * w ** 2 * np.sin(arg), axis=2)
        return q, qd, qdd


def random_multisine(spec, rng: np.random.Generator, harmonics: int = 5, f0: float = 0.1,
                     speed_fraction: float = 0.4) -> MultiSine:
    """A random multi-sine whose peak speed per joint is about ``speed_fraction``·q̇_max."""
    q0 = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0, 0.0])
    w = 2 * np.pi * f0 * np.arange(1, harmonics + 1)
    amp = rng.uniform(0.2, 1.0, size=(6, harmonics)) / w
    peak = np.sum(amp * w, axis=1)
    amp *= (speed_fraction * np.minimum(spec.qd_max, 2.0) / peak)[:, None]
    return MultiSine(q0, amp, rng.uniform(0, 2 * np.pi, size=(6, harmonics)), f0)


def synthetic_recording(spec, duration_s: float = 20.0, rate_hz: float = 500.0,
                        current_noise_a: float = 0.02, params: np.ndarray | None = None,
                        seed: int = 0, friction_eps: float = 0.01, trajectory: MultiSine | None = None):
    """(Recording, true qdd (N, 6), true tau (N, 6)) of a multi-sine run; currents = τ/gains + noise."""
    from urident.logs import Recording
    from urident.model import joint_torques

    rng = np.random.default_rng(seed)
    traj = trajectory or random_multisine(spec, rng)
    t = np.arange(int(round(duration_s * rate_hz))) / rate_hz
    q, qd, qdd = traj(t)
    p = spec.nominal_params if params is None else np.asarray(params, dtype=float)
    tau = joint_torques(spec, p, q, qd, qdd, friction_eps)
    current = tau / spec.drive_gains + rng.normal(0.0, current_noise_a, size=tau.shape)
    rec = Recording(t=t, q=q, qd=qd, current=current, robot=spec.name, rate_hz=rate_hz,
                    metadata={"synthetic": True, "seed": seed})
    return rec, qdd, tau
