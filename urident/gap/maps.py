"""Where the residual lies: binned maps and spectra (pure functions of arrays).

Every map bins one joint's residual r (N,) over one variable and returns, per bin, the share of
samples, the share of residual energy Σr², the RMS and the mean (bias) of r there. A regime is
*concentrated* when its energy share clearly exceeds its sample share.

* velocity: a near-zero band |q̇| < v0, then three quantile bins of |q̇| per direction;
* signed load s = sign(q̇)·|τ̂| (friction that grows with load shows as an odd, growing bias);
* joint angle (uniform bins) and the angle-domain spectrum: the residual averaged on a uniform
  angle grid, detrended, amplitude of sin/cos(k·q) for integer k (periods per revolution) — gear
  harmonics show as peaks; also of r·sign(q̇) (position-dependent friction);
* time: windows over the run (drift: slope of the bias and of sign(q̇)·r);
* frequency: Welch spectrum of r, energy per band; correlation of r with dτ̂/dt (a delay d gives
  r ≈ −d·dτ̂/dt).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NEAR_ZERO_VELOCITY = 0.02   # [rad/s]


@dataclass(frozen=True)
class BinStats:
    label: str
    lo: float
    hi: float
    sample_share: float
    energy_share: float
    rms: float
    mean: float

    def as_dict(self) -> dict:
        return {"label": self.label, "lo": _f(self.lo), "hi": _f(self.hi),
                "sample_share": _f(self.sample_share), "energy_share": _f(self.energy_share),
                "rms_nm": _f(self.rms), "mean_nm": _f(self.mean)}


def _f(x) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def bin_stats(r: np.ndarray, index: np.ndarray, labels, edges) -> list[BinStats]:
    """Statistics of r per bin; ``index`` (N,) holds each sample's bin (−1: none)."""
    r = np.asarray(r, float)
    total = float(np.sum(r * r)) or 1.0
    n = len(r)
    out = []
    for b, label in enumerate(labels):
        sel = index == b
        k = int(sel.sum())
        rb = r[sel]
        out.append(BinStats(label, edges[b][0], edges[b][1], k / max(n, 1),
                            float(np.sum(rb * rb)) / total,
                            float(np.sqrt(np.mean(rb * rb))) if k else float("nan"),
                            float(np.mean(rb)) if k else float("nan")))
    return out


def _quantile_edges(x: np.ndarray, n_bins: int) -> np.ndarray:
    if x.size == 0:
        return np.array([])
    e = np.unique(np.quantile(x, np.linspace(0, 1, n_bins + 1)))
    return e


def velocity_map(r, qd, v0: float = NEAR_ZERO_VELOCITY, per_side: int = 3) -> list[BinStats]:
    qd = np.asarray(qd, float)
    idx = np.full(len(qd), -1)
    labels, edges = [f"|q̇| < {v0:g} rad/s"], [(0.0, v0)]
    idx[np.abs(qd) < v0] = 0
    for sgn, name in ((-1, "q̇ < 0"), (1, "q̇ > 0")):
        sel = sgn * qd >= v0
        e = _quantile_edges(np.abs(qd[sel]), per_side)
        for a, b in zip(e[:-1], e[1:]):
            inside = sel & (np.abs(qd) >= a) & (np.abs(qd) <= b) & (idx == -1)
            idx[inside] = len(labels)
            lo, hi = (-b, -a) if sgn < 0 else (a, b)
            labels.append(f"q̇ in [{lo:.3g}, {hi:.3g}] rad/s")
            edges.append((lo, hi))
    return bin_stats(r, idx, labels, edges)


def _generic_map(r, x, e, unit: str, name: str) -> list[BinStats]:
    x = np.asarray(x, float)
    if len(e) < 2:
        return []
    idx = np.clip(np.searchsorted(e, x, side="right") - 1, 0, len(e) - 2)
    labels = [f"{name} in [{a:.3g}, {b:.3g}] {unit}" for a, b in zip(e[:-1], e[1:])]
    return bin_stats(r, idx, labels, list(zip(e[:-1], e[1:])))


def load_map(r, signed_load, n_bins: int = 8) -> list[BinStats]:
    return _generic_map(r, signed_load, _quantile_edges(np.asarray(signed_load, float), n_bins),
                        "N·m", "sign(q̇)·|τ̂|")


def angle_map(r, q, n_bins: int = 12) -> list[BinStats]:
    q = np.asarray(q, float)
    lo, hi = float(np.min(q)), float(np.max(q))
    if not hi > lo:
        return []
    return _generic_map(r, q, np.linspace(lo, hi, n_bins + 1), "rad", "q")


def time_map(r, t, n_bins: int = 10) -> list[BinStats]:
    t = np.asarray(t, float)
    return _generic_map(r, t, np.linspace(t.min(), t.max(), n_bins + 1) if t.max() > t.min() else [],
                        "s", "t")


@dataclass(frozen=True)
class AngleSpectrum:
    k: np.ndarray            # integer harmonics (periods per revolution)
    amplitude: np.ndarray    # [N·m] of the torque-mode residual r(q)
    amplitude_friction: np.ndarray  # of r·sign(q̇)
    span_rad: float

    def peaks(self, n: int = 3, friction: bool = False, min_k: int = 1) -> list[int]:
        """The ``n`` harmonics with the largest amplitude relative to the spectrum's median
        (local maxima only)."""
        a = self.amplitude_friction if friction else self.amplitude
        if a.size < 3:
            return []
        local = np.r_[a[0] >= a[1], (a[1:-1] >= a[:-2]) & (a[1:-1] >= a[2:]), a[-1] >= a[-2]]
        order = [i for i in np.argsort(-a) if local[i] and self.k[i] >= min_k]
        return [int(self.k[i]) for i in order[:n]]

    def as_dict(self, top: int = 5) -> dict:
        return {"span_rad": _f(self.span_rad),
                "peaks": [{"k": k, "amplitude_nm": _f(self.amplitude[k - 1])} for k in self.peaks(top)],
                "peaks_friction": [{"k": k, "amplitude_nm": _f(self.amplitude_friction[k - 1])}
                                   for k in self.peaks(top, True)]}


def _uniform_angle_average(x, q, step):
    lo = float(np.min(q))
    n_bins = max(int(np.ceil((float(np.max(q)) - lo) / step)), 1)
    idx = np.minimum(((q - lo) / step).astype(int), n_bins - 1)
    count = np.bincount(idx, minlength=n_bins)
    total = np.bincount(idx, weights=x, minlength=n_bins)
    centres = lo + (np.arange(n_bins) + 0.5) * step
    have = count > 0
    if have.sum() < 2:
        return centres, np.zeros(n_bins)
    y = np.interp(centres, centres[have], total[have] / count[have])
    return centres, y


def angle_spectrum(r, q, qd, friction_eps: float = 0.01, k_max: int = 150,
                   bins_per_period: int = 4) -> AngleSpectrum:
    """Amplitude of sin/cos(k·q), k = 1..k_max, of the residual resampled on a uniform angle grid
    (bin width 2π/(k_max·bins_per_period)), with a linear trend removed and a Hann window."""
    r, q, qd = (np.asarray(v, float) for v in (r, q, qd))
    ks = np.arange(1, k_max + 1)
    span = float(np.ptp(q)) if q.size else 0.0
    if span <= 0:
        z = np.zeros(k_max)
        return AngleSpectrum(ks, z, z.copy(), span)
    step = 2 * np.pi / (k_max * bins_per_period)
    out = []
    for x in (r, r * np.tanh(qd / friction_eps)):
        c, y = _uniform_angle_average(x, q, step)
        if len(c) > 2:
            y = y - np.polyval(np.polyfit(c, y, 1), c)
        win = np.hanning(len(c)) if len(c) > 4 else np.ones(len(c))
        e = np.exp(-1j * np.outer(ks, c))
        out.append(2.0 * np.abs(e @ (y * win)) / max(win.sum(), 1e-12))
    return AngleSpectrum(ks, out[0], out[1], span)


@dataclass(frozen=True)
class FrequencyMap:
    bands_hz: tuple[tuple[float, float], ...]
    energy_share: np.ndarray
    peak_hz: float
    corr_dtau: float      # correlation of r with dτ̂/dt
    delay_s: float        # −cov(r, dτ̂/dt)/var(dτ̂/dt): the delay that explains most of r

    def as_dict(self) -> dict:
        return {"bands": [{"lo_hz": a, "hi_hz": b, "energy_share": _f(e)}
                          for (a, b), e in zip(self.bands_hz, self.energy_share)],
                "peak_hz": _f(self.peak_hz), "corr_dtau": _f(self.corr_dtau),
                "delay_s": _f(self.delay_s)}


def frequency_map(r, fs: float, dtau) -> FrequencyMap:
    from scipy.signal import welch

    r = np.asarray(r, float)
    dtau = np.asarray(dtau, float)
    nper = int(min(len(r), max(64, 2 ** int(np.log2(max(fs * 4, 64))))))
    f, p = welch(r - r.mean(), fs=fs, nperseg=nper)
    edges = [0.0, 0.5, 2.0, 5.0, 15.0, fs / 2]
    bands = tuple((a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a)
    total = float(p.sum()) or 1.0
    share = np.array([p[(f >= a) & (f < b)].sum() / total for a, b in bands])
    peak = float(f[1:][np.argmax(p[1:])]) if len(f) > 1 else float("nan")
    dc = dtau - dtau.mean()
    rc = r - r.mean()
    var = float(dc @ dc)
    denom = np.sqrt(var * float(rc @ rc))
    corr = float(rc @ dc / denom) if denom > 0 else 0.0
    delay = float(-(rc @ dc) / var) if var > 0 else 0.0
    return FrequencyMap(bands, share, peak, corr, delay)


@dataclass(frozen=True)
class Regime:
    joint: int           # 0-based
    axis: str            # velocity, load, angle, time
    bin: BinStats

    @property
    def concentration(self) -> float:
        return self.bin.energy_share / max(self.bin.sample_share, 1e-12)

    def text(self, what: str = "of the residual energy") -> str:
        b = self.bin
        return (f"joint {self.joint + 1}: {100 * b.energy_share:.0f} % {what} at {b.label}, "
                f"which holds {100 * b.sample_share:.0f} % of the samples")


def concentrated_regimes(joint: int, maps: dict[str, list[BinStats]], min_share: float = 0.15,
                         min_ratio: float = 1.5, top: int = 2) -> list[Regime]:
    """Bins whose energy share is ≥ ``min_share`` and ≥ ``min_ratio`` × their sample share, best
    (largest energy − sample share) first."""
    found = []
    for axis, bins in maps.items():
        for b in bins:
            if b.sample_share > 0 and b.energy_share >= min_share and \
                    b.energy_share >= min_ratio * b.sample_share:
                found.append(Regime(joint, axis, b))
    found.sort(key=lambda g: -(g.bin.energy_share - g.bin.sample_share))
    return found[:top]


def joint_maps(r, qd, signed_load, q, t) -> dict[str, list[BinStats]]:
    """The binned maps of one joint's residual (velocity, load, angle, time)."""
    return {"velocity": velocity_map(r, qd), "load": load_map(r, signed_load),
            "angle": angle_map(r, q), "time": time_map(r, t)}


def best_regime(joint: int, weights, qd, signed_load, q, t, prefer: tuple[str, ...] = ()) -> Regime | None:
    """Where a non-negative per-sample quantity (e.g. the improvement an effect brings)
    concentrates: the bin with the largest share − sample share, axes in ``prefer`` first
    when they show a concentration."""
    w = np.sqrt(np.clip(np.asarray(weights, float), 0, None))
    maps = joint_maps(w, qd, signed_load, q, t)
    regimes = concentrated_regimes(joint, maps, min_share=0.1, min_ratio=1.2, top=20)
    for axis in prefer:
        for g in regimes:
            if g.axis == axis:
                return g
    return regimes[0] if regimes else None
