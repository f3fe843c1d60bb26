"""PARAMS.yaml: identified parameters with their model, options and data provenance.

    format: urident-params
    version: 1
    robot: ur10e
    method: ols                    # ols | bounded | consistent
    weighting: none                # none | joint
    model: {reduced: false, friction_eps: 0.01, coulomb: tanh, dahl_rad: 0.01, extras: [], stribeck_vs: 0.05}
    preprocess: {filter_hz: 10.0, torque_filter_hz: null, decimate: 1, trim_rest: true, ...}
    drive_gains: [g1, ..., g6]     # N·m/A, the ones used to turn currents into torques
    base_parameters:               # in model order: base set, then extra friction features
      - {name: C1, expression: C1 + IM1, value: ..., sigma: ..., rel_sigma_pct: ...}
    standard_parameters:           # the 78-vector (consistent method only; else null)
      - {name: m1, value: ...}
    data: [{file: ..., rows: [635, 3510], sha256: ..., samples_used: [0, 2876]}]
    fit: {n_samples: ..., noise_var: ..., e_n: ..., rms_nm: [...]}
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import yaml

from urident.errors import ConfigError, shown
from urident.fileio import write_text_atomic
from urident.ident.design import ModelConfig
from urident.ident.identify import METHODS, IdentifiedModel
from urident.ident.preprocess import PreprocessConfig, Provenance
from urident.model.parameters import N_PARAMS, parameter_names
from urident.yamlio import Fields, key_path, load_yaml

FORMAT = "urident-params"
VERSION = 1
_TOP = {"format", "version", "robot", "method", "weighting", "model", "preprocess", "drive_gains",
        "base_parameters", "standard_parameters", "data", "fit"}
_REQUIRED = {"format", "robot", "method", "model", "drive_gains", "base_parameters"}


class ParamsFileError(ConfigError):
    """A parameters file is missing, malformed or does not fit the robot."""


def to_dict(m: IdentifiedModel) -> dict:
    rel = m.relative_sigma_pct
    return {
        "format": FORMAT,
        "version": VERSION,
        "robot": m.robot,
        "method": m.method,
        "weighting": m.weighting,
        "model": m.model.as_dict(),
        "preprocess": {f.name: getattr(m.preprocess, f.name) for f in fields(PreprocessConfig)},
        "drive_gains": [float(g) for g in m.drive_gains],
        "base_parameters": [
            {"name": n, "expression": e, "value": float(v), "sigma": float(s),
             "rel_sigma_pct": float(r) if np.isfinite(r) else None}
            for n, e, v, s, r in zip(m.names, m.expressions, m.values, m.sigma, rel)],
        "standard_parameters": None if m.standard is None else [
            {"name": n, "value": float(v)} for n, v in zip(parameter_names(), m.standard)],
        "data": [p.as_dict() for p in m.provenance],
        "fit": {"n_samples": int(m.n_samples), "noise_var": float(m.noise_var),
                "e_n": float(m.train_e_n),
                "rms_nm": None if m.train_rms is None else [float(v) for v in m.train_rms]},
    }


def save_params(m: IdentifiedModel, path: str | Path, overwrite: bool = True) -> None:
    """Write PARAMS.yaml atomically, never through a symbolic link (``overwrite=False``: the
    file must not exist)."""
    write_text_atomic(path, yaml.safe_dump(to_dict(m), sort_keys=False, width=120), fsync=False,
                      overwrite=overwrite)


def _err(path, msg) -> ParamsFileError:
    return ParamsFileError(f"{path}: {msg}")


def load_params(path: str | Path) -> IdentifiedModel:
    """Read a parameters file; ParamsFileError (one line, naming the file and key) on any defect."""
    path = Path(path)
    data = load_yaml(path, "parameters file", ParamsFileError)
    if data is None:
        raise _err(path, "parameters file is empty")
    if not isinstance(data, dict):
        raise _err(path, "expected a mapping at the top level")
    f = Fields(path, ParamsFileError)
    f.keys(data, _TOP, "", required=sorted(_REQUIRED))
    if data["format"] != FORMAT:
        raise f.fail("format", f"is {shown(data['format'])!r}, expected {FORMAT!r}")
    if data.get("version", VERSION) != VERSION:
        raise f.fail("version", f"{shown(data.get('version'))!r} not supported (expected {VERSION})")
    if not isinstance(data["robot"], str):
        raise f.fail("robot", "must be a robot name")
    if data["method"] not in METHODS:
        raise f.fail("method", f"must be one of {', '.join(METHODS)}")
    if not isinstance(data.get("weighting", "none"), str):
        raise f.fail("weighting", "must be text")
    f.mapping(data["model"], "model")
    f.keys(data["model"], ModelConfig.__dataclass_fields__, "model")
    model = _build(f, "model", lambda: ModelConfig.from_dict(data["model"], f"{path}: model"))
    pre = f.mapping(data.get("preprocess") or {}, "preprocess")
    f.keys(pre, {x.name for x in fields(PreprocessConfig)}, "preprocess")
    preprocess = _build(f, "preprocess", lambda: PreprocessConfig(**pre))
    gains = f.array(data, "drive_gains", "", 6)
    if np.any(gains <= 0):
        raise f.fail("drive_gains", "must be positive [N·m/A]")
    items = data["base_parameters"]
    if not isinstance(items, list) or not items:
        raise f.fail("base_parameters", "must be a non-empty list")
    names, expr, values, sigma = [], [], [], []
    for k, item in enumerate(items):
        where = f"base_parameters[{k}]"
        f.mapping(item, where)
        f.keys(item, {"name", "expression", "value", "sigma", "rel_sigma_pct"}, where,
               required=("name", "value"))
        values.append(f.number(item, "value", where))
        sigma.append(_statistic(f, item, "sigma", where))
        names.append(str(item["name"]))
        expr.append(str(item.get("expression", item["name"])))
    standard = None
    if data.get("standard_parameters") is not None:
        std = data["standard_parameters"]
        if not isinstance(std, list) or len(std) != N_PARAMS:
            raise f.fail("standard_parameters", f"must list {N_PARAMS} parameters")
        for k, item in enumerate(std):
            f.mapping(item, f"standard_parameters[{k}]")
            f.keys(item, {"name", "value"}, f"standard_parameters[{k}]", required=("value",))
        standard = np.array([f.number(item, "value", f"standard_parameters[{k}]")
                             for k, item in enumerate(std)])
    prov = []
    provenance = data.get("data") or []
    if not isinstance(provenance, list):
        raise f.fail("data", "must be a list")
    for k, d in enumerate(provenance):
        where = f"data[{k}]"
        f.mapping(d, where)
        f.keys(d, {"file", "rows", "sha256", "samples_used", "signal"}, where)
        rows = None if d.get("rows") is None else _index_pair(f, d, "rows", where)
        used = (0, 0) if d.get("samples_used") is None else _index_pair(f, d, "samples_used", where)
        sha = d.get("sha256")
        signal = d.get("signal")
        prov.append(Provenance(str(d.get("file")), rows, None if sha is None else str(sha), used,
                               None if signal is None else str(signal)))
    fit = f.mapping(data.get("fit") or {}, "fit")
    f.keys(fit, {"n_samples", "noise_var", "e_n", "rms_nm"}, "fit")
    return IdentifiedModel(
        robot=data["robot"], method=data["method"], model=model, names=tuple(names),
        expressions=tuple(expr), values=np.array(values), sigma=np.array(sigma), drive_gains=gains,
        preprocess=preprocess, weighting=str(data.get("weighting", "none")), standard=standard,
        provenance=tuple(prov),
        n_samples=0 if fit.get("n_samples") is None else f.integer(fit, "n_samples", "fit", minimum=0),
        noise_var=_statistic(f, fit, "noise_var", "fit"),
        train_rms=None if fit.get("rms_nm") is None else _rms(f, fit),
        train_e_n=_statistic(f, fit, "e_n", "fit"))


def _index_pair(f: Fields, mapping: dict, key: str, where: str) -> tuple[int, int]:
    pair = f.array(mapping, key, where, 2)
    if not np.all((pair == np.round(pair)) & (np.abs(pair) < 2**53)):
        raise f.fail(key_path(where, key), "must be two whole numbers")
    return int(pair[0]), int(pair[1])


def _rms(f: Fields, fit: dict) -> np.ndarray:
    values = f.get(fit, "rms_nm", list, "fit")
    if len(values) != 6 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise f.fail("fit.rms_nm", "must be a list of 6 numbers")
    try:
        return np.array(values, dtype=float)
    except OverflowError:
        raise f.fail("fit.rms_nm", "is out of range") from None


def _statistic(f: Fields, mapping: dict, key: str, where: str) -> float:
    """A reported statistic: a number, NaN when not available (None or .nan)."""
    if mapping.get(key) is None:
        return np.nan
    try:
        return float(f.get(mapping, key, (int, float), where))
    except OverflowError:
        raise f.fail(key_path(where, key), "is out of range") from None


def _build(f: Fields, where: str, make):
    """``make()``, its errors (the dataclass's own checks) as ``FILE: where: message``."""
    try:
        return make()
    except ParamsFileError:
        raise
    except (ConfigError, TypeError, ValueError, OverflowError) as exc:
        message = str(exc)
        prefix = f"{f.label}: {where}: "
        raise f.fail(where, message[len(prefix):] if message.startswith(prefix) else message) from None
