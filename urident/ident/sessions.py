"""Session shifts: how much of a session's prediction error is a change that the shared model does
not carry from one day to the next — a constant torque per joint (a current-sensor offset, a
static load) and a scale of the joint's friction torque (lubricant temperature, wear).

:func:`session_shift` fits both per joint on a session's residual (measured − predicted torque) by
least squares against [1, f_j(t)], f_j the identified model's friction torque of joint j on the
same samples, and reports the RMS before and after: the share of the session's error such a shift
explains. Two numbers per joint over the whole log: the in-sample optimism is negligible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.ident.design import design_chunks
from urident.ident.preprocess import Prepared
from urident.model.parameters import is_friction


@dataclass(frozen=True)
class SessionShift:
    """Per joint: the fitted offset [N·m] and friction scale (1 = the identified friction), the
    RMS of the residual before and after removing them [N·m]."""

    offset_nm: np.ndarray
    friction_scale: np.ndarray
    rms_before: np.ndarray
    rms_after: np.ndarray

    @property
    def explained_pct(self) -> np.ndarray:
        """(6,) share of each joint's mean square error the shift explains [%]."""
        before = np.where(self.rms_before > 0, self.rms_before, 1.0)
        return 100.0 * (1.0 - (self.rms_after / before) ** 2)

    @property
    def explained_mean_pct(self) -> float:
        """Share of the joints' summed mean square error the shift explains [%]."""
        b = float(np.sum(self.rms_before ** 2))
        return 100.0 * (1.0 - float(np.sum(self.rms_after ** 2)) / b) if b > 0 else 0.0

    def text(self) -> str:
        return "\n".join([
            f"  session shift (offset + friction scale per joint, fitted on this log): explains "
            f"{self.explained_mean_pct:.1f} % of the mean square error",
            "    offset_nm      " + " ".join(f"{v:6.2f}" for v in self.offset_nm),
            "    friction_scale " + " ".join(f"{v:6.3f}" for v in self.friction_scale),
            "    rms_after_nm   " + " ".join(f"{v:6.2f}" for v in self.rms_after),
            "    explained_pct  " + " ".join(f"{v:6.1f}" for v in self.explained_pct)])

    def as_dict(self) -> dict:
        return {"offset_nm": [float(v) for v in self.offset_nm],
                "friction_scale": [float(v) for v in self.friction_scale],
                "rms_before_nm": [float(v) for v in self.rms_before],
                "rms_after_nm": [float(v) for v in self.rms_after],
                "explained_pct": [float(v) for v in self.explained_pct],
                "explained_mean_pct": self.explained_mean_pct}


def friction_torque(identified, spec, data: Prepared) -> np.ndarray:
    """(N, 6) the identified model's friction torque (every column of a friction kind) on ``data``."""
    mask = is_friction(identified.kinds)
    values = np.where(mask, np.asarray(identified.values, dtype=float), 0.0)
    out = np.empty((len(data), 6))
    for a, b, blocks in design_chunks(spec, identified.model, data.q, data.qd, data.qdd, data.segment, data.t,
                                      temperature=data.temperature):
        out[a:b] = blocks @ values
    return out


def session_shift(identified, spec, data: Prepared, tau_predicted: np.ndarray) -> SessionShift:
    """The shift of one session (module doc): ``data.tau`` measured, ``tau_predicted`` (N, 6) the
    prediction on the same samples (:class:`urident.ident.prediction.Prediction`)."""
    residual = data.tau - np.asarray(tau_predicted, dtype=float)
    fric = friction_torque(identified, spec, data)
    offset, scale, after = np.zeros(6), np.ones(6), np.zeros(6)
    for j in range(6):
        a = np.column_stack([np.ones(len(data)), fric[:, j]])
        if not np.any(fric[:, j]):
            a = a[:, :1]
        x, *_ = np.linalg.lstsq(a, residual[:, j], rcond=None)
        offset[j] = x[0]
        if len(x) > 1:
            scale[j] = 1.0 + x[1]
        after[j] = np.sqrt(np.mean((residual[:, j] - a @ x) ** 2))
    before = np.sqrt(np.mean(residual ** 2, axis=0))
    return SessionShift(offset, scale, before, after)


# ---------------------------------------------------------------------------------------------
# Several sessions in one identification

NUISANCE = ("offset", "friction_scale")


@dataclass(frozen=True)
class SessionTerms:
    """Per-session nuisance terms kept by CV (``identify --sessions``): ``sessions`` the log of
    each session (the first is the reference: none of its own), ``chosen`` (joint, kind) pairs with
    their CV gain, and per kept pair the value in every other session (offset [N·m]; friction
    scale, 1 = the shared friction)."""

    sessions: tuple[str, ...]
    chosen: tuple[tuple[int, str, float, float], ...]     # (joint, kind, gain %, t)
    values: dict
    tried: tuple[tuple[int, str, float, float], ...]      # the best group not kept, per joint
    cv_rms_before: np.ndarray
    cv_rms_after: np.ndarray

    def text(self) -> str:
        lines = [f"sessions: {len(self.sessions)} (reference {self.sessions[0]}); per-session terms kept "
                 f"by blocked CV (every session cut in the same folds; same rule as the friction terms):"]
        if not self.chosen:
            lines.append("  none")
        for j, kind, gain, t in self.chosen:
            vals = ", ".join(f"{s}: {v:+.3f}" if kind == "offset" else f"{s}: {v:.3f}"
                             for s, v in zip(self.sessions[1:], self.values[(j, kind)]))
            lines.append(f"  J{j + 1} {kind} (-{gain:.1f} %, t {t:.1f}): {vals}")
        for j, kind, gain, t in self.tried:
            lines.append(f"  J{j + 1} not kept: {kind} ({-gain:+.1f} %, t {t:.1f})")
        lines.append("  CV RMS per joint [N·m] " + " ".join(f"{v:.3f}" for v in self.cv_rms_before)
                     + " -> " + " ".join(f"{v:.3f}" for v in self.cv_rms_after))
        return "\n".join(lines)


def session_index(data: Prepared) -> tuple[np.ndarray, tuple[str, ...]]:
    """(N,) session of each sample (one session per log file, in order) and the files."""
    files: list[str] = []
    seg_session = []
    for p in data.provenance:
        if p.file not in files:
            files.append(p.file)
        seg_session.append(files.index(p.file))
    if len(seg_session) != int(np.max(data.segment)) + 1:   # provenance not one per segment
        seg_session = list(range(int(np.max(data.segment)) + 1))
        files = [f"segment {k + 1}" for k in seg_session]
    return np.asarray(seg_session)[data.segment], tuple(files)


def fit_sessions(spec, data: Prepared, model, weighting: str = "joint", folds: int = 5):
    """Shared parameters and per-session nuisance terms (module doc): returns the data with every
    kept term removed from the measured torque (identify on it for the shared model) and the
    :class:`SessionTerms`. A term enters per joint and kind for all non-reference sessions at once,
    when its CV gain passes the friction terms' rule (:func:`urident.ident.friction_select.fold_test`
    and ``MIN_GAIN``)."""
    from dataclasses import replace as dc_replace

    from urident.errors import ConfigError
    from urident.ident.estimate_ols import estimate_ols_reduced
    from urident.ident.friction_select import MIN_GAIN, fold_test
    from urident.ident.identify import identify
    from urident.ident.reduced import Accumulator, ReducedLS, merge, triangle

    sess, files = session_index(data)
    n_s = len(files)
    if n_s < 2:
        raise ConfigError("--sessions needs logs of at least two sessions (one per log file)")
    first = identify(spec, data, "ols", model, weighting)
    fric = friction_torque(first, spec, data)
    # fold k: the k-th of `folds` contiguous blocks of every session
    fold = np.zeros(len(data), dtype=int)
    for s in range(n_s):
        idx = np.flatnonzero(sess == s)
        fold[idx] = np.minimum((np.arange(len(idx)) * folds) // max(len(idx), 1), folds - 1)
    # columns: the model's, then per joint j, kind, session s >= 1: one column on joint j's rows
    groups = [(j, kind) for j in range(6) for kind in NUISANCE]

    def nuisance(a, b):
        out = np.zeros((b - a, 6, len(groups) * (n_s - 1)))
        for g, (j, kind) in enumerate(groups):
            for s in range(1, n_s):
                on = (sess[a:b] == s).astype(float)
                out[:, j, g * (n_s - 1) + s - 1] = on if kind == "offset" else on * fric[a:b, j]
        return out

    accs = [Accumulator() for _ in range(folds)]
    for a, b, blocks in design_chunks(spec, model, data.q, data.qd, data.qdd, data.segment, data.t,
                                      temperature=data.temperature):
        full = np.concatenate([blocks, nuisance(a, b)], axis=2)
        for k in range(folds):
            rows = np.flatnonzero(fold[a:b] == k)
            if len(rows):
                accs[k].add(full[rows], data.tau[a:b][rows, :, None])
    parts = [acc.result() for acc in accs]
    n_model = parts[0].n_params - len(groups) * (n_s - 1)
    trains = [merge(p for i, p in enumerate(parts) if i != k) for k in range(folds)]
    n_test = np.array([p.n_samples for p in parts], dtype=float)

    def cols_of(sel):
        c = list(range(n_model))
        for g, grp in enumerate(groups):
            if grp in sel:
                c += [n_model + g * (n_s - 1) + s for s in range(n_s - 1)]
        return np.array(c + [parts[0].n_params])      # + the torque column

    def sub(red: ReducedLS, cols) -> ReducedLS:
        r = np.stack([triangle(rj[:, cols], len(cols)) for rj in red.r])
        return ReducedLS(r, red.n_samples, len(cols) - 1)

    def score(sel) -> np.ndarray:
        """(folds, 6) held-out mean square error."""
        cols = cols_of(sel)
        out = np.zeros((folds, 6))
        for k in range(folds):
            est = estimate_ols_reduced(sub(trains[k], cols), [str(i) for i in range(len(cols) - 1)], weighting)
            out[k] = sub(parts[k], cols).residual_sq(est.values) / n_test[k]
        return out

    sel: list[tuple[int, str]] = []
    chosen, tried = [], []
    base = score(sel)
    before = np.sqrt((base * n_test[:, None]).sum(axis=0) / n_test.sum())
    open_ = set(range(6))
    while open_:
        trial = {grp: score(sel + [grp]) for grp in groups if grp not in sel and grp[0] in open_}
        added = False
        for j in sorted(open_):
            best = None
            for (jj, kind), sc in trial.items():
                if jj != j:
                    continue
                t, _, passes = fold_test(base[:, j] - sc[:, j])
                gain = 100.0 * (1.0 - np.sqrt(np.sum(sc[:, j] * n_test) / np.sum(base[:, j] * n_test)))
                if best is None or gain > best[2]:
                    best = (j, kind, gain, t, passes)
            if best is not None and best[4] and best[2] >= 100 * MIN_GAIN:
                sel.append((j, best[1]))
                chosen.append(best[:4])
                added = True
            else:
                open_.discard(j)
                if best is not None:
                    tried.append(best[:4])
        if added:
            base = score(sel)
        else:
            break
    after = np.sqrt((base * n_test[:, None]).sum(axis=0) / n_test.sum())
    # the kept terms on all data, removed from the measured torque
    cols = cols_of(sel)
    est = estimate_ols_reduced(sub(merge(parts), cols), [str(i) for i in range(len(cols) - 1)], weighting)
    values, tau = {}, data.tau.copy()
    k = n_model
    for g, grp in enumerate(groups):
        if grp not in sel:
            continue
        j, kind = grp
        coef = est.values[k:k + n_s - 1]
        k += n_s - 1
        values[grp] = coef if kind == "offset" else 1.0 + coef
        for s in range(1, n_s):
            on = sess == s
            tau[on, j] -= coef[s - 1] * (1.0 if kind == "offset" else fric[on, j])
    terms = SessionTerms(files, tuple(chosen), values, tuple(tried), before, after)
    return dc_replace(data, tau=tau), terms
