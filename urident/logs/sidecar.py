"""The YAML sidecar (``LOG.yaml`` beside ``LOG.csv``): atomic write, validated read."""

from __future__ import annotations

import datetime as _dt
import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from urident.errors import LogFormatError, shown
from urident.fileio import write_text_atomic
from urident.yamlio import load_yaml

from .schema import FORMAT_NAME, SIDECAR_KEYS, STATUSES


def utc_now_iso() -> str:
    """Current time, ISO 8601 UTC with µs and a ``Z`` suffix."""
    now = _dt.datetime.now(_dt.timezone.utc)
    return now.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes; of a directory (a rosbag2 bag), of its files' relative names
    and bytes in name order. The one content hash of urident (logs, trajectories, held-out checks)."""
    digest = hashlib.sha256()
    path = Path(path)
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        if path.is_dir():
            digest.update(str(file.relative_to(path)).encode() + b"\0")
        with open(file, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                digest.update(chunk)
    return digest.hexdigest()


def write_sidecar(path: str | Path, data: dict[str, Any]) -> None:
    """Write ``data`` as YAML atomically (temp file, fsync, rename), so a crash leaves either the
    old or the new sidecar, never half of one."""
    text = yaml.safe_dump(_plain(data), sort_keys=False, default_flow_style=None, width=100)
    write_text_atomic(path, text)


def _plain(value: Any) -> Any:
    """Convert numpy scalars/arrays, tuples and paths to plain YAML-safe Python values."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "tolist"):  # numpy array or scalar
        return _plain(value.tolist())
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)


def read_sidecar(path: str | Path) -> dict[str, Any]:
    """Read and validate a sidecar; any defect is a one-line LogFormatError naming the key."""
    path = Path(path)
    data = load_yaml(path, "sidecar", LogFormatError)
    if data is None:
        raise LogFormatError(f"{path}: sidecar is empty")
    if not isinstance(data, dict):
        raise LogFormatError(f"{path}: sidecar must be a YAML mapping, got {type(data).__name__}")
    out: dict[str, Any] = {}
    for key, value in data.items():
        if not isinstance(key, str):
            raise LogFormatError(f"{path}: {shown(key)}: sidecar key is not a string")
        if isinstance(value, (_dt.datetime, _dt.date)):
            value = value.isoformat()
        out[key] = value
        if key not in SIDECAR_KEYS or value is None:
            continue
        types = SIDECAR_KEYS[key]
        if isinstance(value, bool) or not isinstance(value, types):
            names = " or ".join(t.__name__ for t in types)
            raise LogFormatError(f"{path}: {key}: must be {names}, got {type(value).__name__}")
    _check_values(path, out)
    return out


def _finite(value: float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer beyond float range
        return False


def _check_values(path: Path, data: dict[str, Any]) -> None:
    fmt = data.get("format")
    if fmt is not None and fmt != FORMAT_NAME:
        raise LogFormatError(f"{path}: format: is {shown(fmt)!r}, expected {FORMAT_NAME!r}")
    status = data.get("status")
    if status is not None and status not in STATUSES:
        raise LogFormatError(
            f"{path}: status: is {shown(status)!r}, expected one of {', '.join(STATUSES)}"
        )
    rate = data.get("rate_hz")
    if rate is not None and not (_finite(rate) and 0 < rate <= 1e6):
        raise LogFormatError(f"{path}: rate_hz: must be a positive rate, got {rate}")
    for key in ("late_cycles", "duplicates_skipped", "n_samples", "format_version"):
        value = data.get(key)
        if value is not None and value < 0:
            raise LogFormatError(f"{path}: {key}: must be >= 0, got {value}")
    for key in ("gear_ratios", "torque_constants"):
        value = data.get(key)
        if value is None:
            continue
        ok = len(value) == 6 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and _finite(v)
            for v in value
        )
        if not ok:
            raise LogFormatError(f"{path}: {key}: must be a list of 6 finite numbers")
    columns = data.get("columns")
    if columns is not None and not all(isinstance(c, str) for c in columns):
        raise LogFormatError(f"{path}: columns: must be a list of column names")
    robot = data.get("robot")
    if robot is not None and not robot.strip():
        raise LogFormatError(f"{path}: robot: is empty")


#: ``extra`` key of the payload declared to the controller during the run (``urident run`` reads
#: the controller's RTDE ``payload``, ``payload_cog``, ``payload_inertia`` when the version has them).
DECLARED_PAYLOAD_KEY = "declared_payload"


@dataclass(frozen=True)
class DeclaredPayload:
    """The payload the controller was told during a run: mass [kg], centre of mass [m] (3, flange
    frame) and inertia [kg·m²] (6: Ixx, Iyy, Izz, Ixy, Ixz, Iyz) when the controller publishes it."""

    mass_kg: float
    cog_m: tuple[float, float, float]
    inertia_kg_m2: tuple[float, ...] | None


def declared_payload(metadata: dict[str, Any]) -> DeclaredPayload | None:
    """The :class:`DeclaredPayload` of a log's sidecar metadata, or None when it records none (or
    nothing usable)."""
    extra = metadata.get("extra") if isinstance(metadata, dict) else None
    value = extra.get(DECLARED_PAYLOAD_KEY) if isinstance(extra, dict) else None
    if not isinstance(value, dict):
        return None
    try:
        mass = float(value["mass_kg"])
        cog = [float(v) for v in value.get("cog_m") or [0.0, 0.0, 0.0]]
        inertia = value.get("inertia_kg_m2")
        inertia = None if inertia is None else [float(v) for v in inertia]
    except (KeyError, TypeError, ValueError):
        return None
    if not _finite(mass) or len(cog) != 3 or (inertia is not None and len(inertia) != 6):
        return None
    return DeclaredPayload(mass, tuple(cog), None if inertia is None else tuple(inertia))


def describe_declared_payload(metadata: dict[str, Any]) -> str | None:
    """One line for reports: the payload the controller was told during the run, or None."""
    p = declared_payload(metadata)
    if p is None:
        return None
    cog = ", ".join(f"{1000 * v:.1f}" for v in p.cog_m)
    inertia = ("" if p.inertia_kg_m2 is None
               else ", inertia [" + ", ".join(f"{v:.5g}" for v in p.inertia_kg_m2) + "] kg·m²")
    return (f"payload declared to the controller during the run (sidecar): {p.mass_kg:.4g} kg, "
            f"centre of mass [{cog}] mm{inertia}")
