"""Reading an ``.rrd`` file back through Rerun's own chunk API (``rerun.chunk.RrdReader``), for
tests and scripts: which entities exist, and their time series.

The installed rerun-sdk (0.41) has no ``rerun.dataframe``; its DataFusion-based query API needs
the optional ``datafusion`` package, so this reads the chunks' Arrow record batches directly.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rerun.chunk import RrdReader

from urident.viz.recording import TIMELINE


@dataclass
class RrdContents:
    """Per entity path (no leading ``/``) and component (``Archetype:field``): the timeline
    values [s] (None for static rows) and the cell of each row (a Python list)."""

    application_id: str
    components: dict[str, dict[str, list[tuple[float | None, object]]]] = field(
        default_factory=lambda: defaultdict(lambda: defaultdict(list)))
    has_blueprint: bool = False

    @property
    def entities(self) -> list[str]:
        return sorted(self.components)

    def rows(self, entity: str, component: str) -> list[tuple[float | None, object]]:
        """``(t, cell)`` rows of one component, sorted by time (static rows first)."""
        rows = self.components.get(entity, {}).get(component, [])
        return sorted(rows, key=lambda r: -np.inf if r[0] is None else r[0])

    def scalars(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """Time ``(N,)`` and values ``(N,)`` of a one-value ``Scalars`` series."""
        rows = [r for r in self.rows(entity, "Scalars:scalars") if r[0] is not None]
        t = np.array([r[0] for r in rows], dtype=float)
        values = np.array([r[1][0] if r[1] else np.nan for r in rows], dtype=float)
        return t, values


def read_rrd(path: str | Path, timeline: str = TIMELINE) -> RrdContents:
    """Everything in the first recording of an ``.rrd`` file, indexed by ``timeline``."""
    reader = RrdReader(path)
    recordings = reader.recordings()
    if not recordings:
        raise ValueError(f"{path}: no recording in the file")
    out = RrdContents(application_id=recordings[0].application_id,
                      has_blueprint=bool(reader.blueprints()))
    for chunk in reader.stream(store=recordings[0]):
        entity = chunk.entity_path.lstrip("/")
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if timeline in names:
            times = batch.column(timeline).cast("int64").to_numpy(zero_copy_only=False) * 1e-9
        else:
            times = [None] * batch.num_rows
        for name in names:
            if name == timeline or name.startswith("rerun.") or name == "log_time" or ":" not in name:
                continue
            cells = batch.column(name).to_pylist()
            store = out.components[entity][name]
            for t, cell in zip(times, cells):
                if cell is not None:
                    store.append((None if t is None else float(t), cell))
    return out
