"""What a diagnosis returns: scored candidates (:class:`Score`), findings, the
:class:`GapResult`, and its JSON document (:func:`result_dict`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from urident.gap.candidates import Candidate
from urident.gap.config import NO_EFFECT, GapConfig
from urident.gap.residual import SetContext
from urident.gap.scoring import Fit, Scorer
from urident.ident.metrics import error_metrics


def rms(r: np.ndarray) -> np.ndarray:
    """(6,) RMS per joint of an (N, 6) residual [N·m]."""
    return error_metrics(r)[1]


def e_n(r: np.ndarray) -> float:
    """The paper's e_N = ‖r‖ / N of an (N, 6) residual."""
    return error_metrics(r)[0]


@dataclass(eq=False)
class Score:
    """One candidate scored on top of the current model."""

    candidate: Candidate
    fit: Fit
    gain: float                      # mean per-sample improvement Σ_j Δr² [N·m²]
    ci: tuple[float, float]
    joint: int                       # 0-based joint it helps most (its own for one-joint effects)
    rms_before: np.ndarray
    rms_after: np.ndarray
    significant: bool
    change: np.ndarray | None = field(default=None, repr=False)   # (N, 6) correction of the prediction
    d: np.ndarray | None = field(default=None, repr=False)        # (N,) per-sample improvement
    base: Fit | None = field(default=None, repr=False)            # the fit it was scored on top of
    d_blocks: np.ndarray | None = field(default=None, repr=False)  # (M,) sums of d per bootstrap block
    block_counts: np.ndarray | None = field(default=None, repr=False)
    change_rms: np.ndarray | None = field(default=None, repr=False)   # (6,) RMS of ``change``
    short_of_floor: bool = False     # identification mode: every test passed but materiality

    def materialize(self) -> "Score":
        """Fill ``change`` and ``d`` (per sample) from the fits (only the scores reported need them)."""
        if self.change is None and self.base is not None:
            before, after = self.base.residual, self.fit.residual
            self.change = before - after
            self.d = np.sum(before ** 2 - after ** 2, axis=1)
        return self

    @property
    def shrink_pct(self) -> float:
        b, a = self.rms_before[self.joint], self.rms_after[self.joint]
        return float(100.0 * (1.0 - a / b)) if b > 0 else 0.0

    def row(self, spec=None) -> dict:
        c = self.candidate
        coef = self.fit.coefficients()[c]
        return {"effect": c.effect, "joint": self.joint + 1, "variant": c.variant, "mode": c.mode,
                "gain_nm2": self.gain, "gain_ci95_nm2": list(self.ci),
                "rms_before_nm": float(self.rms_before[self.joint]),
                "rms_after_nm": float(self.rms_after[self.joint]), "shrink_pct": self.shrink_pct,
                "significant": bool(self.significant), "magnitude": c.magnitude(coef, spec)}


@dataclass(frozen=True)
class Finding:
    joint: int                       # 1-based
    effect: str
    variant: str
    mode: str
    regime: str
    rms_before_nm: float
    rms_after_nm: float
    shrink_pct: float
    confidence: str                  # high | medium | confounded
    gain_ci95_nm2: tuple[float, float]
    magnitude: dict
    confounded_with: tuple[str, ...] = ()
    joints: tuple[int, ...] = ()     # 1-based, every joint it changes, most torque explained first
    torque_nm: tuple[float, ...] = ()        # per joint of ``joints``: RMS of its correction [N·m]
    joint_shrink_pct: tuple[float, ...] = ()  # per joint of ``joints``: validation RMS shrink [%]
    claim: str = "cause"             # cause | partial (its form leaves what it does not explain)
    remains: dict = field(default_factory=dict)   # partial: what its form leaves (texts, figures)

    def as_dict(self) -> dict:
        return {"joint": self.joint, "joints": list(self.joints or (self.joint,)),
                "torque_nm": list(self.torque_nm), "joint_shrink_pct": list(self.joint_shrink_pct),
                "effect": self.effect, "variant": self.variant, "mode": self.mode,
                "regime": self.regime, "rms_before_nm": self.rms_before_nm,
                "rms_after_nm": self.rms_after_nm, "shrink_pct": self.shrink_pct,
                "confidence": self.confidence, "gain_ci95_nm2": list(self.gain_ci95_nm2),
                "magnitude": self.magnitude, "confounded_with": list(self.confounded_with),
                "claim": self.claim, **({"remains": self.remains} if self.remains else {})}


@dataclass(eq=False, frozen=True)
class GapResult:
    robot: str
    model: object                    # the baseline IdentifiedModel
    ident: SetContext
    valid: SetContext
    baseline_e_n: float
    baseline_rms: np.ndarray
    final_e_n: float
    final_rms: np.ndarray
    findings: list[Finding]
    fit: Fit                         # the selected candidates, fitted
    steps: list[list[Score]]         # every candidate scored at every greedy step
    confounds: list[dict]
    where: dict                      # per-joint maps and regimes
    config: GapConfig
    scorer: Scorer | None = None     # to fit any candidates on the same data (benchmarks)
    events: list = field(default_factory=list)   # urident.gap.events.Event, set aside
    n_valid_all: int | None = None   # validation samples before the events were set aside
    check: object = None             # urident.gap.check.CheckResult on held-out logs, if checked

    @property
    def verdict(self) -> str:
        if not self.findings:
            return NO_EFFECT
        return "; ".join(f"{f.effect} on joint {f.joint}" for f in self.findings)

    def chosen(self) -> list[Candidate]:
        return list(self.fit.ident) + list(self.fit.cv)

    def best_of(self, effect: str, joint: int | None) -> Candidate | None:
        """The best-scoring first-step candidate of ``effect`` on 0-based ``joint`` (any joint
        for effects on all joints)."""
        best = None
        for s in self.steps[0] if self.steps else []:
            c = s.candidate
            if c.effect == effect and (c.joint is None or c.joint == joint):
                if best is None or s.gain > best.gain:
                    best = s
        return None if best is None else best.candidate

    def correction(self, candidates: Sequence[Candidate]) -> Fit:
        """``candidates`` fitted together on this diagnosis' data (as the selection would be);
        ``.change(make_context(spec, result.model, other_set))`` applies them elsewhere."""
        return self.scorer.evaluate(list(candidates))

    def as_dict(self) -> dict:
        return result_dict(self)

    def to_dict(self) -> dict:
        """The JSON document ``urident gap --json-out`` writes (with the held-out ``check``)."""
        doc = result_dict(self)
        if self.check is not None:
            doc["check"] = json_safe(self.check.as_dict())
        return doc

    def to_json(self, indent: int | None = 1) -> str:
        """:meth:`to_dict` as JSON text: no NaN, None or infinity (a missing figure says why)."""
        import json

        return json.dumps(self.to_dict(), indent=indent, allow_nan=False, default=json_default)


def json_default(x):
    """numpy arrays and scalars as JSON lists and numbers."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def _list(x) -> list[float]:
    return [float(v) for v in np.asarray(x, float)]


def result_dict(res) -> dict:
    """The JSON document: baseline, findings, final (the required keys) and the details."""
    return json_safe(_document(res))


#: Why a quantity of the report is absent, by its key (the report writes no NaN, None or infinity:
#: a quantity that cannot be computed is left out and named under ``absent`` with the reason).
ABSENT_REASONS = {
    "rms_nm": "no samples in this bin", "mean_nm": "no samples in this bin",
    "lo": "the bin is unbounded below", "hi": "the bin is unbounded above",
    "measured_over_target_scale": "the target moment is zero on this joint",
    "gain_factor": "the fitted correction leaves no positive gain (1 + coefficient <= 0)",
    "extrapolated_shrink_pct": "no correction on this run's motion to extrapolate",
    "limit": "its column is zero on these states: no value is identifiable",
    "peak_hz": "too few samples for a spectrum",
    "change_between_runs": "no target moment in the identification logs",
    "controller_model": "the logs hold no target moment",
}
#: The reason given for a key not in :data:`ABSENT_REASONS`.
NOT_COMPUTABLE = "not computable on these data"


def _missing(v) -> bool:
    return v is None or (isinstance(v, (float, np.floating)) and not np.isfinite(v))


def json_safe(x):
    """``x`` made JSON-safe: numpy scalars to Python; a value that is None or not finite is left
    out and its key listed under ``absent`` with the reason (:data:`ABSENT_REASONS`); a list with
    such entries (a per-joint figure some joints lack) becomes ``{"1": value, ...}`` keyed by the
    1-based position of the entries that exist, the others listed under ``absent`` as
    ``key[position]``. A bare missing value outside a dict is an error (nothing to name it by)."""
    if isinstance(x, dict):
        out, absent = {}, dict(x.get("absent") or {})
        for k, v in x.items():
            k = str(k)
            if k == "absent":
                continue
            if isinstance(v, np.ndarray):
                v = v.tolist()
            if _missing(v):
                absent.setdefault(k, ABSENT_REASONS.get(k, NOT_COMPUTABLE))
            elif isinstance(v, (list, tuple)) and any(_missing(e) for e in v):
                out[k] = {str(i + 1): json_safe(e) for i, e in enumerate(v) if not _missing(e)}
                for i, e in enumerate(v):
                    if _missing(e):
                        absent.setdefault(f"{k}[{i + 1}]", ABSENT_REASONS.get(k, NOT_COMPUTABLE))
            else:
                out[k] = json_safe(v)
        if absent:
            out["absent"] = {str(k): str(v) for k, v in absent.items()}
        return out
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        if not np.isfinite(x):
            raise ValueError(f"non-finite number {x} outside a named field of the report")
        return float(x)
    return x


def _events_summary(res) -> dict:
    events = getattr(res, "events", [])
    n_all = getattr(res, "n_valid_all", None) or res.valid.n
    aside = int(sum(e.stop - e.start for e in events))
    return {"n_samples_set_aside": aside, "n_valid_samples": int(n_all),
            "share_set_aside": float(aside / n_all) if n_all else 0.0}


def _document(res) -> dict:
    b, f = res.baseline_rms, res.final_rms
    steps = []
    for k, scores in enumerate(res.steps):
        steps.append({"step": k + 1, "candidates": [s.row() for s in scores]})
    return {
        "robot": res.robot,
        "verdict": res.verdict,
        "no_effect_found": not res.findings,
        "baseline": {"e_n": float(res.baseline_e_n), "rms_nm": _list(b), "method": res.model.method,
                     "friction_eps": float(res.model.model.friction_eps),
                     "n_ident_samples": res.ident.n, "n_valid_samples": res.valid.n},
        "findings": [x.as_dict() for x in res.findings],
        "final": {"e_n": float(res.final_e_n), "rms_nm": _list(f),
                  "shrink_pct": _list(np.where(b > 0, 100 * (1 - f / np.where(b > 0, b, 1)), 0.0)),
                  "e_n_shrink_pct": float(100 * (1 - res.final_e_n / res.baseline_e_n))
                  if res.baseline_e_n > 0 else 0.0},
        "confounded": res.confounds,
        "events": [e.as_dict() for e in getattr(res, "events", [])],
        "events_summary": _events_summary(res),
        "where": res.where,
        "candidates": steps,
        "settings": {"min_shrink_pct": res.config.min_shrink_pct,
                     "cv_min_noise_ratio": res.config.cv_min_noise_ratio, "level": res.config.level,
                     "n_boot": res.config.n_boot, "n_folds": res.config.n_folds,
                     "block_s": res.config.block_s, "parsimony_tol": res.config.parsimony_tol,
                     "confound_corr": res.config.confound_corr, "no_effect_text": NO_EFFECT},
    }
