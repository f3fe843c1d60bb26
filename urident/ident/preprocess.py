"""Preprocessing of a recording for identification: accelerations, torques, trimming, decimation.

Accelerations (paper eq. 46). The paper filters with y = s/(s/w + 1)·u, w = 2πf, and Matlab's
``filtfilt``. Running ``filtfilt`` on that differentiator directly does *not* give a derivative:
the backward pass differentiates the time-reversed signal, so the result is −d²/dt² of the input
(on q̇ it would be minus the jerk). We therefore split the filter as s · L(s) with the low-pass
L(s) = 1/(s/w + 1): L is discretised by the bilinear transform (corner pre-warped so it stays at f)
at the log's median rate and run forward and backward (``scipy.signal.filtfilt``, zero phase,
magnitude |L|²), then the derivative s is taken by central differences on the *actual* timestamps
(``numpy.gradient(v, t)``), which is also zero phase.

Jittery timestamps (the UR10e logs: 100 Hz, 2–34 ms jitter). The timestamps are the true sample
times: on those logs ``gradient(q, t_actual)`` matches the controller's q̇ ten times better (RMS
0.004 rad/s) than a uniform grid does (0.04 rad/s). Filtering in sample index on a jittery grid turns
the jitter into noise (each output becomes an average over a randomly shifted time window), so when
the steps deviate from their median by more than 1 %, the signal is interpolated (linearly) onto a
uniform grid at the median rate, filtered and differentiated there, and the result interpolated
back to the original sample times. The sample set is therefore unchanged (the reference figures are
defined on it), and with a uniform log the grid is the log itself. A bag's header stamps are such
sample times too (the ros2_control cycle that read the state; its wake-up latency and catch-up
are jitter of this kind: ``benchmarks/bag_jitter.py`` measures the effect). Stamps that come in
bunches (receive times of DDS batches) have no median period; the grid then takes the gap rule's
nominal period.

Causal mode (a stream: the live view of a running session has no future samples, so no
zero-phase filter): the same filter s·L(s) at the same corner, run forwards only
(:class:`CausalAcceleration`): backward difference of q̇ on the actual timestamps through L
discretised on each step's actual Δt, y ← y + (1 − exp(−w·Δt))·(u − y). It lags by about 1/w
(16 ms at 10 Hz) and has magnitude |L| instead of |L|²; the first sample's q̈ is 0.

Torques: the log's joint torques when it carries valid ones, else τ = drive_gains · current
(:func:`urident.ident.torque.measured_torque`, ``--signal``), optionally low-passed with
the same zero-phase L (``torque_filter_hz``). ``torque_lead_s``: the measured torque leads the motion
by that time (``--preset auto`` chooses it by CV: about 8 ms on the UR10e logs, a simulated arm's
lagging current gives −2 to −4 ms); the torque at t is paired with q, q̇ (so q̈) at t + lead,
interpolated on the actual timestamps (:func:`lead_motion`). The causal mode ignores it (a stream
has no later motion; the live view's prediction is then that much out of step). Rest trimming
drops leading and trailing samples where every |q̇_j| is below ``rest_threshold``; decimation
keeps every k-th sample after filtering.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np
import scipy.signal

from urident.errors import ConfigError, LogFormatError

MIN_SAMPLES = 20
MAX_TORQUE_LEAD_S = 0.05


def lead_motion(t: np.ndarray, x: np.ndarray, lead_s: float, segment: np.ndarray | None = None) -> np.ndarray:
    """(N, k) ``x`` at t + ``lead_s`` (linear interpolation on the actual timestamps, each
    ``segment`` on its own, held at its ends): the motion the torque at t belongs to when the
    measured torque leads the motion by ``lead_s``. The motion is shifted, not the torque: the
    motion signals are smooth, so interpolating them changes nothing else, while interpolating
    the noisy torque between samples would average its noise away and lower any error scored
    on it (a fractional shift of the UR10e torques lowered CV 1.27 -> 0.97 N·m that way)."""
    if lead_s == 0:
        return x
    out = np.empty_like(x)
    seg = np.zeros(len(t), dtype=int) if segment is None else segment
    for s in np.unique(seg):
        k = seg == s
        for j in range(x.shape[1]):
            out[k, j] = np.interp(t[k] + lead_s, t[k], x[k, j])
    return out


def with_acceleration_corner(data: "Prepared", filter_hz: float, prewarp: bool = True) -> "Prepared":
    """``data`` with q̈ recomputed from its q̇ by the acceleration filter at ``filter_hz``
    (:func:`accelerations`, each segment on its own)."""
    qdd = np.empty_like(data.qdd)
    for s in np.unique(data.segment):
        k = data.segment == s
        qdd[k] = accelerations(data.t[k], data.qd[k], filter_hz, prewarp)
    return replace(data, qdd=qdd)


def with_torque_lead(data: "Prepared", lead_s: float) -> "Prepared":
    """``data`` with its motion (q, q̇, q̈) taken ``lead_s`` later (:func:`lead_motion`)."""
    if lead_s == 0:
        return data
    return replace(data, **{k: lead_motion(data.t, getattr(data, k), lead_s, data.segment)
                            for k in ("q", "qd", "qdd")})


@dataclass(frozen=True)
class PreprocessConfig:
    """Options of :func:`preprocess` (SI units)."""

    filter_hz: float = 10.0                 # corner of the paper's filter (accelerations)
    torque_filter_hz: float | None = None   # zero-phase low-pass of the torques (None: off)
    decimate: int = 1                       # keep every k-th sample after filtering
    trim_rest: bool = True                  # drop leading/trailing samples at rest
    rest_threshold: float = 1e-3            # [rad/s] "at rest": all |q̇_j| below this
    prewarp: bool = True                    # bilinear transform with the corner pre-warped
    torque_lead_s: float = 0.0              # [s] the torque at t is paired with the motion at t + lead

    def __post_init__(self) -> None:
        if not (np.isfinite(self.filter_hz) and self.filter_hz > 0):
            raise ConfigError(f"filter_hz must be positive, not {self.filter_hz}")
        if self.torque_filter_hz is not None and not self.torque_filter_hz > 0:
            raise ConfigError(f"torque_filter_hz must be positive, not {self.torque_filter_hz}")
        if int(self.decimate) != self.decimate or self.decimate < 1:
            raise ConfigError(f"decimate must be a positive integer, not {self.decimate}")
        if not self.rest_threshold >= 0:
            raise ConfigError(f"rest_threshold must not be negative, not {self.rest_threshold}")
        if not (np.isfinite(self.torque_lead_s) and abs(self.torque_lead_s) <= MAX_TORQUE_LEAD_S):
            raise ConfigError(f"torque_lead_s must be within ±{MAX_TORQUE_LEAD_S} s, not {self.torque_lead_s}")


@dataclass(frozen=True)
class Provenance:
    """Where a prepared data set came from."""

    file: str
    rows: tuple[int, int] | None
    sha256: str | None
    samples_used: tuple[int, int]   # [first, last) indices into the loaded recording
    signal: str | None = None       # where the torques came from (urident.ident.torque.SIGNAL_TEXT)

    def as_dict(self) -> dict:
        out = {"file": self.file, "rows": None if self.rows is None else list(self.rows),
               "sha256": self.sha256, "samples_used": list(self.samples_used)}
        if self.signal is not None:
            out["signal"] = self.signal
        return out


@dataclass(frozen=True)
class Prepared:
    """Identification-ready data: ``t (N,)``, ``q, qd, qdd, tau (N, 6)`` float64, SI units.
    ``segment (N,)`` numbers the contiguous pieces (one per log) so that concatenated logs are
    never differentiated or filtered across a seam. ``temperature (N, 6)`` °C: the logged joint
    temperatures when every log carried finite ones, else None (never filled in)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    drive_gains: np.ndarray
    provenance: tuple[Provenance, ...] = ()
    segment: np.ndarray = field(default=None)  # type: ignore[assignment]
    temperature: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.segment is None:
            object.__setattr__(self, "segment", np.zeros(len(self.t), dtype=int))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_samples(self) -> int:
        return len(self)

    def select(self, index) -> "Prepared":
        return replace(self, t=self.t[index], q=self.q[index], qd=self.qd[index],
                       qdd=self.qdd[index], tau=self.tau[index], segment=self.segment[index],
                       temperature=None if self.temperature is None else self.temperature[index])


def lowpass_coefficients(cutoff_hz: float, fs: float, prewarp: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of L(s) = 1/(s/w + 1), w = 2π·cutoff, by the bilinear transform at rate ``fs``."""
    if not cutoff_hz < fs / 2:
        raise ConfigError(f"filter corner {cutoff_hz} Hz must be below the Nyquist frequency "
                          f"{fs / 2:g} Hz of the log")
    w = 2 * np.pi * cutoff_hz
    if prewarp:
        w = 2 * fs * np.tan(w / (2 * fs))
    b, a = scipy.signal.bilinear([1.0], [1.0 / w, 1.0], fs)
    return np.asarray(b), np.asarray(a)


def _period(t: np.ndarray) -> float:
    """The median step, unless stamps come in bunches (a bag's receive times, delivered in DDS
    batches), where it is no period: then the gap rule's nominal period over spans."""
    dt = np.diff(t)
    med = float(np.median(dt))
    if med >= 0.5 * (t[-1] - t[0]) / dt.size:
        return med
    from urident.logs.gaps import nominal_period

    return float(nominal_period(t))


def sample_rate(t: np.ndarray) -> float:
    """Median sample rate [Hz] of timestamps ``t`` (bunched stamps: :func:`_period`)."""
    t = np.asarray(t, dtype=float)
    dt = np.diff(t)
    if dt.size == 0 or not np.all(dt > 0):
        raise LogFormatError("timestamps must be strictly increasing")
    return float(1.0 / _period(t))


def zero_phase_lowpass(x: np.ndarray, fs: float, cutoff_hz: float, prewarp: bool = True) -> np.ndarray:
    """``filtfilt`` of L(s) along axis 0 of uniformly sampled ``x`` (magnitude |L|², zero phase)."""
    b, a = lowpass_coefficients(cutoff_hz, fs, prewarp)
    return scipy.signal.filtfilt(b, a, np.asarray(x, dtype=float), axis=0)


def _uniform_grid(t: np.ndarray) -> np.ndarray | None:
    """A uniform grid at the median rate covering ``t``, or None when ``t`` is uniform within 1 %."""
    dt = np.diff(t)
    med = _period(t)
    if np.max(np.abs(dt / med - 1.0)) <= 0.01:
        return None
    n = int(np.floor((t[-1] - t[0]) / med + 1e-9)) + 1
    return t[0] + med * np.arange(n)


def _interp(t_new: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t_new, t, x[:, j]) for j in range(x.shape[1])], axis=1)


def lowpass_t(t: np.ndarray, x: np.ndarray, cutoff_hz: float, prewarp: bool = True) -> np.ndarray:
    """Zero-phase low-pass of (N, k) samples at times ``t`` (jitter handled, module doc)."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    fs = sample_rate(t)
    grid = _uniform_grid(t)
    if grid is None:
        return zero_phase_lowpass(x, fs, cutoff_hz, prewarp)
    return _interp(t, grid, zero_phase_lowpass(_interp(grid, t, x), fs, cutoff_hz, prewarp))


def accelerations(t: np.ndarray, qd: np.ndarray, filter_hz: float = 10.0, prewarp: bool = True) -> np.ndarray:
    """(N, 6) accelerations: zero-phase version of the paper's s/(s/w + 1) applied to q̇ (module doc)."""
    t = np.asarray(t, dtype=float)
    qd = np.asarray(qd, dtype=float)
    if len(t) < MIN_SAMPLES:
        raise LogFormatError(f"need at least {MIN_SAMPLES} samples to filter, got {len(t)}")
    fs = sample_rate(t)
    grid = _uniform_grid(t)
    if grid is None:
        return np.gradient(zero_phase_lowpass(qd, fs, filter_hz, prewarp), t, axis=0)
    v = zero_phase_lowpass(_interp(grid, t, qd), fs, filter_hz, prewarp)
    return _interp(t, grid, np.gradient(v, grid, axis=0))


class CausalAcceleration:
    """q̈ of a stream, causal mode of :func:`accelerations` (module doc); feed batches in time order,
    any split gives the same result. Samples whose time does not increase keep the last estimate."""

    def __init__(self, filter_hz: float = 10.0):
        if not (np.isfinite(filter_hz) and filter_hz > 0):
            raise ConfigError(f"filter_hz must be positive, not {filter_hz}")
        self.w = 2 * np.pi * float(filter_hz)
        self._t: float | None = None
        self._qd: np.ndarray | None = None
        self._y = np.zeros(6)

    def update(self, t: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """(n, 6) accelerations of samples ``t (n,)``, ``qd (n, 6)``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        qd = np.asarray(qd, dtype=float).reshape(-1, 6)
        out = np.empty_like(qd)
        for k in range(len(t)):
            tk, v = float(t[k]), qd[k]
            if self._t is not None and tk > self._t:
                dt = tk - self._t
                self._y = self._y + (1.0 - np.exp(-self.w * dt)) * ((v - self._qd) / dt - self._y)
            if self._t is None or tk > self._t:
                self._t, self._qd = tk, v.copy()
            out[k] = self._y
        return out


def rest_trim_range(qd: np.ndarray, threshold: float) -> tuple[int, int]:
    """[first, last) of the samples between the first and the last one where some |q̇_j| ≥ threshold."""
    moving = np.flatnonzero(np.any(np.abs(qd) >= threshold, axis=1))
    if moving.size == 0:
        return 0, 0
    return int(moving[0]), int(moving[-1]) + 1


def file_sha256(path: Path | None) -> str | None:
    """SHA-256 of a log file (None for a recording that has no file)."""
    from urident.logs.sidecar import sha256_file

    if path is None or not Path(path).is_file():
        return None
    return sha256_file(path)


def _check_finite(name: str, x: np.ndarray, source: str) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise LogFormatError(f"{source}: {name} holds NaN/inf (sample {row})")


def preprocess(recording, spec, config: PreprocessConfig | None = None,
               drive_gains: Sequence[float] | None = None, tau: np.ndarray | None = None,
               causal: bool = False, signal: str | None = None) -> Prepared:
    """One :class:`urident.logs.Recording` → :class:`Prepared`. Torques are the recording's joint
    torques when it carries valid ones, else the current times the drive gains (the robot file's,
    or ``drive_gains``): :func:`urident.ident.torque.measured_torque`, ``signal`` forces one;
    pass ``tau`` (N, 6) to use other torques. The recording's ``robot`` must match ``spec``. ``causal``: accelerations by
    the causal mode (module doc; no torque filter then)."""
    from urident.ident.torque import SIGNAL_TEXT, measured_torque, resolve_drive_gains, torque_signal

    config = config or PreprocessConfig()
    source = str(recording.source) if recording.source is not None else "<recording>"
    if recording.robot is not None and recording.robot != spec.name:
        raise ConfigError(f"{source}: recorded on robot {recording.robot!r}, identifying {spec.name!r}")
    t = np.asarray(recording.t, dtype=float)
    if len(t) < MIN_SAMPLES:
        raise LogFormatError(f"{source}: {len(t)} samples, need at least {MIN_SAMPLES}")
    for name in ("q", "qd", "current"):
        _check_finite(name, getattr(recording, name), source)
    gains = resolve_drive_gains(spec, drive_gains)
    torque = measured_torque(recording, gains, signal, spec) if tau is None else np.asarray(tau, float)
    _check_finite("tau", torque, source)
    lead = 0.0 if causal else config.torque_lead_s   # a stream has no later motion to pair
    qd = lead_motion(t, np.asarray(recording.qd, dtype=float), lead)
    if causal and config.torque_filter_hz is not None:
        raise ConfigError("the causal mode has no torque filter (torque_filter_hz must be None)")
    try:
        if causal:
            sample_rate(t)  # strictly increasing, as the zero-phase mode demands
            qdd = CausalAcceleration(config.filter_hz).update(t, qd)
        else:
            qdd = accelerations(t, qd, config.filter_hz, config.prewarp)
        if config.torque_filter_hz is not None:
            torque = lowpass_t(t, torque, config.torque_filter_hz, config.prewarp)
    except LogFormatError as exc:
        raise LogFormatError(f"{source}: {exc}") from None
    except ConfigError as exc:   # a corner above this log's Nyquist: a parameters file's, or --filter-hz
        raise ConfigError(f"{source}: {exc} (a parameters file records the corner it was identified "
                          "with; --filter-hz sets another)") from None
    first, last = (0, len(t))
    if config.trim_rest:
        first, last = rest_trim_range(qd, config.rest_threshold)
        if last - first < MIN_SAMPLES:
            raise LogFormatError(f"{source}: the robot hardly moves (fewer than {MIN_SAMPLES} samples "
                                 f"with some |qd| >= {config.rest_threshold} rad/s)")
    sl = slice(first, last, int(config.decimate))
    rows = recording.metadata.get("rows") if hasattr(recording, "metadata") else None
    used = "given torques" if tau is not None else SIGNAL_TEXT[torque_signal(recording, signal)]
    prov = Provenance(source, None if rows is None else tuple(int(r) for r in rows),
                      file_sha256(recording.source), (first, last), used)
    temperature = _temperature(recording)
    q = lead_motion(t, np.asarray(recording.q, float), lead)
    return Prepared(t[sl].copy(), q[sl].copy(), qd[sl].copy(),
                    qdd[sl].copy(), torque[sl].copy(), gains, (prov,),
                    temperature=None if temperature is None else temperature[sl].copy())


def _temperature(recording) -> np.ndarray | None:
    """The recording's (N, 6) joint temperatures [°C], or None when it has none or any is not finite
    (a model with temperature terms then says the log lacks them rather than using a filler)."""
    temperature = getattr(recording, "temperature", None)
    if temperature is None:
        return None
    temperature = np.asarray(temperature, dtype=float)
    return temperature if np.all(np.isfinite(temperature)) else None


def preprocess_pieces(recording, spec, config: PreprocessConfig | None = None,
                      drive_gains: Sequence[float] | None = None,
                      causal: bool = False) -> list[tuple[int, Prepared]]:
    """:func:`preprocess` each gap-free piece of ``recording`` on its own (nothing is
    differentiated or filtered across a gap), as several recordings are; returns
    ``(offset, prepared)`` pairs, ``offset`` the piece's first sample in ``recording`` (add it to
    a piece's ``samples_used``). Pieces too short or at rest are left out when another is usable."""
    from urident.logs.gaps import piece_bounds

    bounds = piece_bounds(recording)
    if len(bounds) == 1:
        return [(0, preprocess(recording, spec, config, drive_gains, causal=causal))]
    out, first_error = [], None
    for a, b in bounds:
        try:
            out.append((a, preprocess(recording.select(slice(a, b)), spec, config, drive_gains,
                                      causal=causal)))
        except LogFormatError as exc:
            first_error = first_error or exc
    if not out:
        raise first_error
    return out


def concatenate(parts: Sequence[Prepared]) -> Prepared:
    """Several prepared logs as one data set (segments numbered in order)."""
    if not parts:
        raise ConfigError("no data to identify from")
    if len(parts) == 1:
        return parts[0]
    gains = parts[0].drive_gains
    for p in parts[1:]:
        if not np.allclose(p.drive_gains, gains):
            raise ConfigError("logs prepared with different drive gains cannot be combined")
    seg = np.concatenate([np.full(len(p), k) for k, p in enumerate(parts)])
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    temperature = None if any(p.temperature is None for p in parts) else cat("temperature")
    return Prepared(cat("t"), cat("q"), cat("qd"), cat("qdd"), cat("tau"), gains,
                    tuple(pr for p in parts for pr in p.provenance), seg, temperature)
