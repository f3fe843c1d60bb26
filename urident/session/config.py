"""Experiment configuration of a session: servo parameters, approach, rest and monitor thresholds.

Read from YAML (``urident run --config FILE``; ``experiments/session.yaml`` documents every key);
unknown keys are rejected, and every error names the file and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from urident.errors import ConfigError, shown
from urident.yamlio import Fields, load_yaml

# ur_rtde enforces these ranges for servoJ.
LOOKAHEAD_RANGE_S = (0.03, 0.2)
GAIN_RANGE = (100.0, 2000.0)


@dataclass(frozen=True)
class ServoConfig:
    lookahead_time_s: float = 0.1   # servoJ smoothing lookahead [s], 0.03-0.2
    gain: float = 300.0             # servoJ proportional gain, 100-2000


@dataclass(frozen=True)
class ApproachConfig:
    speed_rad_s: float = 0.3            # moveJ speed of the leading joint to the start [rad/s]
    acceleration_rad_s2: float = 0.5    # moveJ acceleration [rad/s^2]
    max_distance_rad: float = 2.0       # refuse to approach a start farther than this (any joint)


@dataclass(frozen=True)
class MonitorConfig:
    max_tracking_error_rad: float = 0.25   # |q_cmd − q| on any joint
    max_stale_periods: int = 25            # controller timestamp unchanged this many cycles
    late_tolerance_s: float = 0.0005       # a cycle is late when its work overruns the period by this
    max_consecutive_late: int = 50         # abort after this many late cycles in a row
    max_late_fraction: float = 0.05        # … or when this fraction of cycles is late (after 1 s)


@dataclass(frozen=True)
class ExperimentConfig:
    servo: ServoConfig = field(default_factory=ServoConfig)
    approach: ApproachConfig = field(default_factory=ApproachConfig)
    monitors: MonitorConfig = field(default_factory=MonitorConfig)
    rest_s: float = 1.0          # hold the final point for this long before stopping [s]
    source: str | None = None

    def __post_init__(self) -> None:
        where = self.source or "experiment configuration"
        lo, hi = LOOKAHEAD_RANGE_S
        if not lo <= self.servo.lookahead_time_s <= hi:
            raise ConfigError(f"{where}: servo.lookahead_time_s: must be in [{lo}, {hi}] s, "
                              f"not {self.servo.lookahead_time_s}")
        lo, hi = GAIN_RANGE
        if not lo <= self.servo.gain <= hi:
            raise ConfigError(f"{where}: servo.gain: must be in [{lo:g}, {hi:g}], not {self.servo.gain}")
        if self.approach.speed_rad_s > 1.0:
            raise ConfigError(f"{where}: approach.speed_rad_s: must be at most 1.0 rad/s (a slow approach)")


_SECTIONS = {"servo": ServoConfig, "approach": ApproachConfig, "monitors": MonitorConfig}


def load_experiment_config(path: str | Path | None) -> ExperimentConfig:
    """The configuration in ``path``, or the defaults when ``path`` is None."""
    if path is None:
        return ExperimentConfig()
    path = Path(path)
    data = load_yaml(path, "experiment configuration")
    f = Fields(path)
    if data is None:
        data = {}
    f.mapping(data, "", "a mapping at the top level")
    f.keys(data, set(_SECTIONS) | {"rest_s"}, "")
    kwargs: dict[str, Any] = {"source": str(path)}
    for name, cls in _SECTIONS.items():
        section = f.mapping(data.get(name) or {}, name)
        kwargs[name] = _build(cls, section, f, name)
    if "rest_s" in data:
        kwargs["rest_s"] = _number(data["rest_s"], f, "rest_s", float)
    return ExperimentConfig(**kwargs)


def _build(cls: type, section: dict, f: Fields, prefix: str) -> Any:
    known = {x.name: x for x in fields(cls)}
    f.keys(section, known, prefix)
    values = {}
    for key, value in section.items():
        kind = int if known[key].type in ("int", int) else float
        values[key] = _number(value, f, f"{prefix}.{key}", kind)
    return replace(cls(), **values)


def _number(value: Any, f: Fields, key: str, kind: type) -> float | int:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise f.fail(key, f"must be a number, not {shown(value)!r}")
    try:
        finite = math.isfinite(value)
    except OverflowError:
        finite = False
    if not finite or value < 0:
        raise f.fail(key, f"must be a finite non-negative number, not {shown(value)}")
    if kind is int and value != int(value):
        raise f.fail(key, f"must be a whole number, not {value}")
    return kind(value)
