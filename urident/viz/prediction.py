"""Predicted joint torques for the views, from pluggable sources.

Two shapes of predictor are used:

* a **torque model** ``(q, qd, qdd) -> tau (N, 6)`` built by :func:`torque_model` from a 78-vector
  of standard parameters, a base-parameter vector (full or the paper's reduced model, told apart
  by its length) or any callable of that signature. The live streamer uses it with a causal q̈.
* a **recording predictor** ``(recording) -> tau_pred (N, 6)``, what ``urident view`` and the
  post-hoc API take. Until ``urident.ident`` provides its own ``predict``, :func:`recording_predictor`
  builds one from a torque model and :func:`zero_phase_acceleration`.

Acceleration estimates:

* post-hoc, :func:`zero_phase_acceleration`: central differences of q̇, then a 4th-order
  Butterworth low-pass run forwards and backwards (zero phase), cutoff ``cutoff_hz`` (10 Hz);
* live, :class:`CausalAcceleration`: backward difference of q̇ through a first-order low-pass
  ``y += dt/(T + dt) · (Δq̇/Δt − y)`` with ``T = 1/(2π f_c)``, ``f_c`` = 15 Hz by default. It lags
  by about T (≈ 11 ms at 15 Hz), so the live predicted torque's inertial part lags slightly; the
  post-hoc view has no lag.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable

import numpy as np

from urident.errors import ConfigError
from urident.model.robot import N_PARAMS, RobotSpec

TorqueModel = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
RecordingPredictor = Callable[[Any], np.ndarray]

DEFAULT_POSTHOC_CUTOFF_HZ = 10.0
DEFAULT_LIVE_CUTOFF_HZ = 15.0


class _LinearModel:
    """``tau = Θ(q, q̇, q̈)[:, :, columns] @ values`` (picklable, for the live process)."""

    def __init__(self, spec: RobotSpec, values: np.ndarray, columns: np.ndarray | None,
                 friction_eps: float | None):
        self.spec = spec
        self.values = np.asarray(values, dtype=float)
        self.columns = columns
        self.friction_eps = friction_eps

    def __call__(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        from urident.model.regressor import DEFAULT_FRICTION_EPS, regressor_blocks

        eps = DEFAULT_FRICTION_EPS if self.friction_eps is None else self.friction_eps
        blocks = regressor_blocks(self.spec, q, qd, qdd, eps)
        if self.columns is not None:
            blocks = blocks[..., self.columns]
        return blocks @ self.values


def torque_model(spec: RobotSpec, params: Any = None,
                 friction_eps: float | None = None) -> TorqueModel:
    """A ``(q, qd, qdd) -> tau`` model: ``params`` None (the robot file's nominal parameters), a
    78-vector, a base-parameter vector of the full or reduced model, or a callable (returned as
    it is)."""
    if params is None:
        return _LinearModel(spec, spec.nominal_params, None, friction_eps)
    if callable(params):
        return params
    values = np.asarray(params, dtype=float).reshape(-1)
    if not np.all(np.isfinite(values)):
        raise ConfigError("prediction parameters hold NaN or infinite values")
    if values.size == N_PARAMS:
        return _LinearModel(spec, values, None, friction_eps)
    from urident.model.base import base_parameters

    sizes = []
    for reduced in (False, True):
        base = base_parameters(spec, reduced=reduced)
        sizes.append(base.n_base)
        if values.size == base.n_base:
            return _LinearModel(spec, values, np.asarray(base.independent), friction_eps)
    raise ConfigError(f"prediction parameters: expected {N_PARAMS} standard or {sizes[0]} / "
                      f"{sizes[1]} base parameters of {spec.name}, got {values.size} values")


class _IdentifiedTorqueModel:
    """``urident.ident``'s prediction for a loaded PARAMS.yaml (picklable)."""

    def __init__(self, identified: Any, spec: RobotSpec):
        from urident.ident.identify import check_compatible

        check_compatible(identified, spec)
        self.identified = identified
        self.spec = spec

    def __call__(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        from urident.ident.identify import predict

        return predict(self.identified, self.spec, q, qd, qdd)


def _is_ident_params_file(path: Path) -> bool:
    if path.suffix.lower() not in (".yaml", ".yml"):
        return False
    with open(path, encoding="utf-8", errors="replace") as fh:
        head = fh.read(4096)
    return "urident-params" in head


def load_prediction_params(path: str | Path, spec: RobotSpec | None = None) -> Any:
    """Prediction parameters from a file, for :func:`torque_model`: an identification result
    (``urident identify``'s PARAMS.yaml, ``format: urident-params``; needs ``spec``) becomes a
    torque model calling ``urident.ident.identify.predict``; otherwise a plain vector from
    ``.npy``, whitespace/comma text (``.txt``/``.csv``), or JSON/YAML holding a list or a mapping
    with ``params``, ``base_params`` or ``parameters``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: parameter file not found")
    if spec is not None and _is_ident_params_file(path):
        from urident.ident.params_file import load_params

        return _IdentifiedTorqueModel(load_params(path), spec)
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            data: Any = np.load(path, allow_pickle=False)
        elif suffix in (".json", ".yaml", ".yml"):
            from urident.yamlio import parse_yaml, read_text

            text = read_text(path, "parameter file")
            data = json.loads(text) if suffix == ".json" else parse_yaml(text, str(path))
            if data is None or not text.strip():
                raise ConfigError(f"{path}: parameter file is empty")
            if isinstance(data, dict):
                for key in ("params", "base_params", "parameters"):
                    if key in data:
                        data = data[key]
                        break
                else:
                    raise ConfigError(f"{path}: expected a key 'params', 'base_params' or "
                                      "'parameters'")
            if isinstance(data, dict):  # name -> value
                data = list(data.values())
        else:
            data = np.loadtxt(path, delimiter="," if suffix == ".csv" else None, ndmin=1)
        values = np.asarray(data, dtype=float).reshape(-1)
    except ConfigError:
        raise
    except (ValueError, TypeError, OSError) as exc:
        raise ConfigError(f"{path}: cannot read a parameter vector ({exc})") from None
    if values.size == 0:
        raise ConfigError(f"{path}: no parameter values")
    if not np.all(np.isfinite(values)):
        raise ConfigError(f"{path}: parameters hold NaN or infinite values")
    return values


def zero_phase_acceleration(t: np.ndarray, qd: np.ndarray,
                            cutoff_hz: float = DEFAULT_POSTHOC_CUTOFF_HZ) -> np.ndarray:
    """q̈ (N, 6) from q̇ (N, 6): central differences, zero-phase Butterworth low-pass."""
    t = np.asarray(t, dtype=float)
    qd = np.asarray(qd, dtype=float)
    if len(t) < 2:
        return np.zeros_like(qd)
    qdd = np.gradient(qd, t, axis=0)
    dt = float(np.median(np.diff(t)))
    nyquist = 0.5 / dt if dt > 0 else 0.0
    if nyquist > 0 and cutoff_hz < nyquist:
        import scipy.signal

        sos = scipy.signal.butter(4, cutoff_hz / nyquist, output="sos")
        if len(t) > 3 * (2 * len(sos) + 1):
            qdd = scipy.signal.sosfiltfilt(sos, qdd, axis=0)
    return qdd


class CausalAcceleration:
    """Live q̈ estimate: low-passed backward difference of q̇ (see the module docstring)."""

    def __init__(self, cutoff_hz: float = DEFAULT_LIVE_CUTOFF_HZ):
        self.time_constant = 1.0 / (2.0 * np.pi * cutoff_hz)
        self._t: float | None = None
        self._qd: np.ndarray | None = None
        self._y = np.zeros(6)

    def update(self, t: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Feed samples ``t (n,)``, ``qd (n, 6)`` in time order; returns q̈ (n, 6)."""
        out = np.empty_like(qd)
        for k in range(len(t)):
            tk, v = float(t[k]), qd[k]
            if self._t is not None and tk > self._t:
                dt = tk - self._t
                raw = (v - self._qd) / dt
                self._y = self._y + dt / (self.time_constant + dt) * (raw - self._y)
            self._t, self._qd = tk, v
            out[k] = self._y
        return out


def recording_predictor(spec: RobotSpec, params: Any = None,
                        cutoff_hz: float = DEFAULT_POSTHOC_CUTOFF_HZ) -> RecordingPredictor:
    """A ``(recording) -> tau_pred (N, 6)`` predictor from ``params`` (see :func:`torque_model`),
    with q̈ from :func:`zero_phase_acceleration`."""
    model = torque_model(spec, params)

    def predict(recording) -> np.ndarray:
        qdd = zero_phase_acceleration(recording.t, recording.qd, cutoff_hz)
        return np.asarray(model(recording.q, recording.qd, qdd), dtype=float)

    return predict


def measured_torque(spec: RobotSpec, current: np.ndarray) -> np.ndarray:
    """Measured joint torque (N, 6) [N m]: drive gains (i_G · k, from the robot file) × motor
    current (N, 6) [A]."""
    return np.asarray(current, dtype=float) * spec.drive_gains
