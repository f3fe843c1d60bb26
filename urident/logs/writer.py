"""Crash-safe log writer: CSV rows buffered in memory, flushed at least once a second."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from urident.fileio import check_output, create_exclusive

from .schema import (
    FORMAT_NAME,
    FORMAT_VERSION,
    LOG_FIELDS,
    STATUS_ABORTED,
    STATUS_COMPLETED,
    STATUS_RUNNING,
    STATUSES,
    USER_METADATA_KEYS,
    LogField,
    field_columns,
    resolve_fields,
    sidecar_path,
)
from .sidecar import sha256_file, utc_now_iso, write_sidecar


def _urident_version() -> str:
    try:
        from urident.version import __version__

        return str(__version__)
    except ImportError:  # pragma: no cover
        return "unknown"


class LogWriter:
    """Write a urident log (``path`` CSV + sidecar YAML) from a control loop.

    ``append`` formats one row into an in-memory buffer (~30 µs for the default 79 columns); the
    buffer goes to the OS at least every ``flush_interval_s`` (default 0.5 s) and on ``close``,
    which also fsyncs. A killed process therefore loses at most the last ``flush_interval_s`` of
    samples and leaves a sidecar with ``status: running``. Rows whose timestamp equals the previous
    row's are skipped (counted as ``duplicates_skipped``).

    Used as a context manager, a normal exit closes with ``status: completed``; an exception
    closes with ``status: aborted`` and the exception as ``abort_reason`` (and propagates).

    ``metadata`` keys: robot, controller_version, rate_hz, trajectory_file, trajectory_sha256
    (computed from trajectory_file when omitted and the file exists), gear_ratios,
    torque_constants, start_time (default: now), ``extra`` (free-form dict); other keys are
    added to ``extra``.
    """

    def __init__(
        self,
        path: str | Path,
        fields: Iterable[str | LogField] = LOG_FIELDS,
        metadata: Mapping[str, Any] | None = None,
        *,
        flush_interval_s: float = 0.5,
        overwrite: bool = False,
    ) -> None:
        self.path = Path(path)
        if self.path.suffix != ".csv":
            raise ValueError(f"log path must end in .csv: {self.path}")
        self.sidecar = sidecar_path(self.path)
        self.fields: tuple[LogField, ...] = resolve_fields(fields)
        self.columns: list[str] = field_columns(self.fields)
        self.n_columns = len(self.columns)
        self._row_format = ",".join(f.csv_format for f in self.fields for _ in range(f.width))
        self._row_format += "\n"
        self._offsets: dict[str, tuple[int, int]] = {}
        pos = 0
        for f in self.fields:
            self._offsets[f.name] = (pos, f.width)
            self._offsets.setdefault(f.attr, (pos, f.width))
            pos += f.width
        self.flush_interval_s = float(flush_interval_s)
        self.n_samples = 0
        self.duplicates_skipped = 0
        self.late_cycles = 0
        self.status: str | None = None
        self._buffer: list[str] = []
        self._last_t: float | None = None
        self._closed = False

        self._meta = self._initial_metadata(metadata or {})
        if not overwrite:
            check_output(self.sidecar, overwrite=False)
        # created exclusively (never through a symbolic link); OutputError names the reason
        fd = create_exclusive(self.path, overwrite=overwrite)
        self._fh = os.fdopen(fd, "w", encoding="utf-8", newline="\n")
        self._fh.write(",".join(self.columns) + "\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._write_sidecar(STATUS_RUNNING, None)
        self._last_flush = time.monotonic()

    # ------------------------------------------------------------------ metadata
    def _initial_metadata(self, metadata: Mapping[str, Any]) -> dict[str, Any]:
        extra = dict(metadata.get("extra") or {})
        meta: dict[str, Any] = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION}
        for key in USER_METADATA_KEYS:
            meta[key] = metadata.get(key)
        for key, value in metadata.items():
            if key not in USER_METADATA_KEYS and key != "extra":
                extra[key] = value
        if meta["trajectory_file"] is not None:
            meta["trajectory_file"] = str(meta["trajectory_file"])
            traj = Path(meta["trajectory_file"])
            if meta["trajectory_sha256"] is None and traj.is_file():
                meta["trajectory_sha256"] = sha256_file(traj)
        for key in ("gear_ratios", "torque_constants"):
            if meta[key] is not None:
                meta[key] = [float(v) for v in meta[key]]
        if meta["rate_hz"] is not None:
            meta["rate_hz"] = float(meta["rate_hz"])
        if meta["start_time"] is None:
            meta["start_time"] = utc_now_iso()
        meta["end_time"] = None
        meta["urident_version"] = _urident_version()
        meta["columns"] = list(self.columns)
        meta["extra"] = extra
        return meta

    def _write_sidecar(self, status: str, abort_reason: str | None) -> None:
        data = dict(self._meta)
        data.update(
            status=status,
            abort_reason=abort_reason,
            late_cycles=self.late_cycles,
            duplicates_skipped=self.duplicates_skipped,
            n_samples=self.n_samples,
        )
        write_sidecar(self.sidecar, data)

    # ------------------------------------------------------------------ appending
    def append(self, row: Sequence[float] | Mapping[str, Any]) -> bool:
        """Append one sample: a flat sequence of ``n_columns`` values in column order, or a
        mapping field name (or Recording attribute name) -> scalar / 6-vector. Returns False
        when the row was skipped as a duplicate timestamp."""
        if self._closed:
            raise ValueError(f"{self.path}: log writer is closed")
        if isinstance(row, Mapping):
            values = self._flatten(row)
        else:
            values = tuple(row.tolist() if hasattr(row, "tolist") else row)
            if len(values) != self.n_columns:
                raise ValueError(f"row has {len(values)} values, log has {self.n_columns} columns")
        t = values[0]
        if t == self._last_t:
            self.duplicates_skipped += 1
            return False
        self._last_t = t
        self._buffer.append(self._row_format % values)
        self.n_samples += 1
        now = time.monotonic()
        if now - self._last_flush >= self.flush_interval_s:
            self._flush(now)
        return True

    def append_sample(self, timestamp: float, **values: Any) -> bool:
        """Append one sample by keyword: ``append_sample(t, actual_q=q, actual_qd=qd, ...)`` or
        with attribute names (``q=``, ``qd=``, ``current=``...). Every field of the log needed."""
        values["timestamp"] = timestamp
        return self.append(values)

    def _flatten(self, row: Mapping[str, Any]) -> tuple:
        out: list[Any] = [None] * self.n_columns
        seen = 0
        for key, value in row.items():
            if key not in self._offsets:
                raise ValueError(f"{key!r} is not a field of this log ({', '.join(self._offsets)})")
            start, width = self._offsets[key]
            if width == 1:
                out[start] = value.item() if hasattr(value, "item") else value
            else:
                vec = value.tolist() if hasattr(value, "tolist") else list(value)
                if len(vec) != width:
                    raise ValueError(f"field {key!r} needs {width} values, got {len(vec)}")
                out[start : start + width] = vec
            seen += width
        if seen != self.n_columns or any(v is None for v in out):
            missing = [f.name for f in self.fields if out[self._offsets[f.name][0]] is None]
            raise ValueError(f"sample lacks field(s) {', '.join(missing) or '(given twice?)'}")
        return tuple(out)

    def mark_late_cycle(self, n: int = 1) -> None:
        """Count a control cycle that missed its deadline (reported as ``late_cycles``)."""
        self.late_cycles += n

    # ------------------------------------------------------------------ flushing / closing
    def _flush(self, now: float | None = None) -> None:
        if self._buffer:
            chunk = "".join(self._buffer)
            self._buffer.clear()
            self._fh.write(chunk)
            self._fh.flush()  # to the OS: survives a killed process
        self._last_flush = time.monotonic() if now is None else now

    def flush(self) -> None:
        """Write buffered rows to the OS now."""
        if not self._closed:
            self._flush()

    def close(
        self,
        status: str = STATUS_COMPLETED,
        abort_reason: str | None = None,
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        """Write every buffered row, fsync, and finalise the sidecar. Idempotent."""
        if self._closed:
            return
        if status not in STATUSES or status == STATUS_RUNNING:
            raise ValueError(f"close status must be completed or aborted, got {status!r}")
        self._closed = True
        try:
            self._flush()
            os.fsync(self._fh.fileno())
        finally:
            self._fh.close()
            if extra:
                self._meta["extra"].update(extra)
            self._meta["end_time"] = utc_now_iso()
            self.status = status
            reason = None if abort_reason is None else " ".join(str(abort_reason).split())
            self._write_sidecar(status, reason)

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close(STATUS_COMPLETED)
        else:
            reason = f"{exc_type.__name__}: {exc}" if str(exc) else exc_type.__name__
            self.close(STATUS_ABORTED, reason)

    def __del__(self) -> None:  # an unclosed writer still gets its rows to the OS
        try:
            if not self._closed and not self._fh.closed:
                self._flush()
        except Exception:  # noqa: BLE001 - never raise from __del__
            pass
