"""Column maps for foreign (headerless) CSV logs, and named presets.

Two spellings, both parsed by :func:`parse_column_map`:

* explicit, 0-based file columns, Python slices (stop excluded)::

      t=0,q=1:7,qd=7:13,current=13:19        # optional ncols=31 fixes the column count

* sequential layout: field names in file order, a joint field takes 6 columns, ``qN..qM``
  spelling accepted, ``skip`` / ``skip*N`` skips columns; the column count is then exact::

      t,q,qd,i,i_des,tau_des
      t,q1..q6,qd1..qd6,i1..i6,i_des1..i_des6,tau_des1..tau_des6

Field names: ``t q qd current target_q target_qd target_qdd target_current target_moment temperature
tau robot_mode safety_status_bits runtime_state``, the ur_rtde names (``timestamp``, ``actual_q`` …)
and the aliases ``time``, ``i`` (current), ``i_des`` (target_current), ``tau_des``
(target_moment), ``q_des``, ``qd_des``, ``qdd_des``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping

from urident.errors import LogFormatError

from .schema import FIELDS_BY_ATTR, FIELDS_BY_NAME, REQUIRED_ATTRS


class ColumnMapError(LogFormatError):
    """A column map (``--columns``) or format preset (``--format``) is malformed."""


_ALIASES: dict[str, str] = {
    "time": "t",
    "i": "current",
    "i_des": "target_current",
    "tau_des": "target_moment",
    "q_des": "target_q",
    "qd_des": "target_qd",
    "qdd_des": "target_qdd",
}
_ALIASES.update({f.name: f.attr for f in FIELDS_BY_NAME.values()})
_ALIASES.update({attr: attr for attr in FIELDS_BY_ATTR})

#: Named presets for ``--format``: name -> (column map, description).
PRESETS: dict[str, tuple[str, str]] = {
    "dynamic_calibration": (
        "t,q,qd,i,i_des,tau_des",
        "shamilmamedov/dynamic_calibration UR10e CSV, 31 columns: "
        "t,q1..q6,qd1..qd6,i1..i6,i_des1..i_des6,tau_des1..tau_des6",
    ),
    "dynamic_calibration_19": (
        "t,q,qd,i",
        "dynamic_calibration CSV with 19 columns: t,q1..q6,qd1..qd6,i1..i6",
    ),
}


@dataclass(frozen=True)
class ColumnMap:
    """Which 0-based file columns hold which :class:`Recording` attribute."""

    columns: Mapping[str, tuple[int, ...]]  #: attribute -> column indices (1 or 6)
    ncols: int | None = None  #: exact column count every row must have (None: same as line 1)
    spec: str = ""  #: the text it was parsed from (for messages and metadata)

    @property
    def min_ncols(self) -> int:
        return 1 + max(i for cols in self.columns.values() for i in cols)


def _canonical(name: str, spec: str) -> str:
    key = name.strip()
    if key not in _ALIASES:
        known = "t, q, qd, current (i), target_q, target_qd, target_qdd, target_current (i_des), "
        known += "target_moment (tau_des), temperature, tau, robot_mode, safety_status_bits, "
        known += "runtime_state"
        raise ColumnMapError(f"column map {spec!r}: unknown field {key!r} (known: {known})")
    return _ALIASES[key]


_INT = re.compile(r"^\s*(\d+)\s*$")
_SLICE = re.compile(r"^\s*(\d+)\s*:\s*(\d+)\s*$")
_RANGE = re.compile(r"^([A-Za-z_]+?)_?(\d+)\.\.([A-Za-z_]+?)_?(\d+)$")
_SKIP = re.compile(r"^(skip|_)(?:\s*\*\s*(\d+))?$")


def parse_column_map(spec: "str | ColumnMap | Mapping[str, object]") -> ColumnMap:
    """Parse a column map (see module doc) or a preset name; raise :class:`ColumnMapError`."""
    if isinstance(spec, ColumnMap):
        return spec
    if isinstance(spec, Mapping):
        spec = ",".join(f"{k}={_mapping_value(k, v)}" for k, v in spec.items())
    if not isinstance(spec, str):
        raise ColumnMapError(f"column map must be a string, got {type(spec).__name__}")
    text = spec.strip()
    if text in PRESETS:
        cmap = parse_column_map(PRESETS[text][0])
        return ColumnMap(dict(cmap.columns), cmap.ncols, text)
    if not text:
        raise ColumnMapError("column map is empty (e.g. 't=0,q=1:7,qd=7:13,current=13:19')")
    items = [item.strip() for item in text.split(",")]
    if any(not item for item in items):
        raise ColumnMapError(f"column map {spec!r}: empty item (two commas in a row?)")
    explicit = ["=" in item for item in items]
    if all(explicit):
        columns, ncols = _parse_explicit(items, spec)
    elif not any(explicit):
        columns, ncols = _parse_sequential(items, spec)
    else:
        raise ColumnMapError(
            f"column map {spec!r}: mixes 'name=columns' items with a plain layout; use one form"
        )
    return _checked(columns, ncols, spec)


def _mapping_value(key: object, value: object) -> str:
    if isinstance(value, bool):
        raise ColumnMapError(f"column map: bad columns {value!r} for {key!r}")
    if isinstance(value, int):
        return str(value)
    if isinstance(value, (tuple, list)) and len(value) == 2 and all(
        isinstance(v, int) and not isinstance(v, bool) for v in value
    ):
        return f"{value[0]}:{value[1]}"
    if isinstance(value, str):
        return value
    raise ColumnMapError(f"column map: bad columns {value!r} for {key!r} (int or (start, stop))")


def _parse_explicit(items: list[str], spec: str) -> tuple[dict[str, tuple[int, ...]], int | None]:
    columns: dict[str, tuple[int, ...]] = {}
    ncols = None
    for item in items:
        name, _, value = item.partition("=")
        name = name.strip()
        if name == "ncols":
            m = _INT.match(value)
            if not m or int(m.group(1)) < 1:
                raise ColumnMapError(f"column map {spec!r}: ncols={value.strip()!r} is not a count")
            ncols = int(m.group(1))
            continue
        attr = _canonical(name, spec)
        if attr in columns:
            raise ColumnMapError(f"column map {spec!r}: field {name!r} given twice")
        m_int, m_slice = _INT.match(value), _SLICE.match(value)
        if m_int:
            cols = (int(m_int.group(1)),)
        elif m_slice:
            start, stop = int(m_slice.group(1)), int(m_slice.group(2))
            if stop <= start:
                raise ColumnMapError(f"column map {spec!r}: {item!r} is an empty column range")
            cols = tuple(range(start, stop))
        else:
            raise ColumnMapError(
                f"column map {spec!r}: {item!r}: expected NAME=INDEX or NAME=START:STOP "
                "(0-based, stop excluded)"
            )
        columns[attr] = cols
    return columns, ncols


def _parse_sequential(items: list[str], spec: str) -> tuple[dict[str, tuple[int, ...]], int]:
    columns: dict[str, tuple[int, ...]] = {}
    pos = 0
    for item in items:
        m_skip = _SKIP.match(item)
        if m_skip:
            n = int(m_skip.group(2) or 1)
            if n < 1:
                raise ColumnMapError(f"column map {spec!r}: {item!r} skips no column")
            pos += n
            continue
        m_range = _RANGE.match(item)
        if m_range:
            name, first, name2, last = m_range.groups()
            if name != name2 or (int(first), int(last)) not in ((1, 6), (0, 5)):
                raise ColumnMapError(
                    f"column map {spec!r}: {item!r}: a range must be NAME1..NAME6 or NAME0..NAME5"
                )
            attr = _canonical(name, spec)
            if FIELDS_BY_ATTR[attr].width != 6:
                raise ColumnMapError(f"column map {spec!r}: {name!r} is a scalar, not 6 columns")
        else:
            attr = _canonical(item, spec)
        if attr in columns:
            raise ColumnMapError(f"column map {spec!r}: field {item!r} given twice")
        width = FIELDS_BY_ATTR[attr].width
        columns[attr] = tuple(range(pos, pos + width))
        pos += width
    return columns, pos


def _checked(columns: dict[str, tuple[int, ...]], ncols: int | None, spec: str) -> ColumnMap:
    for attr in REQUIRED_ATTRS:
        if attr not in columns:
            raise ColumnMapError(
                f"column map {spec!r}: no column for required field {attr!r} "
                f"(required: {', '.join(REQUIRED_ATTRS)})"
            )
    used: dict[int, str] = {}
    for attr, cols in columns.items():
        width = FIELDS_BY_ATTR[attr].width
        if len(cols) != width:
            raise ColumnMapError(
                f"column map {spec!r}: {attr!r} needs {width} column(s), got {len(cols)}"
            )
        for c in cols:
            if c in used:
                raise ColumnMapError(
                    f"column map {spec!r}: column {c} used by both {used[c]!r} and {attr!r}"
                )
            used[c] = attr
    cmap = ColumnMap(columns, ncols, spec)
    if ncols is not None and cmap.min_ncols > ncols:
        raise ColumnMapError(
            f"column map {spec!r}: uses column {cmap.min_ncols - 1} but ncols={ncols}"
        )
    return cmap


def column_names(cmap: ColumnMap) -> dict[int, str]:
    """File column index -> display name (``q_3``) for messages."""
    names: dict[int, str] = {}
    for attr, cols in cmap.columns.items():
        if len(cols) == 1:
            names[cols[0]] = attr
        else:
            for j, c in enumerate(cols):
                names[c] = f"{attr}_{j}"
    return {c: f"{name} (index {c})" for c, name in names.items()}
