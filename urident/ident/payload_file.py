"""PAYLOAD.yaml: a tool's inertial parameters in UR's tool flange frame.

    format: urident-payload
    version: 1
    robot: ur10e
    method: consistent                  # ols | consistent | given
    mass_kg: 1.234
    com_m: [0.0, 0.0, 0.05]              # flange frame
    inertia_kg_m2: [[..], [..], [..]]    # 3x3 about the centre of mass, flange axes
    sigma: {mass_kg: .., com_m: [..], inertia_kg_m2: [[..]]}     # optional; null = fixed; the
                                         # inertia's σ is that of the estimated entries about the flange origin
    identifiable: [m, mcx, ...]          # optional: parameters the data determined
    urscript: set_target_payload(...)    # informational, not read
    fit: {...}                           # informational, not read
    capsule: {radius_m: 0.05, length_m: 0.1}   # optional: the tool's size for collision checks
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from urident.fileio import write_text_atomic
from urident.model.payload import PAYLOAD_FIELDS, Payload, PayloadError
from urident.yamlio import Fields, key_path, load_yaml

FORMAT = "urident-payload"
VERSION = 1
_TOP = {"format", "version", "robot", "method", "mass_kg", "com_m", "inertia_kg_m2", "sigma",
        "identifiable", "urscript", "fit", "capsule"}


def _nan_none(v):
    return None if not np.isfinite(v) else float(v)


def to_dict(p: Payload, fit: dict | None = None) -> dict:
    sigma = None
    if p.sigma:
        sigma = {"mass_kg": _nan_none(p.sigma["mass_kg"]),
                 "com_m": [_nan_none(v) for v in p.sigma["com_m"]],
                 "inertia_kg_m2": [[_nan_none(v) for v in row] for row in p.sigma["inertia_kg_m2"]]}
    out = {"format": FORMAT, "version": VERSION, "robot": p.robot, "method": p.method, **inertial_dict(p),
           "sigma": sigma, "identifiable": list(p.identifiable),
           "urscript": None if p.info.get("mass_bound_kg") is not None else p.urscript()}   # a bound's mass: none
    if fit:
        out["fit"] = fit
    if p.info.get("capsule"):
        out["capsule"] = p.info["capsule"]
    return out


def save_payload(p: Payload, path, overwrite: bool = False, fit: dict | None = None) -> None:
    write_text_atomic(path, yaml.safe_dump(to_dict(p, fit), sort_keys=False, width=120),
                      fsync=False, overwrite=overwrite)


def inertial_fields(f: Fields, data: dict, where: str = "", spec=None) -> tuple[float, np.ndarray, np.ndarray]:
    """``mass_kg`` (> 0), ``com_m`` (3) and the optional ``inertia_kg_m2`` (3×3, symmetric, ⪰ 0,
    principal moments within the triangle inequality; default zero) of the mapping ``data`` at key
    path ``where`` (a payload file's top level, a trajectory file's ``payload``); with ``spec``,
    the mass within the robot's rated payload and the centre of mass within its reach."""
    from urident.model.robot import inertia_problem

    mass = f.number(data, "mass_kg", where, positive=True)
    com = f.array(data, "com_m", where, 3)
    inertia = (np.zeros((3, 3)) if data.get("inertia_kg_m2") is None
               else f.array(data, "inertia_kg_m2", where, (3, 3)))
    if not np.allclose(inertia, inertia.T, atol=1e-12 + 1e-9 * np.abs(inertia).max()):
        raise f.fail(key_path(where, "inertia_kg_m2"), "must be symmetric")
    problem = inertia_problem(0.5 * (inertia + inertia.T), definite=False)
    if problem:
        raise f.fail(key_path(where, "inertia_kg_m2"), f"{problem} (about the centre of mass)")
    if spec is not None:
        for key, problem in (("mass_kg", spec.rated_payload_problem(mass)), ("com_m", spec.tool_com_problem(com))):
            if problem:
                raise f.fail(key_path(where, key), problem)
    return mass, com, inertia


def inertial_dict(p: Payload) -> dict:
    """The inverse of :func:`inertial_fields`: plain floats."""
    return {"mass_kg": float(p.mass_kg), "com_m": [float(v) for v in p.com_m],
            "inertia_kg_m2": [[float(v) for v in row] for row in p.inertia_kg_m2]}


def load_payload(path, spec=None) -> Payload:
    """Read PAYLOAD.yaml; PayloadError (one line, naming the file and key) on any defect, and when
    ``spec`` is given and the file is for another robot."""
    path = Path(path)
    data = load_yaml(path, "payload file", PayloadError)
    f = Fields(path, PayloadError)
    f.document(data, _TOP, ("format", "robot", "mass_kg", "com_m"), FORMAT, "payload file")
    if data.get("version", VERSION) != VERSION:
        raise f.fail("version", f"not supported (expected {VERSION})")
    robot = f.get(data, "robot", str)
    if spec is not None and robot != spec.name:
        raise f.fail("robot", f"payload for robot {robot!r}, not {spec.name!r}")
    mass, com, inertia = inertial_fields(f, data, spec=spec)
    ident = data.get("identifiable", list(PAYLOAD_FIELDS))
    if not isinstance(ident, list) or any(x not in PAYLOAD_FIELDS for x in ident):
        raise f.fail("identifiable", f"must list names among {', '.join(PAYLOAD_FIELDS)}")
    method = str(data.get("method", "given"))
    info = {}
    if data.get("capsule") is not None:
        cap = f.mapping(data["capsule"], "capsule")
        f.keys(cap, {"radius_m", "length_m"}, "capsule", required=("radius_m", "length_m"))
        info["capsule"] = {"radius_m": f.number(cap, "radius_m", "capsule", positive=True),
                           "length_m": f.number(cap, "length_m", "capsule", nonnegative=True)}
    return Payload(robot, mass, com, inertia, sigma={}, identifiable=tuple(ident), method=method, info=info)
