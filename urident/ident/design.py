"""The identification model: which base parameters and friction features, and its regressor.

``ModelConfig`` fixes everything the regressor depends on (the paper's reduced or full base set, the
tanh slope ε, the Coulomb model and extra friction features). ``design_matrix`` returns the stacked
(6N, n) matrix, row 6k + j, whose first ``b`` columns are the base-parameter columns Θ_B of the
paper and the rest the extra friction columns (:mod:`urident.ident.features`, the friction states
of :mod:`urident.ident.friction`). Column names and kinds follow :mod:`urident.model.parameters`.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass

import numpy as np

from urident.errors import ConfigError, shown
from urident.ident import features
from urident.ident.friction import COULOMB_MODELS, DAHL_SOURCES, dahl_states, hold_state, velocity_displacement
from urident.model.parameters import (COULOMB_OFFSET, EXTRA_COLUMNS, extra_column_names, joint_column_name,
                                      nonnegative_parameters, parameter_kinds)

#: Friction features that depend on the logged joint temperature; per joint only, each with its
#: reference temperature T_ref [°C] (``tempvisc@35.2``), at which the base friction holds.
TEMPERATURE_FEATURES = ("tempvisc", "tempcoul")
#: Features the model's ``extras`` (every joint, no own parameter) may hold.
EXTRA_FEATURES = tuple(x for x in EXTRA_COLUMNS if x not in TEMPERATURE_FEATURES)
#: Per-joint terms that carry a parameter of their own (``sigmoid@0.05``): its meaning and unit;
#: without one the model's (friction_eps, stribeck_vs, dahl_rad; harmonic 1) is used.
TERM_PARAMETERS = {"sigmoid": "eps [rad/s]", "sigoffset": "eps [rad/s]", "stribeck": "v_s [rad/s]",
                   "dahl": "delta [rad]", "poscos": "harmonic [-]", "possin": "harmonic [-]",
                   "tempvisc": "T_ref [°C]", "tempcoul": "T_ref [°C]"}


def parse_term(term: str) -> tuple[str, float | None]:
    """``'sigmoid@0.05'`` → ('sigmoid', 0.05); ``'load'`` → ('load', None). ConfigError if unknown."""
    name, sep, value = str(term).partition("@")
    if name not in EXTRA_COLUMNS:
        raise ConfigError(f"friction feature {name!r} unknown (known: {', '.join(EXTRA_COLUMNS)})")
    if not sep:
        if name in TEMPERATURE_FEATURES:
            raise ConfigError(f"friction term {term!r} needs its reference temperature: '{name}@T_REF' [°C]")
        return name, None
    if name not in TERM_PARAMETERS:
        raise ConfigError(f"friction feature {name!r} takes no parameter (given {term!r})")
    try:
        v = float(value)
    except ValueError:
        raise ConfigError(f"friction term {term!r}: {value!r} is not a number") from None
    if name in TEMPERATURE_FEATURES:
        if not np.isfinite(v):
            raise ConfigError(f"friction term {term!r}: its reference temperature must be finite")
    elif not (np.isfinite(v) and v > 0):
        raise ConfigError(f"friction term {term!r}: its parameter must be positive")
    return name, v


def term_text(name: str, value: float | None) -> str:
    """The canonical spelling of a per-joint term (inverse of :func:`parse_term`)."""
    return name if value is None else f"{name}@{value:g}"


@dataclass(frozen=True)
class ModelConfig:
    """What is identified. Defaults are the paper's: full base set, tanh Coulomb, ε = 0.01 rad/s."""

    reduced: bool = False           # the paper's reduced model (33 base parameters) or full (52)
    friction_eps: float = 0.01      # [rad/s] tanh slope
    coulomb: str = "tanh"           # 'tanh' (paper), 'dahl' or 'hold' (history-driven, friction.py)
    dahl_rad: float = 0.01          # [rad] Dahl presliding distance δ
    hold_velocity: float = 3e-4     # [rad/s] 'hold': |q̇| needed to reverse the friction state
    extras: tuple[str, ...] = ()    # extra friction features: offset, stribeck, dahl, load, sqrtvisc
    stribeck_vs: float = 0.05       # [rad/s] Stribeck velocity
    dahl_source: str = "position"   # Dahl displacement from 'position' (q) or 'velocity' (∫q̇ dt)
    # per joint (6 tuples, or empty): friction terms of that joint only, 'name' or 'name@value'
    joint_extras: tuple[tuple[str, ...], ...] = ()
    # per joint (6 entries, or empty): that joint's Coulomb state, 'tanh' or 'dahl@delta' (instead of coulomb)
    joint_coulomb: tuple[str, ...] = ()

    def friction_summary(self) -> str:
        """The friction model in one phrase, for reports: ``tanh friction, eps = 0.01 rad/s``."""
        if self.coulomb == "tanh":
            text = f"tanh friction, eps = {self.friction_eps:g} rad/s"
        elif self.coulomb == "dahl":
            text = f"Dahl friction, delta = {self.dahl_rad:g} rad from {self.dahl_source}"
        else:
            text = f"hold friction, v_hold = {self.hold_velocity:g} rad/s"
        text += f" + {', '.join(self.extras)}" if self.extras else ""
        if self.joint_coulomb:
            text += "; Coulomb state per joint: " + ", ".join(self.joint_coulomb)
        if self.joint_extras:
            text += "; per joint: " + "; ".join(f"J{j + 1} {'+'.join(t) or '-'}"
                                                for j, t in enumerate(self.joint_extras))
        return text

    def joint_terms(self) -> list[tuple[int, str, float | None]]:
        """(joint, feature, own parameter or None) of every per-joint term, in column order."""
        return [(j, *parse_term(t)) for j, terms in enumerate(self.joint_extras) for t in terms]

    @property
    def uses_temperature(self) -> bool:
        """Whether a friction term depends on the logged joint temperature."""
        return any(x in TEMPERATURE_FEATURES for _, x, _ in self.joint_terms())

    def coulomb_text(self) -> str:
        """The Coulomb state in one phrase: ``tanh``, ``dahl (delta 0.0002 rad)`` or, when the
        joints have their own, ``per joint: J1 dahl@0.0002, J2 tanh, ...``."""
        if self.joint_coulomb:
            return "per joint: " + ", ".join(f"J{j + 1} {c}" for j, c in enumerate(self.joint_coulomb))
        if self.coulomb == "dahl":
            return f"dahl (delta {self.dahl_rad:g} rad from {self.dahl_source})"
        return self.coulomb

    def __post_init__(self) -> None:
        if not self.friction_eps > 0:
            raise ConfigError(f"friction_eps must be positive, not {self.friction_eps}")
        if self.coulomb not in COULOMB_MODELS:
            raise ConfigError(f"coulomb model {self.coulomb!r} unknown (known: {', '.join(COULOMB_MODELS)})")
        object.__setattr__(self, "extras", tuple(self.extras))
        for x in self.extras:
            if x in TEMPERATURE_FEATURES:
                raise ConfigError(f"friction feature {x!r} needs a reference temperature: give it per joint "
                                  f"(joint_extras '{x}@T_REF', T_REF in °C)")
            if x not in EXTRA_FEATURES:
                raise ConfigError(f"friction feature {x!r} unknown (known: {', '.join(EXTRA_FEATURES)})")
        if len(set(self.extras)) != len(self.extras):
            raise ConfigError(f"friction features repeated: {', '.join(self.extras)}")
        if self.dahl_source not in DAHL_SOURCES:
            raise ConfigError(f"dahl_source {self.dahl_source!r} unknown (known: {', '.join(DAHL_SOURCES)})")
        if not (self.dahl_rad > 0 and self.stribeck_vs > 0 and self.hold_velocity > 0):
            raise ConfigError("dahl_rad, stribeck_vs and hold_velocity must be positive")
        joint = tuple(tuple(term_text(*parse_term(t)) for t in terms) for terms in self.joint_extras)
        if joint and len(joint) != 6:
            raise ConfigError(f"joint_extras needs one list per joint (6), not {len(joint)}")
        for j, terms in enumerate(joint):
            if len(set(terms)) != len(terms):
                raise ConfigError(f"joint_extras of joint {j + 1}: a term repeated: {', '.join(terms)}")
            clash = [t for t in terms if t in self.extras]
            if clash:
                raise ConfigError(f"joint_extras of joint {j + 1}: {clash[0]!r} is already in extras")
        object.__setattr__(self, "joint_extras", joint)
        states = tuple(str(c) for c in self.joint_coulomb)
        if states and len(states) != 6:
            raise ConfigError(f"joint_coulomb needs one state per joint (6), not {len(states)}")
        canon = []
        for j, c in enumerate(states):
            if c == "tanh":
                canon.append(c)
                continue
            name, value = parse_term(c) if c.startswith("dahl@") else (c, None)
            if name != "dahl" or value is None:
                raise ConfigError(f"joint_coulomb of joint {j + 1}: {c!r} is not 'tanh' or 'dahl@DELTA'")
            canon.append(term_text(name, value))
        object.__setattr__(self, "joint_coulomb", tuple(canon))

    def as_dict(self) -> dict:
        d = asdict(self)
        d["extras"] = list(self.extras)
        d["joint_extras"] = [list(t) for t in self.joint_extras]
        d["joint_coulomb"] = list(self.joint_coulomb)
        return d

    @classmethod
    def from_dict(cls, data: dict, where: str = "model") -> "ModelConfig":
        allowed = set(cls.__dataclass_fields__)
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise ConfigError(f"{where}: unknown key '{shown(unknown[0])}' (allowed: {', '.join(sorted(allowed))})")
        kw = dict(data)
        if "extras" in kw:
            kw["extras"] = tuple(kw["extras"] or ())
        if "joint_extras" in kw:
            rows = kw["joint_extras"] or ()
            if not isinstance(rows, (list, tuple)) or not all(isinstance(r, (list, tuple)) for r in rows):
                raise ConfigError(f"{where}: joint_extras must be a list of six lists of terms")
            kw["joint_extras"] = tuple(tuple(str(t) for t in r) for r in rows)
        if "joint_coulomb" in kw:
            states = kw["joint_coulomb"] or ()
            if not isinstance(states, (list, tuple)):
                raise ConfigError(f"{where}: joint_coulomb must be a list of six states")
            kw["joint_coulomb"] = tuple(str(c) for c in states)
        return cls(**kw)


@functools.lru_cache(maxsize=16)
def _base_cached(source: str, name: str, reduced: bool):
    from urident.model import load_robot
    from urident.model.base import base_parameters

    return base_parameters(load_robot(source), reduced)


def base_for(spec, reduced: bool):
    """Base parameters of ``spec`` (cached per robot file)."""
    return _base_cached(str(spec.source), spec.name, bool(reduced))


def column_names(spec, config: ModelConfig) -> list[str]:
    base = base_for(spec, config.reduced)
    names = list(base.names)
    for x in config.extras:
        names += extra_column_names(x)
    names += [joint_column_name(x, j, v) for j, x, v in config.joint_terms()]
    return names


def column_kinds(spec, config: ModelConfig) -> list[str]:
    """Kind of each column (:mod:`urident.model.parameters`): a base parameter has the kind of the
    standard parameter it is named after, an extra column its feature's kind."""
    base = base_for(spec, config.reduced)
    kinds = parameter_kinds()
    out = [kinds[k] for k in base.independent]
    for x in config.extras:
        out += [EXTRA_COLUMNS[x][1]] * 6
    out += [EXTRA_COLUMNS[x][1] for _, x, _ in config.joint_terms()]
    return out


def column_expressions(spec, config: ModelConfig) -> list[str]:
    base = base_for(spec, config.reduced)
    expr = list(base.expressions())
    desc = {"offset": "constant torque offset", "stribeck": "Stribeck term tanh(qd/eps)*exp(-(qd/vs)^2)",
            "dahl": "Dahl hysteresis state",
            "load": "load-dependent Coulomb friction |tau_nominal|*z",
            "sqrtvisc": "sub-linear viscous friction sign(qd)*sqrt(|qd|)",
            "asym": "Coulomb asymmetry |z|", "sigmoid": "sigmoid Coulomb tanh(qd/eps)",
            "sigoffset": "sigmoid offset tanh(qd/eps)^2", "quadvisc": "quadratic viscous qd*|qd|",
            "poscos": "position-dependent friction z*cos(k*q)",
            "possin": "position-dependent friction z*sin(k*q)",
            "tempvisc": "temperature-dependent viscous friction qd*(T-T_ref)",
            "tempcoul": "temperature-dependent Coulomb friction z*(T-T_ref)"}
    for x in config.extras:
        expr += [f"{desc[x]} of joint {j + 1}" for j in range(6)]
    for j, x, v in config.joint_terms():
        expr.append(f"{desc[x]} of joint {j + 1}"
                    + ("" if v is None else f" ({TERM_PARAMETERS[x].split()[0]} = {v:g})"))
    return expr


def nonnegative_mask(spec, config: ModelConfig) -> np.ndarray:
    """Columns whose coefficient must be ≥ 0 physically: base parameters that are a positive
    combination of masses, diagonal inertias about the joint frame (A, B, C), rotor inertias and
    friction coefficients only; and the Stribeck and Dahl extras."""
    base = base_for(spec, config.reduced)
    nonneg_std = nonnegative_parameters()
    mask = []
    for row in base.combination:
        nz = np.flatnonzero(np.abs(row) > 1e-12)
        mask.append(bool(np.all(nonneg_std[nz]) and np.all(row[nz] > 0)))
    for x in config.extras:
        mask += [x in features.NONNEGATIVE_EXTRAS] * 6
    mask += [x in features.NONNEGATIVE_EXTRAS for _, x, _ in config.joint_terms()]
    return np.array(mask)


def _dahl(config: ModelConfig, deltas, q, qd, t, segment, state: dict | None = None) -> dict:
    """{δ: (N, 6) Dahl state} for each presliding distance of ``deltas``, in one pass; ``state``
    keeps each δ's state at the last sample (streams, chunks)."""
    deltas = sorted({float(d) for d in deltas})
    keys = [f"dahl@{d!r}" for d in deltas]
    initial = None
    if state is not None and all(k in state for k in keys):
        initial = np.stack([state[k] for k in keys])
    x = velocity_displacement(t, qd, segment) if config.dahl_source == "velocity" and t is not None else q
    z = dahl_states(x, deltas, segment, initial)
    if state is not None:
        for k, zk in zip(keys, z):
            state[k] = zk[-1].copy()
    return {d: np.ascontiguousarray(zk) for d, zk in zip(deltas, z)}


def _dahl_deltas(config: ModelConfig) -> list[float]:
    """Every presliding distance the model's columns need (its Coulomb state, extras, joint terms)."""
    out = [config.dahl_rad] if config.coulomb == "dahl" or "dahl" in config.extras else []
    out += [config.dahl_rad if v is None else v for _, x, v in config.joint_terms() if x == "dahl"]
    out += [parse_term(c)[1] for c in config.joint_coulomb if c != "tanh"]
    return out


def _hold(config: ModelConfig, qd, segment, state: dict | None = None) -> np.ndarray:
    z = hold_state(qd, config.friction_eps, config.hold_velocity, segment,
                   None if state is None else state.get("hold"))
    if state is not None:
        state["hold"] = z[-1].copy()
    return z


def nominal_link_torque(spec, blocks: np.ndarray) -> np.ndarray:
    """(N, 6) link-side rigid-body torque of the robot file's nominal parameters, from the (N, 6, 78)
    regressor (the ten parameters of the six bodies only: no rotor inertia, no friction)."""
    return features.link_torque(blocks, spec.nominal_params)


def design_blocks(spec, config: ModelConfig, q, qd, qdd, segment=None, t=None,
                  state: dict | None = None, temperature=None) -> np.ndarray:
    """(N, 6, n) regressor of the identification model (see module doc). ``t`` (N,) timestamps are
    needed by ``dahl_source='velocity'`` (without them the Dahl state follows the positions);
    ``temperature`` (N, 6) joint temperatures [°C] by the temperature terms.
    ``state`` (a stream, one segment): the history-driven friction states at the first sample
    (empty: the segment starts there), updated in place to those at the last sample."""
    from urident.model import regressor_blocks

    base = base_for(spec, config.reduced)
    blocks = regressor_blocks(spec, q, qd, qdd, config.friction_eps)
    joints = np.arange(6)
    deltas = _dahl_deltas(config)
    dahl = _dahl(config, deltas, q, qd, t, segment, state) if deltas else {}  # once: it advances state
    if config.coulomb == "dahl":
        blocks[:, joints, COULOMB_OFFSET + joints] = dahl[config.dahl_rad]
    elif config.coulomb == "hold":
        blocks[:, joints, COULOMB_OFFSET + joints] = _hold(config, qd, segment, state)
    for j, c in enumerate(config.joint_coulomb):
        blocks[:, j, COULOMB_OFFSET + j] = (np.tanh(qd[:, j] / config.friction_eps) if c == "tanh"
                                            else dahl[parse_term(c)[1]][:, j])
    z = blocks[:, joints, COULOMB_OFFSET + joints]   # the Coulomb state, (N, 6)
    load = functools.cache(lambda: nominal_link_torque(spec, blocks))
    out = [blocks[:, :, base.independent]]
    n = blocks.shape[0]
    for x in config.extras:
        extra = np.zeros((n, 6, 6))
        extra[:, joints, joints] = _feature(config, x, None, q, qd, z, load, dahl)
        out.append(extra)
    terms = config.joint_terms()
    if terms:
        extra = np.zeros((n, 6, len(terms)))
        cache: dict = {}
        for c, (j, x, v) in enumerate(terms):
            key = (x, v)
            if key not in cache:
                cache[key] = _feature(config, x, v, q, qd, z, load, dahl, temperature)
            extra[:, j, c] = cache[key][:, j]
        out.append(extra)
    return np.concatenate(out, axis=2)


def _feature(config: ModelConfig, x: str, v: float | None, q, qd, z, load, dahl,
             temperature=None) -> np.ndarray:
    """(N, 6) values of extra feature ``x`` (own parameter ``v`` or None) on every joint."""
    if x in TEMPERATURE_FEATURES:
        if temperature is None:
            raise ConfigError(f"friction term {x}@{v:g} needs the joint temperatures, and the data carry none")
        temperature = np.asarray(temperature, dtype=float)
        return (features.temperature_viscous(qd, temperature, v) if x == "tempvisc"
                else features.temperature_coulomb(z, temperature, v))
    if x == "offset":
        return features.offset(z.shape)
    if x == "stribeck":
        return features.stribeck(qd, config.friction_eps, config.stribeck_vs if v is None else v)
    if x == "load":
        return features.load_friction(load(), z)
    if x == "sqrtvisc":
        return features.sqrt_viscous(qd)
    if x == "dahl":
        return dahl[config.dahl_rad if v is None else v]
    if x == "asym":
        return features.coulomb_asymmetry(z)
    if x == "sigmoid":
        return features.sigmoid(qd, config.friction_eps if v is None else v)
    if x == "sigoffset":
        return features.sigmoid_offset(qd, config.friction_eps if v is None else v)
    if x == "quadvisc":
        return features.quadratic_viscous(qd)
    cos, sin = features.position_friction(q, z, 1.0 if v is None else v)
    return cos if x == "poscos" else sin


CHUNK_SAMPLES = 8192   # samples per regressor chunk: ≈ 8192·6·78·8 B = 31 MB of blocks at a time


def design_chunks(spec, config: ModelConfig, q, qd, qdd, segment=None, t=None,
                  chunk: int = CHUNK_SAMPLES, temperature=None):
    """Yield ``(start, stop, blocks)``: :func:`design_blocks` of samples [start, stop) equal to the
    rows of the whole-array call, at most ``chunk`` samples at a time (bounded memory). A chunk never
    spans two segments; within one, the next chunk restarts one sample early with the friction
    states of that sample (``state``) and drops it, so history-driven states continue exactly."""
    q, qd, qdd = (np.asarray(x, dtype=float) for x in (q, qd, qdd))
    t = None if t is None else np.asarray(t, dtype=float)
    n = len(q)
    if chunk < 2:
        raise ValueError("chunk must hold at least two samples")
    seg = np.zeros(n, dtype=int) if segment is None else np.asarray(segment)
    bounds = np.r_[0, np.flatnonzero(np.diff(seg) != 0) + 1, n]
    for a, b in zip(bounds[:-1], bounds[1:]):
        state: dict = {}
        start = int(a)
        while start < b:
            stop = int(min(start + chunk, b))
            lo = start - 1 if start > a else start
            part = slice(lo, stop)
            blocks = design_blocks(spec, config, q[part], qd[part], qdd[part], None,
                                   None if t is None else t[part], state,
                                   None if temperature is None else temperature[part])
            yield start, stop, blocks[start - lo:]
            start = stop


def design_matrix(spec, config: ModelConfig, q, qd, qdd, segment=None, t=None,
                  state: dict | None = None, temperature=None) -> np.ndarray:
    """Stacked (6N, n) regressor, row 6k + j."""
    blocks = design_blocks(spec, config, q, qd, qdd, segment, t, state, temperature)
    return blocks.reshape(-1, blocks.shape[2])
