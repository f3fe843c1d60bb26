"""Time-localised events: stretches where the residual departs from what any smooth effect explains
(a person pushing the arm, a collision, a stall, a protective stop's transient).

Every effect of the catalogue is a function of the motion (angle, velocity, load, time since the
start); its residual is bounded by a few times its own robust spread. An external force is not: it
appears for a while, many times that spread above the residual's local level, then goes. Per joint:

* local level m: running median of the residual over :data:`LEVEL_WINDOW_S` (a push of a second or
  two does not move it; a drift or a friction change does);
* spread s: 1.4826·MAD of r − m over the whole run without the stretches flagged so far (taken
  again until they settle), at least the joint's white-noise torque
  (:func:`urident.gap.significance.noise_sigma`) times :data:`NOISE_FLOOR`;
* z = |r − m| / s; a sample is a *core* sample on the joint when z > :data:`CORE_Z`, and the stretch
  around a core extends while z > :data:`EDGE_Z` (hysteresis).

Stretches of any joint are united, those closer than :data:`MERGE_S` merged, and a stretch is an
event when it lasts at least :data:`MIN_DURATION_S` and holds at least :data:`MIN_CORE_S` of core
samples, on joints whose departure peaks at :data:`MIN_PEAK_NOISE` white-noise torques or more.
Why these figures: a bounded effect (a sinusoid, a friction law) stays within about 1.5× its
MAD-scale, far below 5; the catalogue's short spikes (a delay's or Stribeck's bump at a velocity reversal: a few
tens of ms) stay under the duration rule (docs/gap-calibration.md).

Before that, the columns of the smooth effects that leave a short bump at every velocity reversal
(:func:`smooth_basis`) are fitted per joint and taken out: a bump that repeats with the motion is
an effect, not an event.

Kinds: ``stall`` (the arm's speed in the event below :data:`STALL_RATIO` of its speed in the
0.5 s before, and it was moving), ``impact`` (shorter than :data:`IMPACT_S`), else
``external_contact``.

The events' samples are set aside: the effect fits, the scores, the maps and the figures of the
diagnosis use the rest of the validation run (:func:`without_events`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.gap.significance import noise_sigma

LEVEL_WINDOW_S = 4.0     # [s] running median: the residual's local level
LEVEL_RATE_HZ = 25.0     # [Hz] ... taken on samples this far apart
CORE_Z = 5.0             # a core sample departs by more than this many robust spreads
EDGE_Z = 3.0             # an event extends while it departs by more than this
NOISE_FLOOR = 3.0        # the spread is at least this many white-noise torques
MERGE_S = 0.15           # [s] stretches closer than this are one event
MIN_DURATION_S = 0.1     # [s] shorter stretches are a spike of a smooth effect at a reversal
MIN_CORE_S = 0.05        # [s] of core samples an event must hold
MIN_PEAK_NOISE = 10.0    # an event's joint departs by at least this many white-noise torques
IMPACT_S = 0.25          # [s] an event shorter than this is an impact
STALL_RATIO = 0.2        # a stall: the arm's speed in the event below this share of its speed before
MOVING_RAD_S = 0.05      # [rad/s] ... and it was moving before


@dataclass(frozen=True)
class Event:
    start: int                      # first sample (index into the set)
    stop: int                       # one past the last sample
    t_start_s: float                # from the recording's first sample
    t_end_s: float
    joints: tuple[int, ...]         # 0-based, largest departure first
    peak_nm: tuple[float, ...]      # per joint of ``joints``: the residual at its largest |r|
    rms_nm: tuple[float, ...]       # per joint of ``joints``: RMS of the residual over the event
    kind: str                       # external_contact | impact | stall

    def as_dict(self) -> dict:
        return {"t_start_s": self.t_start_s, "t_end_s": self.t_end_s,
                "joints": [j + 1 for j in self.joints], "peak_nm": list(self.peak_nm),
                "rms_nm": list(self.rms_nm), "kind": self.kind, "n_samples": self.stop - self.start}


def _running_median(x: np.ndarray, width: int, step: int = 1, exclude: np.ndarray | None = None) -> np.ndarray:
    """(N, 6) running median of ``x`` over ``width`` samples, taken on every ``step``-th sample and
    interpolated between them (the level of a residual changes over seconds: cost bounded);
    ``exclude`` (N, 6): samples left out of each joint's medians (a flagged push must not lift
    the level its own end is judged against)."""
    from scipy.ndimage import median_filter

    step = max(1, int(step))
    sub = x[::step]
    half = max(1, width // step) // 2
    if exclude is None or not exclude.any():
        med = median_filter(sub, size=(2 * half + 1, 1), mode="mirror")
    else:
        from numpy.lib.stride_tricks import sliding_window_view

        held = np.where(exclude[::step], np.nan, sub)
        padded = np.pad(held, ((half, half), (0, 0)), mode="reflect")
        win = sliding_window_view(padded, 2 * half + 1, axis=0)           # (n_sub, 6, w)
        empty = np.all(np.isnan(win), axis=2)
        med = np.nanmedian(np.where(empty[..., None], 0.0, win), axis=2)
        for j in range(x.shape[1]):                  # a window all excluded: the nearest levels
            bad = empty[:, j]
            if bad.any() and (~bad).any():
                med[bad, j] = np.interp(np.flatnonzero(bad), np.flatnonzero(~bad), med[~bad, j])
    if step == 1:
        return med
    at = np.arange(0, len(x), step)
    grid = np.arange(len(x))
    return np.stack([np.interp(grid, at, med[:, j]) for j in range(x.shape[1])], axis=1)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def departures(r: np.ndarray, fs: float, iterations: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(N, 6) departure r − m of the residual ``r`` from its local level and (N, 6) its z-score
    (module doc). The spread is taken again without the stretches flagged so far (``iterations``
    times): pushes covering a third of a run would otherwise widen it."""
    r = np.asarray(r, float)
    width, step = int(round(LEVEL_WINDOW_S * fs)), int(fs // LEVEL_RATE_HZ)
    floor = NOISE_FLOOR * noise_sigma(r)
    out = np.zeros(r.shape, bool)
    for _ in range(iterations):
        d = r - _running_median(r, width, step, out)
        s = np.empty(r.shape[1])
        for j in range(r.shape[1]):
            x = d[~out[:, j], j] if (~out[:, j]).sum() > 0.5 * len(r) else d[:, j]
            s[j] = 1.4826 * np.median(np.abs(x - np.median(x)))
        s = np.maximum(s, floor)
        z = np.abs(d) / np.where(s > 0, s, np.inf)
        flagged = _stretches(z)
        if np.array_equal(flagged, out):
            break
        out = flagged
    return d, z


def _stretches(z: np.ndarray) -> np.ndarray:
    """(N, 6) True on each joint's stretches above :data:`EDGE_Z` that reach :data:`CORE_Z`."""
    out = np.zeros(z.shape, bool)
    for j in range(z.shape[1]):
        for a, b in _runs(z[:, j] > EDGE_Z):
            if (z[a:b, j] > CORE_Z).any():
                out[a:b, j] = True
    return out


#: Stribeck velocities [rad/s] of the smooth basis' near-zero-velocity columns.
BASIS_VS = (0.01, 0.03, 0.08)
#: Presliding distances [rad] of its holding-friction columns (the ends of the candidates' grid).
BASIS_DELTAS = (1e-4, 3e-3)


def smooth_basis(ctx, spec=None) -> np.ndarray:
    """(N, 6, k) per joint the columns of the smooth effects of a joint's own state that leave
    short bumps at a velocity reversal (Coulomb and Stribeck friction, a delay's dτ̂/dt, load
    friction, a gain), a step at each stop (friction held with the sign of the motion before:
    the Dahl state minus tanh) and a constant, from a :class:`urident.gap.residual.SetContext`: fitted per
    joint and taken out of the residual before events are looked for, so that such a bump
    repeated at every reversal is never an event. With the robot ``spec``, also the payload
    columns (:func:`urident.gap.candidates.set_payload_columns`; a load mounted after the
    identification run changes the gravity torque with the pose: smooth, no event)."""
    from urident.ident import features

    from urident.ident.friction import dahl_states, velocity_displacement

    s = ctx.sign()
    cols = [np.ones_like(s), s, ctx.qd, ctx.dtau, ctx.tau_hat, np.abs(ctx.tau_link) * s]
    cols += [features.stribeck(ctx.qd, ctx.friction_eps, vs) for vs in BASIS_VS]
    p = ctx.data.prepared
    z = dahl_states(velocity_displacement(p.t, p.qd, p.segment), BASIS_DELTAS, p.segment)
    cols += [zd - s for zd in z]           # friction held at a stop with the sign of the move before
    if spec is not None:
        from urident.gap.candidates import set_payload_columns

        pay = set_payload_columns(spec, ctx)
        cols += [pay[:, :, i] for i in range(pay.shape[2])]
    return np.stack(cols, axis=2)


def _smooth_fit(r: np.ndarray, basis: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(N, 6) the least-squares fit of each joint's residual on its basis columns, on ``keep``."""
    out = np.zeros_like(r)
    for j in range(r.shape[1]):
        x = basis[:, j, :]
        k = keep[:, j]
        scale = np.sqrt(np.mean(x[k] ** 2, axis=0))
        ok = scale > 0
        if not ok.any() or k.sum() < 2 * ok.sum():
            continue
        xs = x[:, ok] / scale[ok]
        beta, *_ = np.linalg.lstsq(xs[k], r[k, j], rcond=None)
        out[:, j] = xs @ beta
    return out


def find_events(r: np.ndarray, run_time: np.ndarray, qd: np.ndarray, fs: float,
                basis: np.ndarray | None = None) -> list[Event]:
    """The events of the residual ``r`` (N, 6) (module doc); ``run_time`` (N,) s from the
    recording's first sample, ``qd`` (N, 6) the joint velocities (a stall), ``fs`` the sample rate;
    ``basis`` (N, 6, k): smooth effects' columns (:func:`smooth_basis`) fitted and removed first
    (without the samples of the events found, twice)."""
    r = np.asarray(r, float)
    n = len(r)
    if n < 10:
        return []
    d, z = departures(r, fs)
    if basis is not None:
        for _ in range(2):
            keep = ~_stretches(z).any(axis=1, keepdims=True) & np.ones(r.shape, bool)
            d, z = departures(r - _smooth_fit(r, basis, keep), fs)
    core = z > CORE_Z
    flag = _stretches(z).any(axis=1)
    merge = int(round(MERGE_S * fs))
    runs = _runs(flag)
    merged: list[list[int]] = []
    for a, b in runs:
        if merged and a - merged[-1][1] <= merge:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    speed = np.linalg.norm(np.asarray(qd, float), axis=1)
    sigma = noise_sigma(r)
    out = []
    for a, b in merged:
        t0, t1 = float(run_time[a]), float(run_time[b - 1])
        n_core = int(np.any(core[a:b], axis=1).sum())
        if t1 - t0 < MIN_DURATION_S or n_core < MIN_CORE_S * fs:
            continue
        joints = [j for j in range(r.shape[1]) if core[a:b, j].any()
                  and np.abs(d[a:b, j]).max() >= MIN_PEAK_NOISE * sigma[j]]
        if not joints:
            continue
        joints.sort(key=lambda j: -float(z[a:b, j].max()))
        peak = tuple(float(r[a + int(np.argmax(np.abs(r[a:b, j]))), j]) for j in joints)
        rms = tuple(float(np.sqrt(np.mean(r[a:b, j] ** 2))) for j in joints)
        before = speed[max(0, a - int(0.5 * fs)):a]
        moving = before.size and float(np.median(before)) > MOVING_RAD_S
        if moving and float(np.median(speed[a:b])) < STALL_RATIO * float(np.median(before)):
            kind = "stall"
        elif t1 - t0 < IMPACT_S:
            kind = "impact"
        else:
            kind = "external_contact"
        out.append(Event(int(a), int(b), t0, t1, tuple(joints), peak, rms, kind))
    return out


def event_mask(n: int, events) -> np.ndarray:
    """(N,) True on the samples of ``events``."""
    mask = np.zeros(n, bool)
    for e in events:
        mask[e.start:e.stop] = True
    return mask


def without_events(data, events):
    """The :class:`urident.gap.data.GapSet` ``data`` without the samples of ``events``; each piece
    left between two events is a segment of its own (never filtered or differentiated across)."""
    from dataclasses import replace

    if not events:
        return data
    keep = np.flatnonzero(~event_mask(len(data), events))
    p = data.prepared.select(keep)
    seg = np.asarray(data.prepared.segment)[keep]
    cut = (np.diff(seg) != 0) | (np.diff(keep) > 1)
    p = replace(p, segment=np.r_[0, np.cumsum(cut)].astype(int))
    sub = lambda x: None if x is None else x[keep]   # noqa: E731
    return replace(data, prepared=p, run_time=data.run_time[keep], temperature=sub(data.temperature),
                   target_moment=sub(data.target_moment))
