"""Coulomb friction states beyond the paper's tanh(q̇/ε).

Each replaces the Coulomb column (or, as the ``dahl`` extra feature, adds one), one per joint:

* ``tanh`` (paper): sign(q̇) ≈ tanh(q̇/ε).
* ``dahl``: a presliding/hysteresis state z ∈ [−1, 1] driven by the joint's motion history,
  dz/dq = (1 − z·sign(q̇))/δ (Dahl's model, normalised by the Coulomb level). While the joint moves
  z → sign(q̇) within a few δ of travel, like tanh; when it stops, z *keeps* the value it had, so
  the friction torque at standstill depends on the direction of the last motion, not on the sign of
  the (noisy, tiny) filtered velocity. Exact update for a step Δq of constant sign s:
  z ← s + (z − s)·exp(−|Δq|/δ). State starts at 0 at the beginning of each segment.
* ``hold``: a velocity-driven friction state with memory. z follows tanh(q̇/ε) whenever that moves
  it *away* from zero (|tanh(q̇/ε)| > |z|, same sign) or across zero with |q̇| ≥ v_h (a real reversal,
  not velocity noise); otherwise z keeps its value. In motion it equals the paper's tanh except just
  before a reversal (where it stays saturated: the joint is still sliding); when the joint
  decelerates to a stop it keeps the full friction of the last motion direction (the holding
  current of a harmonic drive stopped after sliding, presliding memory as in Dahl/LuGre) instead
  of dropping to tanh(≈0) = 0. v_h is a few times the standstill velocity noise.

The extra columns that are not a friction state (offset, Stribeck, load friction, sub-linear
viscous) are in :mod:`urident.ident.features`, shared with the gap diagnosis; the column names and
kinds of every extra feature are in :data:`urident.model.parameters.EXTRA_COLUMNS`.

Displacement for the Dahl state (``dahl_source``). ``position``: the differences of the logged q.
``velocity``: the displacement integrated from the logged q̇ (trapezoid rule on the timestamps),
which does not depend on how finely the log stores positions (Dahl distances are ~1e-4 rad, and
some logs store q with 4 decimals, i.e. 1e-4 rad steps, while q̇ keeps its full resolution). Without
timestamps (``t=None``) the position differences are used.
"""

from __future__ import annotations

import numpy as np

COULOMB_MODELS = ("tanh", "dahl", "hold")
DAHL_SOURCES = ("position", "velocity")


def velocity_displacement(t: np.ndarray, qd: np.ndarray, segment: np.ndarray | None = None) -> np.ndarray:
    """(N, 6) displacement ∫q̇ dt (trapezoid rule on the timestamps ``t``), restarting at 0 in each
    segment: a position signal as fine as the velocity signal (module doc)."""
    t = np.asarray(t, dtype=float)
    qd = np.asarray(qd, dtype=float)
    steps = 0.5 * (qd[1:] + qd[:-1]) * np.diff(t)[:, None]
    x = np.vstack([np.zeros((1, qd.shape[1])), np.cumsum(steps, axis=0)])
    if segment is not None:
        seg = np.asarray(segment)
        starts = np.r_[0, np.flatnonzero(np.diff(seg) != 0) + 1]
        first = np.repeat(starts, np.diff(np.r_[starts, len(seg)]))
        x = x - x[first]
    return x


def dahl_state(q: np.ndarray, delta: float, segment: np.ndarray | None = None,
               initial: np.ndarray | None = None) -> np.ndarray:
    """(N, 6) normalised Dahl state from (N, 6) positions; reset to 0 where ``segment`` changes.
    ``initial`` (6,): the state at the first sample instead of 0 (a stream continuing)."""
    return np.ascontiguousarray(dahl_states(q, (delta,), segment, initial)[0])


def dahl_states(q: np.ndarray, deltas, segment: np.ndarray | None = None,
                initial: np.ndarray | None = None) -> np.ndarray:
    """(D, N, 6) :func:`dahl_state` for each presliding distance of ``deltas`` (D,), in one pass
    over the samples (the per-sample recursion is the cost, not the width of each step)."""
    q = np.asarray(q, dtype=float)
    d = np.asarray(deltas, dtype=float).reshape(-1, 1)
    n, m = q.shape
    z = np.zeros((n, len(d), m))
    dq = np.diff(q, axis=0)
    s = np.sign(dq)
    decay = np.exp(-np.abs(dq)[:, None, :] / d)           # (N - 1, D, 6)
    new_seg = np.zeros(n, dtype=bool) if segment is None else np.r_[False, np.diff(segment) != 0]
    cur = np.zeros((len(d), m)) if initial is None else np.broadcast_to(np.asarray(initial, float), (len(d), m))
    if n:
        z[0] = cur
    for k in range(1, n):
        if new_seg[k]:
            cur = np.zeros((len(d), m))
        else:
            cur = s[k - 1] + (cur - s[k - 1]) * decay[k - 1]
        z[k] = cur
    return z.transpose(1, 0, 2)


def hold_state(qd: np.ndarray, eps: float, v_hold: float, segment: np.ndarray | None = None,
               initial: np.ndarray | None = None) -> np.ndarray:
    """(N, 6) friction state of the ``hold`` model (module doc); starts at tanh(q̇₀/ε) per segment,
    or at ``initial`` (6,) on the first sample (a stream continuing)."""
    qd = np.asarray(qd, dtype=float)
    target = np.tanh(qd / eps)
    reverse_ok = np.abs(qd) >= v_hold
    starts = np.zeros(len(qd), dtype=bool)
    starts[0] = True
    if segment is not None:
        starts[1:] |= np.diff(segment) != 0
    z = np.empty_like(target)
    cur = target[0].copy()
    for k in range(len(qd)):
        if starts[k]:
            cur = target[k].copy() if k or initial is None else np.array(initial, dtype=float)
        else:
            t = target[k]
            same = np.sign(t) == np.sign(cur)
            grow = same & (np.abs(t) > np.abs(cur))
            flip = ~same & reverse_ok[k]
            cur = np.where(grow | flip, t, cur)
        z[k] = cur
    return z


def standstill_velocity_noise(qd: np.ndarray, threshold: float = 1e-3) -> float:
    """Std of q̇ over samples where every |q̇_j| < threshold (the log's rest), or nan if none."""
    qd = np.asarray(qd, dtype=float)
    rest = np.all(np.abs(qd) < threshold, axis=1)
    return float(np.std(qd[rest])) if rest.sum() > 10 else float("nan")
