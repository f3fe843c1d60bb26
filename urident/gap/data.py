"""Recordings → the data sets the diagnosis works on.

A :class:`GapSet` is :class:`urident.ident.Prepared` (filtered q̈, unfiltered measured torque
τ = drive gains × raw current, rest trimmed) plus the logged signals that help explain a residual:
time since the start of each run, joint temperatures and the controller's target moment, cut to
the same samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from urident.errors import ConfigError


@dataclass(frozen=True, eq=False)
class GapSet:
    prepared: object                 # urident.ident.Prepared
    run_time: np.ndarray             # (N,) s since the first sample of its recording
    temperature: np.ndarray | None   # (N, 6) °C, None when any recording lacks it
    target_moment: np.ndarray | None  # (N, 6) N·m

    def __len__(self) -> int:
        return len(self.prepared)

    @property
    def t(self) -> np.ndarray:
        return self.prepared.t

    @property
    def segment(self) -> np.ndarray:
        return self.prepared.segment

    @property
    def sample_rate(self) -> float:
        dt = np.diff(self.prepared.t)
        dt = dt[dt > 0]
        return float(1.0 / np.median(dt)) if dt.size else 1.0


def build_set(recordings: Sequence, spec, drive_gains=None, config=None, what: str = "logs",
              params=None, payload=None) -> GapSet:
    """Prepare ``recordings`` (each, and each gap-free piece of one, filtered on its own) and cut
    their auxiliary signals alike; ``params``: the baseline parameters whose preprocessing and
    drive gains to follow (through the one prediction path); ``payload``: a known payload
    whose torque is removed from the measured torque."""
    from urident.ident import PreprocessConfig, predict_recordings, prediction_config
    from urident.ident.preprocess import concatenate, preprocess_pieces

    recordings = list(recordings)
    if not recordings:
        raise ConfigError(f"no {what} given")
    if params is not None:
        config = config or prediction_config(params, trim_rest=True)
    config = config or PreprocessConfig()
    if config.decimate != 1:
        raise ConfigError("gap diagnosis needs every sample (decimate = 1)")
    if params is not None:
        prediction = predict_recordings(params, recordings, spec, config=config, drive_gains=drive_gains)
        prepared, pieces = prediction.data, prediction.pieces
    else:
        parts, pieces = [], []
        for k, recording in enumerate(recordings):
            for offset, p in preprocess_pieces(recording, spec, config, drive_gains):
                parts.append(p)
                pieces.append((k, offset))
        prepared = concatenate(parts)
    if payload is not None:
        from urident.ident.payload import without_payload

        prepared = without_payload(spec, payload, prepared)
    run_time, temps, moments = [], [], []
    for (k, offset), prov in zip(pieces, prepared.provenance):
        rec = recordings[k]
        first, last = offset + prov.samples_used[0], offset + prov.samples_used[1]
        t = np.asarray(rec.t, float)
        run_time.append(t[first:last] - t[0])  # run time counts from the recording's start, across gaps
        temps.append(None if rec.temperature is None else np.asarray(rec.temperature, float)[first:last])
        moments.append(None if rec.target_moment is None else np.asarray(rec.target_moment, float)[first:last])
    temperature = None if any(x is None for x in temps) else np.vstack(temps)
    if temperature is not None and not np.all(np.isfinite(temperature)):
        temperature = None
    target_moment = None if any(x is None for x in moments) else np.vstack(moments)
    return GapSet(prepared, np.concatenate(run_time), temperature, target_moment)
