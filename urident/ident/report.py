"""Plain-text comparison of estimation methods on the same data: per method e_N and per-joint RMS
(training and, when given, validation), then every base parameter as value ± σ per method."""

from __future__ import annotations

from typing import Mapping

import numpy as np


def _row(cells, widths) -> str:
    return "  ".join(str(c).rjust(w) if k else str(c).ljust(w) for k, (c, w) in enumerate(zip(cells, widths)))


def comparison_report(models: Mapping[str, object], validations: Mapping[str, object] | None = None) -> str:
    """``models``: method → IdentifiedModel; ``validations``: method → ValidationResult."""
    lines = []
    first = next(iter(models.values()))
    lines.append(f"robot {first.robot}, model {'reduced' if first.model.reduced else 'full'} "
                 f"({len(first.names)} parameters), friction eps {first.model.friction_eps:g} rad/s, "
                 + (f"coulomb {first.model.coulomb}" if not first.model.joint_coulomb else
                    "coulomb per joint " + ",".join(first.model.joint_coulomb))
                 + (f" (dahl {first.model.dahl_rad:g} rad from {first.model.dahl_source})"
                    if first.model.coulomb == "dahl" or "dahl" in first.model.extras else "")
                 + f", extras {','.join(first.model.extras) or 'none'}, "
                 + ("per-joint terms " + "; ".join(f"J{j + 1} {'+'.join(t) or '-'}"
                                                   for j, t in enumerate(first.model.joint_extras)) + ", "
                    if first.model.joint_extras else "")
                 + f"weighting {first.weighting}, {first.n_samples} samples")
    lines.append("sigma: eq. (21) scaled by the noise variance s^2 = |e|^2/(6m - n) of each fit")
    widths = [16, 8] + [6] * 6 + [7]
    lines.append(_row(["method", "e_N"] + [f"rms{j + 1}" for j in range(6)] + ["mean"], widths))
    for name, m in models.items():
        rms = m.train_rms
        lines.append(_row([f"{name}:train", f"{m.train_e_n:.4f}"] + [f"{v:.2f}" for v in rms]
                          + [f"{np.mean(rms):.3f}"], widths))
        if validations and name in validations:
            v = validations[name]
            lines.append(_row([f"{name}:valid", f"{v.e_n:.4f}"] + [f"{x:.2f}" for x in v.rms_nm]
                              + [f"{v.mean_rms_nm:.3f}"], widths))
    lines.append("")
    methods = list(models)
    widths = [10] + [30] * len(methods)
    lines.append(_row(["parameter"] + [f"{m} value +- sigma (rel %)" for m in methods], widths))
    for k, name in enumerate(first.names):
        cells = [name]
        for m in methods:
            mod = models[m]
            rel = mod.relative_sigma_pct[k]
            rel_text = f"{rel:.1f}" if np.isfinite(rel) and rel < 1e5 else "inf"
            cells.append(f"{mod.values[k]:+.4g} +- {mod.sigma[k]:.2g} ({rel_text})")
        lines.append(_row(cells, widths))
    return "\n".join(lines)


def logs_used(provenance, title: str = "logs used") -> str:
    """One line per log: file, the file rows selected (if any), samples used and SHA-256."""
    provenance = tuple(provenance)
    lines = [f"{title} ({len(provenance)}):"]
    for p in provenance:
        rows = "" if p.rows is None else f" rows {p.rows[0]}-{p.rows[1]},"
        first, last = p.samples_used
        lines.append(f"  {p.file}:{rows} {last - first} samples used [{first}, {last}), "
                     f"sha256 {p.sha256 or '-'}")
    return "\n".join(lines)
