"""Parameter declarations of the effects and their strict validation.

Every parameter of an effect is declared once as a :class:`Param` (key with unit, kind, default,
bounds, one-line doc); the effects-file parser, the catalogue listing and the README all read
these declarations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from urident.errors import ConfigError

N_JOINTS = 6

#: Parameter kinds. ``joint``: a number for every listed joint, or a list with one number per
#: listed joint; ``number``: one number; ``vector3``: three numbers; ``choice``: one of ``choices``.
KINDS = ("joint", "number", "vector3", "choice")


@dataclass(frozen=True)
class Param:
    """One parameter of an effect."""

    key: str
    kind: str
    default: Any  # None: optional, with the fallback described in ``doc``
    doc: str
    low: float | None = None  # lower bound
    low_inclusive: bool = True
    high: float | None = None  # upper bound (inclusive)
    choices: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown parameter kind {self.kind!r}")

    def describe(self) -> str:
        """``key = default`` plus bounds, for the catalogue listing."""
        if self.kind == "choice":
            default = f"{self.default} (one of {', '.join(self.choices)})"
        elif self.default is None:
            default = "optional"
        else:
            default = f"{self.default}"
        per_joint = ", per joint" if self.kind == "joint" else ""
        return f"{self.key} = {default}{per_joint}: {self.doc}"

    def bounds_text(self) -> str:
        parts = []
        if self.low is not None:
            parts.append(f"{'>=' if self.low_inclusive else '>'} {self.low:g}")
        if self.high is not None:
            parts.append(f"<= {self.high:g}")
        return " and ".join(parts)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_number(value: Any, param: Param, where: str) -> float:
    """A finite number within the bounds of ``param``; ``where`` names file and key path."""
    if not _is_number(value):
        raise ConfigError(f"{where}: expected a number, got {_show(value)}")
    try:
        x = float(value)
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise ConfigError(f"{where}: expected a finite number, got {x}")
    lo, hi = param.low, param.high
    if lo is not None and (x < lo or (x == lo and not param.low_inclusive)):
        raise ConfigError(f"{where}: must be {param.bounds_text()}, got {x:g}")
    if hi is not None and x > hi:
        raise ConfigError(f"{where}: must be {param.bounds_text()}, got {x:g}")
    return x


def parse_value(value: Any, param: Param, joints: tuple[int, ...], where: str) -> Any:
    """Validate one given parameter value. ``joint`` kind returns a (6,) array that holds the
    values of the listed ``joints`` (0-based) and NaN elsewhere."""
    if param.kind == "number":
        return check_number(value, param, where)
    if param.kind == "choice":
        if not isinstance(value, str) or value not in param.choices:
            raise ConfigError(f"{where}: must be one of {', '.join(param.choices)}, got {_show(value)}")
        return value
    if param.kind == "vector3":
        if not isinstance(value, list) or len(value) != 3:
            raise ConfigError(f"{where}: expected a list of 3 numbers, got {_show(value)}")
        return np.array([check_number(v, param, f"{where}[{k}]") for k, v in enumerate(value)])
    out = np.full(N_JOINTS, np.nan)
    if isinstance(value, list):
        if len(value) != len(joints):
            raise ConfigError(f"{where}: expected {len(joints)} values (one per joint in 'joints') "
                              f"or one number, got {len(value)}")
        for k, (joint, v) in enumerate(zip(joints, value)):
            out[joint] = check_number(v, param, f"{where}[{k}]")
    else:
        x = check_number(value, param, where)
        out[list(joints)] = x
    return out


def default_value(param: Param, joints: tuple[int, ...]) -> Any:
    """The default of ``param`` in parsed form (``None`` stays ``None``)."""
    if param.default is None:
        return None
    if param.kind == "joint":
        out = np.full(N_JOINTS, np.nan)
        out[list(joints)] = float(param.default)
        return out
    if param.kind == "vector3":
        return np.array(param.default, dtype=float)
    if param.kind == "number":
        return float(param.default)
    return param.default


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
