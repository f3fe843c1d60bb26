"""The one strict YAML reader of every urident file format (robot, trajectory, parameters,
experiment configuration, effects, log sidecar).

    data = load_yaml(path, "robot file")                 # read + parse, or raise one line
    f = Fields(path)                                    # typed access naming the key path
    mass = f.number(link, "mass", "joints[0].link", positive=True)

Every error is one line ``FILE: key.path: message`` (``FILE:LINE: ...`` where the parser gives a
line): the file cannot be read (missing, a directory, no permission, not UTF-8), YAML syntax,
a key given twice in one mapping (``FILE:LINE: key.path: duplicate key``; the last one would
silently win otherwise), unknown keys, wrong types and values. The exception class is the
format's own (``ConfigError``, ``ParamsFileError``, ``LogFormatError``, ...).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import yaml

from urident.errors import ConfigError, UridentError, shown

# libyaml's parser when available (~20x faster); the constructor stays PyYAML's SafeConstructor.
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_MERGE_TAG = "tag:yaml.org,2002:merge"


def key_path(where: str, key: Any) -> str:
    """``where.key`` (``key`` alone at the top level); ``[i]`` items are appended as they are."""
    key = shown(key)
    if not where:
        return key
    return f"{where}{key}" if key.startswith("[") else f"{where}.{key}"


def read_text(path: str | Path, what: str, error: type[Exception] = ConfigError) -> str:
    """The UTF-8 text of ``path``; one-line ``error`` naming the file when it cannot be read."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{path}: {what} not found") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, not a file ({what})") from None
    except OSError as exc:
        raise error(f"{path}: cannot read {what}: {exc.strerror or type(exc).__name__}") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: {what} is not UTF-8 text (byte {exc.start})") from None


def parse_yaml(text: str, label: str, error: type[Exception] = ConfigError) -> Any:
    """Parse one YAML document strictly (safe types only, duplicate keys rejected)."""
    try:
        loader = _Loader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            _check_duplicates(node, "", label, error)
            return loader.construct_document(node)
        finally:
            loader.dispose()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark is not None else ""
        parts = [p for p in (exc.context, exc.problem) if p] or ["malformed YAML"]
        problem = " ".join(", ".join(map(str, parts)).split())
        raise error(f"{label}{line}: malformed YAML ({shown(problem, 100)})",
                    **_data(error, path=label, line=None if mark is None else mark.line + 1)) from None
    except error:
        raise
    except Exception as exc:  # noqa: BLE001 - any parser failure on untrusted input is one line
        message = " ".join(str(exc).split()) or type(exc).__name__
        raise error(f"{label}: malformed YAML ({shown(message, 100)})") from None


def load_yaml(path: str | Path, what: str, error: type[Exception] = ConfigError) -> Any:
    """:func:`read_text` then :func:`parse_yaml`; errors name ``path``."""
    return parse_yaml(read_text(path, what, error), str(path), error)


def _check_duplicates(node: yaml.Node, where: str, label: str, error: type[Exception]) -> None:
    seen_nodes: set[int] = set()
    stack = [(node, where)]
    while stack:
        node, where = stack.pop()
        if id(node) in seen_nodes:  # an alias: checked once (also ends recursive structures)
            continue
        seen_nodes.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            stack.extend((item, f"{where}[{i}]") for i, item in enumerate(node.value))
        elif isinstance(node, yaml.MappingNode):
            keys: set[tuple[str, str]] = set()
            for key_node, value_node in node.value:
                if not isinstance(key_node, yaml.ScalarNode):
                    stack.append((value_node, where))
                    continue
                if key_node.tag == _MERGE_TAG:
                    stack.append((value_node, where))
                    continue
                ident = (key_node.tag, key_node.value)
                path = key_path(where, key_node.value)
                if ident in keys:
                    raise error(f"{label}:{key_node.start_mark.line + 1}: {path}: duplicate key",
                                **_data(error, path=label, line=key_node.start_mark.line + 1, key=path))
                keys.add(ident)
                stack.append((value_node, path))


def _data(error: type[Exception], **data) -> dict:
    """``data`` for the fields of a :class:`UridentError` (other exception types take none)."""
    return data if issubclass(error, UridentError) else {}


class Fields:
    """Typed access to parsed YAML with errors ``LABEL: key.path: message``.

    ``where`` is the key path of the mapping being read ("" at the top level)."""

    def __init__(self, label: str | Path, error: type[Exception] = ConfigError):
        self.label = str(label)
        self.error = error

    def fail(self, where: str, message: str) -> Exception:
        """The error to raise for ``where`` (a full key path; "" for the whole file)."""
        return self.error(f"{self.label}: {where}: {message}" if where else f"{self.label}: {message}",
                          **_data(self.error, path=self.label, key=where or None))

    def document(self, data: Any, keys: set, required: tuple, fmt: str, what: str) -> dict:
        """The top-level mapping of a ``format: FMT`` file: not empty, only ``keys``, every
        ``required`` key present, the right format."""
        if data is None:
            raise self.fail("", f"{what} is empty")
        self.mapping(data, "", "a mapping at the top level")
        self.keys(data, keys, "", required=required)
        if data["format"] != fmt:
            raise self.fail("format", f"is {str(data['format'])[:40]!r}, expected {fmt!r}")
        return data

    def mapping(self, value: Any, where: str, what: str = "a mapping") -> dict:
        if not isinstance(value, dict):
            raise self.fail(where, f"expected {what}, got {_kind(value)}")
        return value

    def keys(self, mapping: dict, allowed: Iterable[str], where: str,
             required: Iterable[str] = ()) -> None:
        """Reject unknown keys (and non-text keys), then missing ``required`` ones."""
        allowed = set(allowed)
        unknown = sorted((str(k) for k in mapping if not isinstance(k, str) or k not in allowed))
        if unknown:
            raise self.fail(key_path(where, unknown[0]),
                            f"unknown key (allowed: {', '.join(sorted(allowed))})")
        for key in required:
            if key not in mapping:
                raise self.fail(key_path(where, key), "missing key")

    def get(self, mapping: dict, key: str, kind: Any, where: str = "") -> Any:
        name = key_path(where, key)
        if key not in mapping:
            raise self.fail(name, "missing key")
        value = mapping[key]
        if not isinstance(value, kind) or (isinstance(value, bool) and bool not in _tuple(kind)):
            raise self.fail(name, f"has the wrong type ({_kind(value)})")
        return value

    def integer(self, mapping: dict, key: str, where: str = "", minimum: int | None = None,
                maximum: int | None = None) -> int:
        value = int(self.get(mapping, key, int, where))
        if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            bounds = f"between {minimum} and {maximum}" if minimum is not None and maximum is not None \
                else (f"at least {minimum}" if minimum is not None else f"at most {maximum}")
            raise self.fail(key_path(where, key), f"must be {bounds}, not {value}")
        return value

    def number(self, mapping: dict, key: str, where: str = "", positive: bool = False,
               nonnegative: bool = False) -> float:
        name = key_path(where, key)
        try:
            value = float(self.get(mapping, key, (int, float), where))
        except OverflowError:
            raise self.fail(name, "is out of range") from None
        if not math.isfinite(value):
            raise self.fail(name, "must be finite")
        if positive and value <= 0:
            raise self.fail(name, f"must be positive, not {value:g}")
        if nonnegative and value < 0:
            raise self.fail(name, f"must not be negative, not {value:g}")
        return value

    def array(self, mapping: dict, key: str, where: str, shape: tuple[int, ...] | int) -> np.ndarray:
        """A finite float array of exactly ``shape`` from nested lists of numbers."""
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        name = key_path(where, key)
        value = self.get(mapping, key, list, where)
        described = "x".join(map(str, shape))
        what = f"a list of {shape[0]} numbers" if len(shape) == 1 else f"a {described} list of numbers"
        if not _is_numeric_nest(value, len(shape)):
            raise self.fail(name, f"must be {what}")
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise self.fail(name, f"must be {what}") from None
        if array.shape != shape:
            raise self.fail(name, f"must be {what}, not shape {'x'.join(map(str, array.shape))}")
        if not np.all(np.isfinite(array)):
            raise self.fail(name, "must hold finite numbers")
        return array


def _tuple(kind: Any) -> tuple:
    return kind if isinstance(kind, tuple) else (kind,)


def _kind(value: Any) -> str:
    return "nothing" if value is None else type(value).__name__


def _is_numeric_nest(value: Any, depth: int) -> bool:
    if depth == 0:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, list) and all(_is_numeric_nest(v, depth - 1) for v in value)
