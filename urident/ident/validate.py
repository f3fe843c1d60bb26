"""Validation: predicted vs measured torques of prepared data, as a :class:`ValidationResult`
(metrics from :mod:`urident.ident.metrics`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.ident.identify import IdentifiedModel, predict_prepared
from urident.ident.metrics import RunningMetrics, error_metrics, metrics  # noqa: F401 (re-exported)
from urident.ident.preprocess import Prepared, Provenance


@dataclass(frozen=True)
class ValidationResult:
    """Arrays for plotting or streaming (t, tau_measured, tau_predicted (N, 6)) and the metrics."""

    method: str
    t: np.ndarray
    tau_measured: np.ndarray
    tau_predicted: np.ndarray
    e_n: float
    rms_nm: np.ndarray
    rre_pct: np.ndarray
    provenance: tuple[Provenance, ...] = ()

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def mean_rms_nm(self) -> float:
        return float(np.mean(self.rms_nm))

    def as_dict(self) -> dict:
        return {"method": self.method, "e_n": float(self.e_n), "rms_nm": [float(v) for v in self.rms_nm],
                "mean_rms_nm": self.mean_rms_nm, "rre_pct": [float(v) for v in self.rre_pct],
                "n_samples": self.n_samples, "data": [p.as_dict() for p in self.provenance]}


def validate(identified: IdentifiedModel, spec, data: Prepared) -> ValidationResult:
    """Predict ``data``'s torques with ``identified`` and compare."""
    pred = predict_prepared(identified, spec, data)
    e_n, rms, rre = metrics(data.tau, pred)
    return ValidationResult(identified.method, data.t, data.tau, pred, e_n, rms, rre, data.provenance)
