"""Matplotlib PNG plots of identification results (Agg backend; no display needed).

    plot_torques(result, "valid.png")            # measured vs predicted torque, one panel per joint
    plot_base_parameters(models, "params.png")   # base parameters ± σ per method
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def plot_torques(result, path: str | Path, title: str | None = None) -> Path:
    """Measured vs predicted joint torques of a ValidationResult (t, tau_measured, tau_predicted)."""
    plt = _pyplot()
    path = Path(path)
    t = np.asarray(result.t) - float(result.t[0])
    fig, axes = plt.subplots(6, 1, figsize=(10, 12), sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(t, result.tau_measured[:, j], lw=0.8, color="0.3", label="measured")
        ax.plot(t, result.tau_predicted[:, j], lw=0.8, color="tab:red", label="predicted")
        ax.set_ylabel(f"τ{j + 1} [N·m]")
        ax.text(0.01, 0.85, f"RMS {result.rms_nm[j]:.2f} N·m, rre {result.rre_pct[j]:.1f} %",
                transform=ax.transAxes, fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(title or f"{result.method}: e_N = {result.e_n:.4f}, mean RMS {np.mean(result.rms_nm):.2f} N·m")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_base_parameters(models: Mapping[str, object], path: str | Path) -> Path:
    """Base parameter values with ±σ error bars, one series per method."""
    plt = _pyplot()
    path = Path(path)
    first = next(iter(models.values()))
    x = np.arange(len(first.names))
    fig, ax = plt.subplots(figsize=(max(8, 0.25 * len(x)), 4))
    width = 0.8 / max(len(models), 1)
    for k, (name, m) in enumerate(models.items()):
        ax.errorbar(x + (k - (len(models) - 1) / 2) * width, m.values, yerr=m.sigma, fmt="o", ms=3,
                    capsize=2, label=name)
    ax.set_xticks(x, first.names, rotation=90, fontsize=7)
    ax.set_yscale("symlog", linthresh=1e-2)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
