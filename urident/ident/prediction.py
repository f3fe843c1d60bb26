"""The one prediction path: parameters + recordings → the prepared data and the predicted torques.

    params = load_params("params.yaml")                    # or load_prediction_params(path, spec)
    p = predict_recordings(params, [load_log("valid.csv")])
    p.data.tau, p.tau_predicted                            # measured and predicted (N, 6) [N·m]
    p.validation().e_n                                     # metrics: urident.ident.metrics

It uses exactly what the parameters record:

* preprocessing (:func:`prediction_config`): the file's acceleration filter (corner, pre-warp) and
  rest threshold; torques raw (drive gains × current, no low-pass), every sample kept (no
  decimation, no rest trimming) unless the caller overrides a key (the CLI's explicit options);
* drive gains: the file's, unless the caller passes others;
* friction state: the model's history-driven states (Dahl, hold) start at each recording's first
  sample and follow its timestamps (``dahl_source='velocity'`` integrates q̇ on them).

``causal=True`` estimates q̈ with the causal mode of the same filter
(:class:`urident.ident.preprocess.CausalAcceleration`): the live view of a running session has no
future samples. :class:`StreamPredictor` is that mode fed batch by batch, friction state carried
across batches; it gives the same torques as ``predict_recordings(..., causal=True)`` on the whole
log. ``urident validate``, ``gap --params``, ``view``, ``run``'s live view and the demo (through
those commands) all predict here; ``urident.viz`` only draws the arrays.

``payload`` (:class:`urident.model.payload.Payload`, e.g. from ``load_payload``): a tool on the
flange whose torque (:func:`urident.ident.payload.payload_torque`, rigid on body 6) adds to the
arm's prediction; the arm's parameters are of the arm without it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from urident.errors import ConfigError
from urident.ident.design import ModelConfig, column_expressions, column_names
from urident.ident.identify import IdentifiedModel, check_compatible, predict, predict_prepared
from urident.ident.metrics import metrics
from urident.ident.preprocess import (CausalAcceleration, PreprocessConfig, Prepared, concatenate,
                                      preprocess_pieces)
from urident.ident.torque import resolve_drive_gains, torque_from_current
from urident.model.robot import N_PARAMS as N_STANDARD


def prediction_config(params: IdentifiedModel, **overrides) -> PreprocessConfig:
    """The preprocessing that predicts with ``params`` (module doc); ``overrides``: keys of
    :class:`PreprocessConfig` set explicitly (e.g. ``trim_rest=True``)."""
    unknown = sorted(set(overrides) - set(PreprocessConfig.__dataclass_fields__))
    if unknown:
        raise ConfigError(f"preprocessing key {unknown[0]!r} unknown")
    changes = {"trim_rest": False, "torque_filter_hz": None, "decimate": 1}
    changes.update({k: v for k, v in overrides.items() if v is not None})
    return replace(params.preprocess, **changes)


@dataclass(frozen=True)
class Prediction:
    """What :func:`predict_recordings` returns: the prepared data (``data.tau`` is the measured
    torque), the predicted torques on the same samples, and what produced them."""

    data: Prepared
    tau_predicted: np.ndarray     # (N, 6) [N·m]
    params: IdentifiedModel
    config: PreprocessConfig
    causal: bool = False
    pieces: tuple[tuple[int, int], ...] = ()  # per part of ``data``: (recording index, first sample)
    payload: Any = None           # the Payload predicted with, if any

    @property
    def residual(self) -> np.ndarray:
        """Measured minus predicted (N, 6) [N·m]."""
        return self.data.tau - self.tau_predicted

    def validation(self):
        """The metrics as a :class:`urident.ident.validate.ValidationResult`."""
        from urident.ident.validate import ValidationResult

        e_n, rms, rre = metrics(self.data.tau, self.tau_predicted)
        return ValidationResult(self.params.method, self.data.t, self.data.tau, self.tau_predicted,
                                e_n, rms, rre, self.data.provenance)

    def recording_pieces(self) -> tuple[tuple[int, int], ...]:
        """Per segment of ``data``: (recording index, first sample); one piece per recording when
        the prediction was not built by :func:`predict_recordings`."""
        return self.pieces or tuple((j, 0) for j in range(len(self.data.provenance)))

    def sample_index(self, k: int = 0) -> np.ndarray:
        """Indices into the ``k``-th loaded recording of its samples in ``data`` (gap-free pieces
        in order)."""
        step = int(self.config.decimate)
        index = [np.arange(offset + prov.samples_used[0], offset + prov.samples_used[1], step)
                 for (j, offset), prov in zip(self.recording_pieces(), self.data.provenance) if j == k]
        return np.concatenate(index) if index else np.zeros(0, dtype=int)


def _check_payload(payload, spec) -> None:
    if payload is None:
        return
    from urident.ident.payload import check_robot
    from urident.model.payload import Payload

    if not isinstance(payload, Payload):
        raise ConfigError(f"payload must be a Payload (urident.ident.payload), not {type(payload).__name__}")
    check_robot(payload, spec)


def _payload_torque(spec, payload, q, qd, qdd) -> np.ndarray:
    from urident.ident.payload import payload_torque

    return payload_torque(spec, payload, q, qd, qdd)


def _spec_for(params: IdentifiedModel, spec):
    if spec is not None:
        return spec
    from urident.model import load_robot

    return load_robot(params.robot)


def predict_recordings(params: IdentifiedModel, recordings, spec=None, *, payload=None,
                       config: PreprocessConfig | None = None, drive_gains=None,
                       causal: bool = False) -> Prediction:
    """Prepare ``recordings`` (one :class:`urident.logs.Recording` or a sequence, each filtered on
    its own) as ``params`` prescribe and predict their torques (module doc). ``spec``: the robot
    (default: the one ``params`` name); ``config``: the whole preprocessing instead of
    :func:`prediction_config`; ``drive_gains``: instead of the parameters'."""
    spec = _spec_for(params, spec)
    check_compatible(params, spec)
    _check_payload(payload, spec)
    recordings = [recordings] if hasattr(recordings, "current") else recordings
    config = config or prediction_config(params)
    gains = resolve_drive_gains(spec, params.drive_gains if drive_gains is None else drive_gains)
    # an iterator of recordings is consumed one at a time (each freed once prepared)
    parts, pieces = [], []
    for k, recording in enumerate(recordings):
        for offset, p in preprocess_pieces(recording, spec, config, gains, causal=causal):
            parts.append(p)
            pieces.append((k, offset))
    if not parts:
        raise ConfigError("no recording to predict")
    data = concatenate(parts)
    del parts
    require_temperature(params.model, data)
    tau = predict_prepared(params, spec, data)
    if payload is not None:
        tau = tau + _payload_torque(spec, payload, data.q, data.qd, data.qdd)
    return Prediction(data, tau, params, config, causal, tuple(pieces), payload)


def require_temperature(model, data: Prepared) -> None:
    """ConfigError naming the logs when ``model`` has temperature terms and ``data`` no joint
    temperatures (a log without them, or with a non-finite one)."""
    if model.uses_temperature and data.temperature is None:
        files = ", ".join(dict.fromkeys(p.file for p in data.provenance)) or "the data"
        raise ConfigError(f"{files}: the model's friction depends on the joint temperature "
                          "(terms tempvisc/tempcoul), and the log carries no (finite) joint temperature")


class StreamPredictor:
    """:func:`predict_recordings` in causal mode, batch by batch (a running session): q̈ by
    :class:`CausalAcceleration` at the parameters' filter corner, measured torque = the
    parameters' drive gains × current, friction states carried from batch to batch."""

    def __init__(self, params: IdentifiedModel, spec=None, *, payload=None, drive_gains=None):
        self.spec = _spec_for(params, spec)
        check_compatible(params, self.spec)
        _check_payload(payload, self.spec)
        self.payload = payload
        self.params = params
        self.gains = resolve_drive_gains(self.spec,
                                         params.drive_gains if drive_gains is None else drive_gains)
        self._acc = CausalAcceleration(params.preprocess.filter_hz)
        self._state: dict = {}
        self._last: tuple | None = None

    def update(self, t, q, qd, current, temperature=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(qdd, tau_measured, tau_predicted), each (n, 6), for samples in strictly increasing
        time order continuing the previous batch; ``temperature`` (n, 6) °C for models with
        temperature terms."""
        t = np.asarray(t, dtype=float).reshape(-1)
        q = np.asarray(q, dtype=float).reshape(-1, 6)
        qd = np.asarray(qd, dtype=float).reshape(-1, 6)
        tau = torque_from_current(np.asarray(current, dtype=float).reshape(-1, 6), self.gains)
        qdd = self._acc.update(t, qd)
        if len(t) == 0:
            return qdd, tau, np.zeros((0, 6))
        temp = None if temperature is None else np.asarray(temperature, dtype=float).reshape(-1, 6)
        if self._last is None:
            pred = predict(self.params, self.spec, q, qd, qdd, None, t, self._state, temp)
        else:
            # the previous batch's last sample first: the friction states continue from it
            lt, lq, lqd, lqdd, ltemp = self._last
            pred = predict(self.params, self.spec, np.vstack([lq, q]), np.vstack([lqd, qd]),
                           np.vstack([lqdd, qdd]), None, np.r_[lt, t], self._state,
                           None if temp is None else np.vstack([ltemp, temp]))[1:]
        self._last = (t[-1], q[-1], qd[-1], qdd[-1], None if temp is None else temp[-1])
        if self.payload is not None:
            pred = pred + _payload_torque(self.spec, self.payload, q, qd, qdd)
        return qdd, tau, pred


def parameters_from_vector(spec, values, what: str = "prediction parameters",
                           method: str = "given") -> IdentifiedModel:
    """Parameters (paper model: tanh friction, ε = 0.01 rad/s, the default preprocessing and the
    robot file's drive gains) from a 78-vector of standard parameters or a base-parameter vector
    of the full or reduced model (told apart by its length)."""
    from urident.ident.design import base_for

    values = np.asarray(values, dtype=float).reshape(-1)
    if not np.all(np.isfinite(values)):
        raise ConfigError(f"{what} hold NaN or infinite values")
    standard = None
    if values.size == N_STANDARD:
        model = ModelConfig()
        standard = values
        values = base_for(spec, False).from_standard(values)
    else:
        sizes = {reduced: base_for(spec, reduced).n_base for reduced in (False, True)}
        match = [r for r, n in sizes.items() if n == values.size]
        if not match:
            raise ConfigError(f"{what}: expected {N_STANDARD} standard or {sizes[False]} / "
                              f"{sizes[True]} base parameters of {spec.name}, got {values.size} values")
        model = ModelConfig(reduced=match[0])
    return IdentifiedModel(
        robot=spec.name, method=method, model=model, names=tuple(column_names(spec, model)),
        expressions=tuple(column_expressions(spec, model)), values=values,
        sigma=np.full(values.size, np.nan), drive_gains=np.array(spec.drive_gains, dtype=float),
        standard=standard)


def nominal_parameters(spec) -> IdentifiedModel:
    """The robot file's nominal parameters as :func:`parameters_from_vector` makes them."""
    return parameters_from_vector(spec, spec.nominal_params, method="nominal")


def _is_params_file(path: Path) -> bool:
    if path.suffix.lower() not in (".yaml", ".yml"):
        return False
    with open(path, encoding="utf-8", errors="replace") as fh:
        return "urident-params" in fh.read(4096)


def load_prediction_params(path: str | Path, spec) -> IdentifiedModel:
    """Parameters to predict with from a file: ``urident identify``'s PARAMS.yaml
    (``format: urident-params``), or a plain vector for :func:`parameters_from_vector` from
    ``.npy``, whitespace/comma text (``.txt``/``.csv``), or JSON/YAML holding a list or a mapping
    with ``params``, ``base_params`` or ``parameters``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: parameter file not found")
    if _is_params_file(path):
        from urident.ident.params_file import load_params

        params = load_params(path)
        check_compatible(params, spec, str(path))
        return params
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
    except (ValueError, TypeError, OverflowError, OSError) as exc:
        raise ConfigError(f"{path}: cannot read a parameter vector ({exc})") from None
    if values.size == 0:
        raise ConfigError(f"{path}: no parameter values")
    if not np.all(np.isfinite(values)):
        raise ConfigError(f"{path}: parameters hold NaN or infinite values")
    return parameters_from_vector(spec, values, f"{path}: prediction parameters")


def as_parameters(spec, params: Any = None) -> IdentifiedModel:
    """``params`` as :class:`IdentifiedModel`: None (nominal), an IdentifiedModel, or a vector."""
    if params is None:
        return nominal_parameters(spec)
    if isinstance(params, IdentifiedModel):
        check_compatible(params, spec)
        return params
    return parameters_from_vector(spec, params)


__all__ = ["Prediction", "StreamPredictor", "as_parameters", "load_prediction_params",
           "nominal_parameters", "parameters_from_vector", "prediction_config", "predict_recordings"]
