"""The JSON report's schema (``report.schema.json``, shipped with the package) and a validator for
the part of JSON Schema (draft 7) it uses: ``type`` (one or a list), ``properties``, ``required``,
``additionalProperties`` (false or a schema), ``items``, ``enum``, ``minimum``, ``maximum``,
``minItems``, ``maxItems`` and ``$ref`` to ``#/definitions/NAME``. A number must also be finite: the
report writes no NaN, None or infinity (a quantity it cannot compute is absent, named under
``absent`` with the reason)."""

from __future__ import annotations

import json
import math
from functools import lru_cache
from importlib import resources

_TYPES = {"object": dict, "array": list, "string": str, "boolean": bool}


@lru_cache(maxsize=1)
def report_schema() -> dict:
    """The schema of ``urident gap --json-out`` (and of ``GapResult.as_dict()``)."""
    text = resources.files("urident.gap").joinpath("report.schema.json").read_text(encoding="utf-8")
    return json.loads(text)


def _is(value, kind: str) -> bool:
    if kind == "null":
        return value is None
    if kind == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    return isinstance(value, _TYPES[kind])


def errors(doc, schema: dict | None = None) -> list[str]:
    """Every place where ``doc`` breaks ``schema`` (default :func:`report_schema`), as
    ``path: what``; empty when it conforms."""
    root = report_schema() if schema is None else schema
    out: list[str] = []
    _check(doc, root, root, "$", out)
    return out


def _check(x, s: dict, root: dict, path: str, out: list[str]) -> None:
    if "$ref" in s:
        name = s["$ref"].split("/")[-1]
        s = root["definitions"][name]
    if isinstance(x, float) and not math.isfinite(x):
        out.append(f"{path}: {x} is not a finite number")
        return
    kinds = s.get("type")
    if kinds is not None:
        kinds = [kinds] if isinstance(kinds, str) else kinds
        if not any(_is(x, k) for k in kinds):
            out.append(f"{path}: {_shown(x)} is not of type {'/'.join(kinds)}")
            return
    if "enum" in s and x not in s["enum"]:
        out.append(f"{path}: {x!r} is not one of {s['enum']}")
    if isinstance(x, (int, float)) and not isinstance(x, bool):
        if "minimum" in s and x < s["minimum"]:
            out.append(f"{path}: {x} < {s['minimum']}")
        if "maximum" in s and x > s["maximum"]:
            out.append(f"{path}: {x} > {s['maximum']}")
    if isinstance(x, dict):
        props = s.get("properties", {})
        for k in s.get("required", ()):
            if k not in x:
                out.append(f"{path}: required key {k!r} missing")
        extra = s.get("additionalProperties", True)
        for k, v in x.items():
            if k in props:
                _check(v, props[k], root, f"{path}.{k}", out)
            elif extra is False:
                out.append(f"{path}: unexpected key {k!r}")
            elif isinstance(extra, dict):
                _check(v, extra, root, f"{path}.{k}", out)
    if isinstance(x, list):
        if "minItems" in s and len(x) < s["minItems"]:
            out.append(f"{path}: fewer than {s['minItems']} items")
        if "maxItems" in s and len(x) > s["maxItems"]:
            out.append(f"{path}: more than {s['maxItems']} items")
        if "items" in s:
            for i, v in enumerate(x):
                _check(v, s["items"], root, f"{path}[{i}]", out)


def _shown(x) -> str:
    """The start of a value, for an error line."""
    text = json.dumps(x)
    return text if len(text) <= 40 else text[:37] + "..."
