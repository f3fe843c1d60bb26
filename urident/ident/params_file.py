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
from urident.ident.design import ModelConfig
from urident.ident.identify import METHODS, IdentifiedModel
from urident.ident.preprocess import PreprocessConfig, Provenance
from urident.model.parameters import N_PARAMS, parameter_names

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


def save_params(m: IdentifiedModel, path: str | Path) -> None:
    Path(path).write_text(yaml.safe_dump(to_dict(m), sort_keys=False, width=120))


def _err(path, msg) -> ParamsFileError:
    return ParamsFileError(f"{path}: {msg}")


def _numbers(path, key, value, n=None) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise _err(path, f"key '{key}' must hold numbers") from None
    if arr.ndim != 1 or (n is not None and arr.shape != (n,)) or not np.all(np.isfinite(arr)):
        raise _err(path, f"key '{key}' must be a list of {n or 'finite'} finite numbers")
    return arr


def load_params(path: str | Path) -> IdentifiedModel:
    """Read a parameters file; ParamsFileError (one line, naming the file and key) on any defect."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise _err(path, "no such parameters file") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f":{mark.line + 1}" if mark is not None else ""
        raise ParamsFileError(f"{path}{where}: malformed YAML") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise _err(path, f"cannot read ({exc})") from None
    if not isinstance(data, dict):
        raise _err(path, "expected a mapping at the top level")
    unknown = sorted(set(map(str, data)) - _TOP)
    if unknown:
        raise _err(path, f"unknown key '{shown(unknown[0])}'")
    missing = sorted(_REQUIRED - set(data))
    if missing:
        raise _err(path, f"missing key '{missing[0]}'")
    if data["format"] != FORMAT:
        raise _err(path, f"key 'format' is {data['format']!r}, expected {FORMAT!r}")
    if data.get("version", VERSION) != VERSION:
        raise _err(path, f"key 'version' {data.get('version')!r} not supported (expected {VERSION})")
    if not isinstance(data["robot"], str):
        raise _err(path, "key 'robot' must be a robot name")
    if data["method"] not in METHODS:
        raise _err(path, f"key 'method' must be one of {', '.join(METHODS)}")
    if not isinstance(data["model"], dict):
        raise _err(path, "key 'model' must be a mapping")
    try:
        model = ModelConfig.from_dict(data["model"], f"{path}: key 'model'")
    except TypeError as exc:
        raise _err(path, f"key 'model': {exc}") from None
    except ConfigError as exc:
        raise ParamsFileError(str(exc) if str(exc).startswith(str(path)) else f"{path}: key 'model': {exc}") from None
    pre = data.get("preprocess") or {}
    if not isinstance(pre, dict):
        raise _err(path, "key 'preprocess' must be a mapping")
    try:
        pre_unknown = sorted(set(pre) - {f.name for f in fields(PreprocessConfig)})
        if pre_unknown:
            raise _err(path, f"unknown key 'preprocess.{shown(pre_unknown[0])}'")
        preprocess = PreprocessConfig(**pre)
    except ConfigError as exc:
        raise ParamsFileError(str(exc) if str(exc).startswith(str(path)) else f"{path}: key 'preprocess': {exc}") from None
    gains = _numbers(path, "drive_gains", data["drive_gains"], 6)
    items = data["base_parameters"]
    if not isinstance(items, list) or not items:
        raise _err(path, "key 'base_parameters' must be a non-empty list")
    names, expr, values, sigma = [], [], [], []
    for k, item in enumerate(items):
        if not isinstance(item, dict) or "name" not in item or "value" not in item:
            raise _err(path, f"key 'base_parameters[{k}]' needs name and value")
        try:
            v = float(item["value"])
            s = float(item.get("sigma", np.nan) if item.get("sigma") is not None else np.nan)
        except (TypeError, ValueError):
            raise _err(path, f"key 'base_parameters[{k}].value' must be a number") from None
        if not np.isfinite(v):
            raise _err(path, f"key 'base_parameters[{k}].value' must be finite (got {item['value']})")
        names.append(str(item["name"]))
        expr.append(str(item.get("expression", item["name"])))
        values.append(v)
        sigma.append(s)
    standard = None
    if data.get("standard_parameters") is not None:
        std = data["standard_parameters"]
        if not isinstance(std, list) or len(std) != N_PARAMS:
            raise _err(path, f"key 'standard_parameters' must list {N_PARAMS} parameters")
        try:
            standard = np.array([float(it["value"]) for it in std])
        except (TypeError, ValueError, KeyError):
            raise _err(path, "key 'standard_parameters' entries need a numeric value") from None
        if not np.all(np.isfinite(standard)):
            raise _err(path, "key 'standard_parameters' must be finite")
    prov = []
    for k, d in enumerate(data.get("data") or []):
        if not isinstance(d, dict):
            raise _err(path, f"key 'data[{k}]' must be a mapping")
        rows = d.get("rows")
        prov.append(Provenance(str(d.get("file")), None if rows is None else tuple(rows),
                               d.get("sha256"), tuple(d.get("samples_used") or (0, 0))))
    fit = data.get("fit") or {}
    return IdentifiedModel(
        robot=data["robot"], method=data["method"], model=model, names=tuple(names),
        expressions=tuple(expr), values=np.array(values), sigma=np.array(sigma), drive_gains=gains,
        preprocess=preprocess, weighting=str(data.get("weighting", "none")), standard=standard,
        provenance=tuple(prov), n_samples=int(fit.get("n_samples") or 0),
        noise_var=float(fit.get("noise_var") or np.nan),
        train_rms=None if fit.get("rms_nm") is None else np.array(fit["rms_nm"], dtype=float),
        train_e_n=float(fit.get("e_n") or np.nan))
