"""Effects files: YAML parsing and strict validation into a frozen :class:`EffectsConfig`.

Format (SI units; joints numbered 1–6 as on the teach pendant)::

    description: free text (optional)
    effects:
      - name: stribeck                 # an effect of the catalogue
        joints: [1, 2, 3]              # optional, default all six
        static_friction_ratio: 1.3     # one number for every listed joint ...
        stribeck_velocity_rad_s: [0.02, 0.02, 0.03]   # ... or one per listed joint
      - name: current_delay
        delay_s: 0.003

Parameters not given take their catalogue default (``urident simulate --list-effects``). One
effect may appear in several entries for different joints, never twice for one joint. Every
defect is a one-line :class:`~urident.errors.ConfigError` naming the file and the key path, e.g.
``effects.yaml: effects[1].delay_s[2]: must be >= 0, got -0.1``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from urident.errors import ConfigError
from urident.yamlio import parse_yaml, read_text
from urident.simcontroller.effects.catalogue import EFFECT_NAMES, EFFECTS
from urident.simcontroller.effects.params import N_JOINTS, default_value, parse_value

PRESETS_DIR = Path(__file__).resolve().parent.parent / "presets"
TOP_KEYS = ("description", "effects")
ENTRY_KEYS = ("name", "joints")


@dataclass(frozen=True, eq=False)
class EffectConfig:
    """One validated entry: effect ``name`` on 0-based ``joints`` with every parameter (given or
    default) in ``values`` (per-joint parameters as (6,) arrays, NaN on joints not listed)."""

    name: str
    index: int
    joints: tuple[int, ...]
    values: dict[str, Any]
    given: frozenset[str]

    def as_dict(self) -> dict[str, Any]:
        """Plain YAML-safe form with every parameter explicit (joints 1-based)."""
        out: dict[str, Any] = {"name": self.name, "joints": [j + 1 for j in self.joints]}
        for param in EFFECTS[self.name].params:
            v = self.values[param.key]
            if v is None:
                continue
            if param.kind == "joint":
                out[param.key] = [float(v[j]) for j in self.joints]
            elif param.kind == "vector3":
                out[param.key] = [float(x) for x in v]
            else:
                out[param.key] = v
        return out


@dataclass(frozen=True, eq=False)
class EffectsConfig:
    """A parsed effects file. ``source`` is what the user gave (path or preset name), ``path``
    the file read (None for text parsed directly), ``text`` its content."""

    source: str
    path: Path | None
    text: str
    description: str
    entries: tuple[EffectConfig, ...]

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the effects present, in catalogue order, each once."""
        present = {e.name for e in self.entries}
        return tuple(n for n in EFFECT_NAMES if n in present)

    def as_dict(self) -> dict[str, Any]:
        return {"description": self.description, "effects": [e.as_dict() for e in self.entries]}


def available_presets() -> list[str]:
    return sorted(p.stem for p in PRESETS_DIR.glob("*.yaml"))


def preset_path(name: str) -> Path:
    path = PRESETS_DIR / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"unknown effects preset '{name}'; presets: {', '.join(available_presets())}")
    return path


def resolve(source: str | Path) -> Path:
    """The file of ``source``: an existing path, or the name of a preset (``realistic``)."""
    text = str(source)
    path = Path(text)
    if path.is_file() or (path.exists() and ("/" in text or text.endswith((".yaml", ".yml")))):
        return path  # a directory or unreadable file given as a path: read_text names it
    if isinstance(source, Path) or "/" in text or text.endswith((".yaml", ".yml")) or not text:
        raise ConfigError(f"{text}: effects file not found")
    if (PRESETS_DIR / f"{text}.yaml").is_file():
        return PRESETS_DIR / f"{text}.yaml"
    raise ConfigError(f"{text}: no such effects file or preset; presets: "
                      f"{', '.join(available_presets())}")


def parse_effects(source: str | Path) -> EffectsConfig:
    """Read and validate an effects file or preset (see the module docstring)."""
    path = resolve(source)
    text = read_text(path, "effects file")
    return parse_effects_text(text, str(path), source=str(source), path=path)


def parse_effects_text(text: str, label: str = "<effects>", *, source: str | None = None,
                       path: Path | None = None) -> EffectsConfig:
    """Validate effects-file ``text``; error messages name ``label``."""
    data = parse_yaml(text, label)
    if data is None:
        raise ConfigError(f"{label}: effects file is empty; write 'effects: []' for no effects")
    if not isinstance(data, dict):
        raise ConfigError(f"{label}: expected a mapping with key 'effects', got {type(data).__name__}")
    for key in data:
        if key not in TOP_KEYS:
            raise ConfigError(f"{label}: {_key(key)}: unknown key; allowed: {', '.join(TOP_KEYS)}")
    if "effects" not in data:
        raise ConfigError(f"{label}: effects: missing key (a list of effects, [] for none)")
    description = data.get("description", "")
    if description is None:
        description = ""
    if not isinstance(description, str):
        raise ConfigError(f"{label}: description: expected text")
    items = data["effects"]
    if not isinstance(items, list):
        raise ConfigError(f"{label}: effects: expected a list of effects, got {type(items).__name__}")
    entries: list[EffectConfig] = []
    owners: dict[tuple[str, int], int] = {}
    for i, item in enumerate(items):
        entry = _parse_entry(item, i, label)
        for j in entry.joints:
            if (entry.name, j) in owners:
                raise ConfigError(f"{label}: effects[{i}].joints: joint {j + 1} already has "
                                  f"{entry.name} (effects[{owners[entry.name, j]}])")
            owners[entry.name, j] = i
        entries.append(entry)
    return EffectsConfig(source=source if source is not None else label, path=path, text=text,
                         description=description, entries=tuple(entries))


def _parse_entry(item: Any, i: int, label: str) -> EffectConfig:
    where = f"{label}: effects[{i}]"
    if not isinstance(item, dict):
        raise ConfigError(f"{where}: expected a mapping with 'name', got {type(item).__name__}")
    for key in item:
        if not isinstance(key, str):
            raise ConfigError(f"{where}: key {key!r} is not text")
    name = item.get("name")
    if name is None:
        raise ConfigError(f"{where}.name: missing; catalogue: {', '.join(EFFECT_NAMES)}")
    if not isinstance(name, str) or name not in EFFECTS:
        raise ConfigError(f"{where}.name: unknown effect {name!r}; catalogue: {', '.join(EFFECT_NAMES)}")
    cls = EFFECTS[name]
    params = {p.key: p for p in cls.params}
    for key in item:
        if key not in ENTRY_KEYS and key not in params:
            allowed = ", ".join(["joints", *params])
            raise ConfigError(f"{where}.{_key(key)}: unknown parameter of {name}; parameters: {allowed}")
    joints = _parse_joints(item.get("joints", list(range(1, N_JOINTS + 1))), f"{where}.joints")
    values: dict[str, Any] = {}
    given = set()
    for key, param in params.items():
        if key in item:
            values[key] = parse_value(item[key], param, joints, f"{where}.{key}")
            given.add(key)
        else:
            values[key] = default_value(param, joints)
    cls.check_entry(values, given, where)
    return EffectConfig(name=name, index=i, joints=joints, values=values, given=frozenset(given))


def _parse_joints(value: Any, where: str) -> tuple[int, ...]:
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where}: expected a non-empty list of joint numbers 1-{N_JOINTS}")
    out = []
    for k, j in enumerate(value):
        if isinstance(j, bool) or not isinstance(j, int) or not 1 <= j <= N_JOINTS:
            raise ConfigError(f"{where}[{k}]: joint must be an integer 1-{N_JOINTS}, got {j!r}")
        if j - 1 in out:
            raise ConfigError(f"{where}[{k}]: joint {j} listed twice")
        out.append(j - 1)
    return tuple(out)


def _key(key) -> str:
    """A key as written in messages: plain when it is a simple name, else quoted."""
    text = str(key)
    if isinstance(key, str) and text.isprintable() and text and " " not in text:
        return text
    return repr(key)
