"""The baseline model and what the candidates are built from.

Baseline: the paper's model (full base set, OLS, Coulomb friction tanh(q̇/ε), ε = 0.01 rad/s)
identified with :func:`urident.ident.identify` on the identification set, or loaded from a
parameters file. Residual r = τ_measured − τ̂ (N, 6), τ_measured = drive gains × raw current.

:class:`SetContext` holds one set's design matrix W (6N, p) and the derived signals the candidate
columns use: τ̂, the link-side (rigid-body) part τ̂_link = τ̂ − friction, and the time derivatives
dτ̂/dt, d²τ̂_link/dt² (taken per segment on the actual timestamps after a zero-phase low-pass).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.gap.data import GapSet

#: Corner of the zero-phase low-pass applied before differentiating τ̂ [Hz].
DERIVATIVE_FILTER_HZ = 15.0


def fit_baseline(spec, ident: GapSet, friction_eps: float = 0.01):
    """The paper's baseline on the identification set (OLS, tanh friction)."""
    from urident.ident import ModelConfig, identify

    return identify(spec, ident.prepared, "ols", ModelConfig(friction_eps=friction_eps))


def _segment_slices(segment: np.ndarray):
    edges = np.flatnonzero(np.diff(segment) != 0) + 1
    bounds = np.r_[0, edges, len(segment)]
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def smooth_derivative(x: np.ndarray, t: np.ndarray, segment: np.ndarray, order: int = 1,
                      cutoff_hz: float = DERIVATIVE_FILTER_HZ) -> np.ndarray:
    """``order``-th time derivative of (N, 6) ``x`` per segment after a zero-phase low-pass."""
    from urident.ident.preprocess import zero_phase_lowpass

    out = np.zeros_like(x)
    for sl in _segment_slices(segment):
        ts, xs = t[sl], x[sl]
        if len(ts) < 20:
            continue
        dt = np.diff(ts)
        fs = 1.0 / np.median(dt[dt > 0])
        y = zero_phase_lowpass(xs, fs, min(cutoff_hz, 0.4 * fs))
        for _ in range(order):
            y = np.gradient(y, ts, axis=0)
        out[sl] = y
    return out


@dataclass(eq=False)
class SetContext:
    """One data set seen through the baseline model (see the module doc)."""

    data: GapSet
    w: np.ndarray            # (6N, p) design matrix of the baseline model
    tau_hat: np.ndarray      # (N, 6) baseline prediction
    tau_link: np.ndarray     # (N, 6) its rigid-body part
    dtau: np.ndarray         # (N, 6) dτ̂/dt
    ddtau_link: np.ndarray   # (N, 6) d²τ̂_link/dt²
    friction_eps: float
    cache: dict

    @property
    def n(self) -> int:
        return len(self.data)

    @property
    def q(self):
        return self.data.prepared.q

    @property
    def qd(self):
        return self.data.prepared.qd

    @property
    def qdd(self):
        return self.data.prepared.qdd

    @property
    def t(self):
        return self.data.prepared.t

    @property
    def tau(self):
        return self.data.prepared.tau

    @property
    def residual(self) -> np.ndarray:
        """Measured minus predicted torque (N, 6)."""
        return self.tau - self.tau_hat

    def sign(self) -> np.ndarray:
        return np.tanh(self.qd / self.friction_eps)


def make_context(spec, model, data: GapSet) -> SetContext:
    """Design matrix and derived signals of ``data`` under the identified ``model``."""
    from urident.ident.design import design_matrix
    from urident.ident.identify import check_compatible
    from urident.model.parameters import is_friction

    check_compatible(model, spec)
    p = data.prepared
    # as urident.ident.predict_prepared: timestamps drive a velocity-driven friction state
    w = design_matrix(spec, model.model, p.q, p.qd, p.qdd, p.segment, p.t)
    values = np.asarray(model.values, float)
    tau_hat = (w @ values).reshape(-1, 6)
    rigid = ~is_friction(model.kinds)      # the link side: rigid body and rotor inertia
    tau_link = (w[:, rigid] @ values[rigid]).reshape(-1, 6)
    dtau = smooth_derivative(tau_hat, p.t, p.segment, 1)
    ddtau = smooth_derivative(tau_link, p.t, p.segment, 2)
    return SetContext(data, w, tau_hat, tau_link, dtau, ddtau, float(model.model.friction_eps), {})
