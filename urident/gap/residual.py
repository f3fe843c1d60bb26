"""The baseline model and what the candidates are built from.

Baseline: the paper's model (full base set, OLS, Coulomb friction tanh(q̇/ε), ε = 0.01 rad/s)
identified with :func:`urident.ident.identify` on the identification set, or loaded from a
parameters file. Residual r = τ_measured − τ̂ (N, 6), τ_measured = drive gains × raw current.

:class:`SetContext` holds one set's baseline and the derived signals the candidate columns use:
τ̂, the link-side (rigid-body) part τ̂_link = τ̂ − friction, and the time derivatives dτ̂/dt,
d²τ̂_link/dt² (taken per segment on the actual timestamps after a zero-phase low-pass). Its
design matrix W is streamed in chunks; only during a diagnosis, on a small set, is it kept
between passes (:data:`DESIGN_CACHE_BYTES`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.gap.data import GapSet

#: Corner of the zero-phase low-pass applied before differentiating τ̂ [Hz].
DERIVATIVE_FILTER_HZ = 15.0
#: During a diagnosis (``make_context(..., keep_design=True)``) a set's design matrix is kept after
#: its first pass when it takes at most this many bytes (it is streamed ~6 times; a UR5e 40 s log
#: at 500 Hz: 50 MB); larger sets stay streamed.
DESIGN_CACHE_BYTES = 160 * 2 ** 20


def design_fits_cache(n_samples: int, n_params: int) -> bool:
    """Whether an (N, 6, p) float64 design takes at most :data:`DESIGN_CACHE_BYTES`."""
    return n_samples * 6 * n_params * 8 <= DESIGN_CACHE_BYTES


def fit_baseline(spec, ident: GapSet, friction_eps: float = 0.01, design=None):
    """The paper's baseline on the identification set (OLS, tanh friction); ``design``: its
    design's chunks already built (:func:`baseline_design`)."""
    from urident.ident import ModelConfig, identify

    return identify(spec, ident.prepared, "ols", ModelConfig(friction_eps=friction_eps), design=design)


def baseline_design(spec, data: GapSet, friction_eps: float = 0.01) -> list | None:
    """The baseline's design of ``data`` as :meth:`SetContext.chunks` yields it, for the fit and
    then the set's context (``make_context(..., design=)``), or None when larger than
    :data:`DESIGN_CACHE_BYTES` (then streamed each time)."""
    from urident.ident import ModelConfig
    from urident.ident.design import CHUNK_SAMPLES, column_names, design_chunks

    model = ModelConfig(friction_eps=friction_eps)
    p = data.prepared
    if not design_fits_cache(len(p), len(column_names(spec, model))):
        return None
    parts = list(design_chunks(spec, model, p.q, p.qd, p.qdd, p.segment, p.t, CHUNK_SAMPLES))
    for _, _, blocks in parts:
        blocks.flags.writeable = False      # shared by every later pass
    return parts


def segment_slices(segment: np.ndarray):
    """One slice per run of equal ``segment`` labels (the pieces a log is filtered in)."""
    edges = np.flatnonzero(np.diff(segment) != 0) + 1
    bounds = np.r_[0, edges, len(segment)]
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def smooth_derivative(x: np.ndarray, t: np.ndarray, segment: np.ndarray, order: int = 1,
                      cutoff_hz: float = DERIVATIVE_FILTER_HZ) -> np.ndarray:
    """``order``-th time derivative of (N, 6) ``x`` per segment after a zero-phase low-pass."""
    from urident.ident.preprocess import zero_phase_lowpass

    out = np.zeros_like(x)
    for sl in segment_slices(segment):
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
    w: np.ndarray | None     # (6N, p) design matrix held in memory, or None: streamed from spec, model
    tau_hat: np.ndarray      # (N, 6) baseline prediction
    tau_link: np.ndarray     # (N, 6) its rigid-body part
    dtau: np.ndarray         # (N, 6) dτ̂/dt
    ddtau_link: np.ndarray   # (N, 6) d²τ̂_link/dt²
    friction_eps: float
    cache: dict
    spec: object = None      # the robot and the baseline IdentifiedModel whose design is streamed
    model: object = None

    @property
    def n_params(self) -> int:
        return self.w.shape[1] if self.w is not None else len(self.model.values)

    def chunks(self, size: int | None = None):
        """Yield ``(start, stop, blocks (m, 6, p))``: the design matrix's rows in chunks."""
        from urident.ident.design import CHUNK_SAMPLES, design_chunks

        size = size or CHUNK_SAMPLES
        if self.w is not None:
            w3 = self.w.reshape(-1, 6, self.w.shape[1])
            for a in range(0, self.n, size):
                yield a, min(a + size, self.n), w3[a:a + size]
            return
        kept = self.cache.get(("design", size))
        if kept is not None:
            yield from kept
            return
        p = self.data.prepared
        keep = self.keeps_design()
        parts = []
        # as urident.ident.predict_prepared: timestamps drive a velocity-driven friction state
        for a, b, blocks in design_chunks(self.spec, self.model.model, p.q, p.qd, p.qdd, p.segment, p.t, size,
                                          temperature=p.temperature):
            if keep:
                blocks.flags.writeable = False      # shared by every later pass
                parts.append((a, b, blocks))
            yield a, b, blocks
        if keep:
            self.cache[("design", size)] = parts

    def keeps_design(self) -> bool:
        """Whether derived arrays are kept between passes: during a diagnosis, on a set whose
        design takes at most :data:`DESIGN_CACHE_BYTES`."""
        return bool(self.cache.get("keep_design")) and design_fits_cache(self.n, self.n_params)

    def design_product(self, g: np.ndarray) -> np.ndarray:
        """(N, 6) W·g for parameter-space vector(s) ``g`` (p,)."""
        out = np.empty((self.n, 6))
        for a, b, blocks in self.chunks():
            out[a:b] = blocks @ g
        return out

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
        """(N, 6) tanh(q̇/ε), computed once per set (read-only: the candidates share it)."""
        s = self.cache.get("sign")
        if s is None:
            s = self.cache["sign"] = np.tanh(self.qd / self.friction_eps)
            s.flags.writeable = False
        return s


def make_context(spec, model, data: GapSet, keep_design: bool = False, design=None) -> SetContext:
    """Derived signals of ``data`` under the identified ``model`` (its design streamed in chunks;
    ``keep_design``: kept in ``cache`` after the first pass when small, :data:`DESIGN_CACHE_BYTES`;
    ``design``: those chunks already built, :func:`baseline_design`; ``cache.clear()`` drops
    them)."""
    from urident.ident.design import CHUNK_SAMPLES
    from urident.ident.identify import check_compatible
    from urident.model.parameters import is_friction

    check_compatible(model, spec)
    p = data.prepared
    values = np.asarray(model.values, float)
    rigid = ~is_friction(model.kinds)      # the link side: rigid body and rotor inertia
    ctx = SetContext(data, None, np.empty((len(p), 6)), np.empty((len(p), 6)), None, None,
                     float(model.model.friction_eps), {"keep_design": True} if keep_design else {},
                     spec, model)
    if design is not None:
        ctx.cache[("design", CHUNK_SAMPLES)] = design
    for a, b, blocks in ctx.chunks():
        ctx.tau_hat[a:b] = blocks @ values
        ctx.tau_link[a:b] = blocks[:, :, rigid] @ values[rigid]
    ctx.dtau = smooth_derivative(ctx.tau_hat, p.t, p.segment, 1)
    ctx.ddtau_link = smooth_derivative(ctx.tau_link, p.t, p.segment, 2)
    return ctx
