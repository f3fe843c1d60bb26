"""High-level identification: prepared data → :class:`IdentifiedModel`, and prediction from it.

    spec = load_robot("ur10e")
    data = prepare([load_log(path, robot="ur10e", rows=(635, 3510), format="dynamic_calibration")], spec)
    models = identify_all(spec, data, ("ols", "bounded", "consistent"))
    tau_hat = predict(models["ols"], spec, q, qd, qdd)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from urident.errors import ConfigError
from urident.ident.design import (ModelConfig, base_for, column_expressions, column_kinds, column_names,
                                  design_chunks, design_matrix, nonnegative_mask)
from urident.ident.estimate import Estimate
from urident.ident.estimate_bounded import estimate_bounded_reduced
from urident.ident.estimate_consistent import DEFAULT_REGULARISATION, estimate_consistent_reduced
from urident.ident.estimate_ols import estimate_ols_reduced
from urident.ident.preprocess import (PreprocessConfig, Prepared, Provenance, concatenate,
                                      preprocess_pieces)
from urident.ident.reduced import reduce_design

METHODS = ("ols", "bounded", "consistent")


@dataclass(frozen=True)
class IdentifiedModel:
    """Everything needed to predict torques and to write a parameters file."""

    robot: str
    method: str
    model: ModelConfig
    names: tuple[str, ...]
    expressions: tuple[str, ...]
    values: np.ndarray            # base parameters (+ extra friction coefficients)
    sigma: np.ndarray
    drive_gains: np.ndarray
    preprocess: PreprocessConfig = field(default_factory=PreprocessConfig)
    weighting: str = "none"
    standard: np.ndarray | None = None     # physically consistent 78-vector (consistent method)
    provenance: tuple[Provenance, ...] = ()
    n_samples: int = 0
    noise_var: float = float("nan")
    train_rms: np.ndarray | None = None
    train_e_n: float = float("nan")
    info: dict | None = None
    kinds: tuple[str, ...] = ()   # kind of each column (urident.model.parameters); from the names if empty

    def __post_init__(self) -> None:
        from urident.model.parameters import column_kind

        if not self.kinds:   # e.g. read from a parameters file: the names say (check_compatible checks them)
            object.__setattr__(self, "kinds", tuple(column_kind(n, "unknown") for n in self.names))
        if len(self.kinds) != len(self.names):
            raise ValueError(f"{len(self.kinds)} column kinds for {len(self.names)} columns")

    @property
    def relative_sigma_pct(self) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return 100.0 * self.sigma / np.abs(self.values)


def prepare(recordings: Iterable, spec, config: PreprocessConfig | None = None,
            drive_gains=None) -> Prepared:
    """Preprocess and concatenate recordings (each filtered on its own, and each gap-free piece
    of a recording with gaps on its own too)."""
    return concatenate([p for r in recordings
                        for _, p in preprocess_pieces(r, spec, config, drive_gains)])


def _as_prepared(data) -> Prepared:
    if isinstance(data, Prepared):
        return data
    return concatenate(list(data))


def _wrap(spec, est: Estimate, model: ModelConfig, data: Prepared, weighting: str,
          config: PreprocessConfig | None) -> IdentifiedModel:
    return IdentifiedModel(
        robot=spec.name, method=est.method, model=model, names=est.names,
        expressions=tuple(column_expressions(spec, model)), values=est.values, sigma=est.sigma,
        drive_gains=np.asarray(data.drive_gains, float), preprocess=config or PreprocessConfig(),
        weighting=weighting, standard=est.standard, provenance=data.provenance,
        n_samples=len(data), noise_var=est.noise_var, train_rms=est.train_rms,
        train_e_n=est.train_e_n, info=est.info, kinds=tuple(column_kinds(spec, model)))


def identify_all(spec, data: Prepared | Sequence[Prepared], methods: Sequence[str] = METHODS,
                 model: ModelConfig | None = None, weighting: str = "none",
                 regularisation: float = DEFAULT_REGULARISATION,
                 preprocess_config: PreprocessConfig | None = None, design=None) -> dict[str, IdentifiedModel]:
    """Run several methods on the same data: one reduced problem (:mod:`urident.ident.reduced`), its
    regressor built in chunks, so memory does not grow with the samples. ``preprocess_config`` is
    only recorded; ``design``: those chunks already built (:func:`~urident.ident.reduced.reduce_blocks`)."""
    model = model or ModelConfig()
    data = _as_prepared(data)
    for m in methods:
        if m not in METHODS:
            raise ConfigError(f"method {m!r} unknown (known: {', '.join(METHODS)}, all)")
    red = reduce_design(spec, model, data, design=design)
    names = column_names(spec, model)
    out = {}
    for m in methods:
        if m == "ols":
            est = estimate_ols_reduced(red, names, weighting)
        elif m == "bounded":
            est = estimate_bounded_reduced(red, names, nonnegative_mask(spec, model), weighting)
        else:
            b = base_for(spec, model.reduced)
            nb = b.n_base
            est = estimate_consistent_reduced(red, names, b.combination, spec.nominal_params,
                                              nonnegative_mask(spec, model)[nb:], weighting, regularisation)
        out[m] = _wrap(spec, est, model, data, weighting, preprocess_config)
    return out


def identify(spec, data: Prepared | Sequence[Prepared], method: str = "ols",
             model: ModelConfig | None = None, weighting: str = "none",
             regularisation: float = DEFAULT_REGULARISATION,
             preprocess_config: PreprocessConfig | None = None, design=None) -> IdentifiedModel:
    """One method (``ols``, ``bounded`` or ``consistent``) on prepared data."""
    return identify_all(spec, data, (method,), model, weighting, regularisation, preprocess_config,
                        design)[method]


def check_compatible(identified: IdentifiedModel, spec, where: str = "parameters") -> None:
    if identified.robot != spec.name:
        raise ConfigError(f"{where}: identified for robot {identified.robot!r}, not {spec.name!r}")
    names = tuple(column_names(spec, identified.model))
    if names != tuple(identified.names):
        raise ConfigError(f"{where}: parameter names do not match the {spec.name} model "
                          f"({'reduced' if identified.model.reduced else 'full'} base set)")
    if tuple(identified.kinds) != tuple(column_kinds(spec, identified.model)):
        raise ConfigError(f"{where}: column kinds do not match the {spec.name} model")


def predict(identified: IdentifiedModel, spec, q, qd, qdd, segment=None, t=None,
            state: dict | None = None, temperature=None) -> np.ndarray:
    """(N, 6) predicted joint torques [N·m] at states (q, q̇, q̈) (N, 6); ``t`` (N,) timestamps for
    models whose friction state integrates q̇ (``dahl_source='velocity'``); ``temperature`` (N, 6)
    joint temperatures [°C] for models with temperature terms; ``state``: see
    :func:`urident.ident.design.design_blocks` (streams). Recordings: :mod:`urident.ident.prediction`."""
    check_compatible(identified, spec)
    if state is not None:
        w = design_matrix(spec, identified.model, q, qd, qdd, segment, t, state, temperature)
        return (w @ identified.values).reshape(-1, 6)
    out = np.empty((len(q), 6))
    for a, b, blocks in design_chunks(spec, identified.model, q, qd, qdd, segment, t,  # bounded memory
                                      temperature=temperature):
        out[a:b] = blocks @ identified.values
    return out


def predict_prepared(identified: IdentifiedModel, spec, data: Prepared) -> np.ndarray:
    return predict(identified, spec, data.q, data.qd, data.qdd, data.segment, data.t,
                   temperature=data.temperature)
