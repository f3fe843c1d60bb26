"""Finite Fourier series trajectories (paper eq. 25) that start and end at rest.

Per joint i, with order L, base frequency ω_i and offset q_i,0::

    q_i(t)   = q_i,0 + Σ_l  a_il/(ω_i l) sin(ω_i l t) − b_il/(ω_i l) cos(ω_i l t)
    q̇_i(t)   =         Σ_l  a_il cos(ω_i l t) + b_il sin(ω_i l t)
    q̈_i(t)   =         Σ_l −a_il ω_i l sin(ω_i l t) + b_il ω_i l cos(ω_i l t)

Rest at t = 0 (and at every whole period) is the linear constraint Σ_l a_il = 0 (no velocity) and
Σ_l l·b_il = 0 (no acceleration). :func:`rest_elimination` solves it for a_i1 and b_i1, so the
2(L−1) remaining coefficients per joint are free. Note that the start position is
``q(0) = q0 − Σ_l b_l/(ω l)``, not q0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_JOINTS = 6


@dataclass(frozen=True)
class FourierTrajectory:
    """Eq. (25) for six joints: ``a``, ``b`` (6, L) [rad/s], ``omega`` (6,) [rad/s], ``q0`` (6,)
    [rad], ``duration`` [s]. Use :meth:`evaluate` for q, q̇, q̈ at any times."""

    a: np.ndarray
    b: np.ndarray
    omega: np.ndarray
    q0: np.ndarray
    duration: float

    def __post_init__(self) -> None:
        a = np.array(self.a, dtype=float)
        b = np.array(self.b, dtype=float)
        omega = np.broadcast_to(np.asarray(self.omega, dtype=float), (N_JOINTS,)).copy()
        q0 = np.array(self.q0, dtype=float)
        if a.ndim != 2 or a.shape[0] != N_JOINTS or a.shape[1] < 1 or b.shape != a.shape:
            raise ValueError(f"a and b must both be (6, L) arrays, got {a.shape} and {b.shape}")
        if q0.shape != (N_JOINTS,):
            raise ValueError(f"q0 must have 6 entries, got shape {q0.shape}")
        for name, value in (("a", a), ("b", b), ("omega", omega), ("q0", q0)):
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be finite")
        if not np.all(omega > 0):
            raise ValueError("omega must be positive")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be positive, got {self.duration}")
        for name, value in (("a", a), ("b", b), ("omega", omega), ("q0", q0)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "duration", float(self.duration))

    @property
    def harmonics(self) -> int:
        """The order L of the series."""
        return self.a.shape[1]

    @property
    def q_start(self) -> np.ndarray:
        """(6,) position at t = 0 [rad]; the session moves here with moveJ before streaming."""
        return self.evaluate(np.zeros(1))[0][0]

    @property
    def q_end(self) -> np.ndarray:
        return self.evaluate(np.array([self.duration]))[0][0]

    def evaluate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, q̇, q̈ each (N, 6) at times ``t`` (N,) [s]."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ks = np.arange(1, self.harmonics + 1)
        wl = self.omega[:, None] * ks[None, :]                     # (6, L)
        phase = t[:, None, None] * wl[None]                         # (N, 6, L)
        s, c = np.sin(phase), np.cos(phase)
        q = self.q0 + np.sum((self.a / wl) * s - (self.b / wl) * c, axis=2)
        qd = np.sum(self.a * c + self.b * s, axis=2)
        qdd = np.sum(wl * (self.b * c - self.a * s), axis=2)
        return q, qd, qdd

    def scaled(self, factors: np.ndarray) -> "FourierTrajectory":
        """The same trajectory with joint i's motion about q0 scaled by ``factors[i]``."""
        f = np.asarray(factors, dtype=float)[:, None]
        return FourierTrajectory(self.a * f, self.b * f, self.omega, self.q0, self.duration)

    @classmethod
    def from_free(cls, free: np.ndarray, omega: np.ndarray | float, q0: np.ndarray,
                  duration: float) -> "FourierTrajectory":
        """A trajectory at rest at t = 0 from free coefficients ``free`` (6, 2(L−1)), see
        :func:`rest_elimination`."""
        free = np.asarray(free, dtype=float)
        harmonics = free.shape[1] // 2 + 1
        coeffs = free @ rest_elimination(harmonics).T
        return cls(coeffs[:, :harmonics], coeffs[:, harmonics:], omega, q0, duration)


def rest_elimination(harmonics: int) -> np.ndarray:
    """E (2L, 2(L−1)) with ``[a; b] = E @ [a_2..a_L; b_2..b_L]`` satisfying Σ a_l = 0 and
    Σ l·b_l = 0 (rest at t = 0 and at whole periods)."""
    if harmonics < 2:
        raise ValueError(f"a trajectory at rest at both ends needs at least 2 harmonics, got {harmonics}")
    n = harmonics - 1
    e = np.zeros((2 * harmonics, 2 * n))
    e[0, :n] = -1.0
    e[1:harmonics, :n] = np.eye(n)
    e[harmonics, n:] = -np.arange(2, harmonics + 1)
    e[harmonics + 1:, n:] = np.eye(n)
    return e


def free_coefficients(trajectory: FourierTrajectory) -> np.ndarray:
    """Inverse of :meth:`FourierTrajectory.from_free`: (6, 2(L−1)) (drops a_1, b_1)."""
    return np.concatenate([trajectory.a[:, 1:], trajectory.b[:, 1:]], axis=1)


def base_frequency(duration: float, periods: int = 1) -> float:
    """The base frequency ω [rad/s] that fits ``periods`` whole periods into ``duration``."""
    return 2.0 * np.pi * periods / duration


@dataclass(frozen=True)
class FourierBasis:
    """q − q0, q̇, q̈ of every joint as linear maps of its free coefficients on a fixed time grid:
    arrays (6, N, 2(L−1)), so ``qd[:, :, j] = basis.qd[j] @ free[j]``."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    @classmethod
    def build(cls, t: np.ndarray, omega: np.ndarray | float, harmonics: int) -> "FourierBasis":
        t = np.asarray(t, dtype=float)
        omega = np.broadcast_to(np.asarray(omega, dtype=float), (N_JOINTS,))
        ks = np.arange(1, harmonics + 1)
        wl = omega[:, None] * ks[None, :]                           # (6, L)
        phase = wl[:, None, :] * t[None, :, None]                   # (6, N, L)
        s, c = np.sin(phase), np.cos(phase)
        w = wl[:, None, :]
        e = rest_elimination(harmonics)
        q = np.concatenate([s / w, -c / w], axis=2) @ e
        qd = np.concatenate([c, s], axis=2) @ e
        qdd = np.concatenate([-w * s, w * c], axis=2) @ e
        return cls(t, q, qd, qdd)

    def evaluate(self, free: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q − q0, q̇, q̈ as (B, N, 6) for a batch of free coefficients ``free`` (B, 6, 2(L−1))."""
        free_t = np.ascontiguousarray(np.moveaxis(free, 1, 0))           # (6, B, K)
        return tuple(np.moveaxis(free_t @ np.swapaxes(m, 1, 2), 0, 2)      # (B, N, 6)
                     for m in (self.q, self.qd, self.qdd))

    def evaluate_one(self, free: np.ndarray, which: str = "q qd qdd") -> tuple[np.ndarray, ...]:
        """:meth:`evaluate` of one coefficient set ``free`` (6, 2(L−1)): the arrays named in
        ``which`` (of q − q0, q̇, q̈), each (N, 6); the same products without the batch's axis
        moves (an optimiser's inner loop)."""
        free_t = np.ascontiguousarray(free)[:, None, :]                       # (6, 1, K)
        return tuple((free_t @ np.swapaxes(getattr(self, name), 1, 2))[:, 0, :].T for name in which.split())


def sample_times(duration: float, rate_hz: float) -> np.ndarray:
    """Times ``k / rate_hz`` for k = 0 … ⌊duration·rate⌋ (includes ``duration`` when it is a whole
    number of controller periods)."""
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate must be positive, got {rate_hz}")
    n = int(np.floor(duration * rate_hz + 1e-9))
    return np.arange(n + 1) / rate_hz


def sample(trajectory, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(t, q, qd, qdd)`` at the controller rate: t (N,), the rest (N, 6)."""
    t = sample_times(trajectory.duration, rate_hz)
    return (t, *trajectory.evaluate(t))
