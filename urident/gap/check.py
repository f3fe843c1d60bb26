"""Held-out check of a diagnosis' findings on logs used neither for identification nor for
selection (``urident gap … --check LOG``).

Per finding, on its joint: the *predicted* shrink is what the finding adds on top of the other
chosen effects on the validation logs, 100·(1 − RMS_all/RMS_others); the *checked* shrink is the
same figure on the check logs, with every chosen effect fitted as the diagnosis fitted it
(identification mode: the joint refit with the base parameters; CV mode: the coefficients fitted
on all validation samples) and applied unchanged. Both get a 95 % block-bootstrap interval
(blocks of ~1 s, the squared residuals before and after resampled together). A finding *holds*
when its checked interval lies above 0: on the check logs it still makes its joint's residual
smaller. Beside the predicted figure, the one extrapolated to the check logs' motion
(:mod:`urident.gap.predict`: the finding's correction there, from their motion alone, against what
the findings leave), which the checked figure tests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from urident.gap.bootstrap import block_bootstrap_means, default_block_length, interval
from urident.gap.candidates import Candidate
from urident.gap.data import build_set
from urident.gap.predict import delay_form_misfit, extrapolated_shrink_pct, remaining_rms, rest_ratio
from urident.gap.residual import make_context


@dataclass(frozen=True)
class CheckRow:
    finding: int                     # 0-based index into GapResult.findings
    effect: str
    joint: int                       # 1-based
    predicted_pct: float
    predicted_ci: tuple[float, float]
    checked_pct: float
    checked_ci: tuple[float, float]
    holds: bool
    extrapolated_pct: float = float("nan")   # predicted for the check logs' motion (urident.gap.predict)

    def as_dict(self) -> dict:
        return {"effect": self.effect, "joint": self.joint, "predicted_shrink_pct": self.predicted_pct,
                "predicted_shrink_ci95_pct": list(self.predicted_ci),
                "extrapolated_shrink_pct": self.extrapolated_pct, "checked_shrink_pct": self.checked_pct,
                "checked_shrink_ci95_pct": list(self.checked_ci), "holds": self.holds}


@dataclass(frozen=True)
class CheckResult:
    n_samples: int
    rows: list[CheckRow]
    baseline_rms: np.ndarray         # (6,) on the check logs [N·m]
    final_rms: np.ndarray            # (6,) with every chosen effect

    def as_dict(self) -> dict:
        b, f = self.baseline_rms, self.final_rms
        return {"n_samples": self.n_samples, "findings": [r.as_dict() for r in self.rows],
                "baseline_rms_nm": [float(x) for x in b], "final_rms_nm": [float(x) for x in f],
                "shrink_pct": [float(100 * (1 - y / x)) if x > 0 else 0.0 for x, y in zip(b, f)]}


def finding_candidate(res, k: int) -> Candidate:
    """The chosen candidate behind ``res.findings[k]``."""
    f = res.findings[k]
    for c in res.chosen():
        if (c.effect, c.mode, c.variant) == (f.effect, f.mode, f.variant) and \
                (c.joint is None or c.joint + 1 == f.joint):
            return c
    raise LookupError(f"no chosen candidate for finding {f.effect} on joint {f.joint}")


def shrink_with_interval(before: np.ndarray, after: np.ndarray, block: int, n_boot: int, seed: int,
                         level: float) -> tuple[float, tuple[float, float]]:
    """100·(1 − RMS(after)/RMS(before)) of two (N,) residuals, with its block-bootstrap interval."""
    sq = np.stack([before ** 2, after ** 2], axis=1)
    boot = block_bootstrap_means(sq, block, n_boot, seed)
    point = 100.0 * (1.0 - np.sqrt(sq[:, 1].mean() / sq[:, 0].mean())) if sq[:, 0].mean() > 0 else 0.0
    samples = 100.0 * (1.0 - np.sqrt(boot[:, 1] / np.where(boot[:, 0] > 0, boot[:, 0], np.inf)))
    return float(point), interval(samples, level)


def check_findings(res, check_recordings: Sequence, spec, *, drive_gains=None, params=None) -> CheckResult:
    """Score ``res``'s findings on ``check_recordings`` (module doc)."""
    cfg = res.config
    data = build_set(check_recordings, spec, drive_gains, None, "check logs", params)
    ctx = make_context(spec, res.model, data)
    r0 = ctx.residual
    chosen = res.chosen()
    r_all = r0 - res.fit.change(ctx) if chosen else r0
    block_c = default_block_length(ctx.n, data.sample_rate * cfg.block_s)
    block_v = default_block_length(res.valid.n, res.valid.data.sample_rate * cfg.block_s)
    # a delay's form misfit on either run and how the rest of the leftover scales (urident.gap.predict)
    m_valid, m_check = delay_form_misfit(res.fit, res.valid), delay_form_misfit(res.fit, ctx)
    ratio = rest_ratio(res.fit, res.valid, ctx) if chosen else np.ones(6)
    rows = []
    for k, f in enumerate(res.findings):
        c = finding_candidate(res, k)
        j = f.joint - 1
        others = res.correction([o for o in chosen if o is not c])
        p, p_ci = shrink_with_interval(others.residual[:, j], res.fit.residual[:, j], block_v,
                                       cfg.n_boot, cfg.seed, cfg.level)
        r_oth = r0 - others.change(ctx)
        s, s_ci = shrink_with_interval(r_oth[:, j], r_all[:, j], block_c, cfg.n_boot, cfg.seed, cfg.level)
        # the finding's own correction on the check logs' motion, against what the findings leave
        c_valid = _rms(others.residual - res.fit.residual)
        own_check = r_oth - r_all
        c_check = _rms(own_check)
        u = remaining_rms(res.fit, c_valid, c_check, _rms(m_valid), _rms(m_check), ratio)
        e = extrapolated_shrink_pct(u, c_check, np.mean(m_check * own_check, axis=0))[j]
        rows.append(CheckRow(k, f.effect, f.joint, p, p_ci, s, s_ci, bool(s_ci[0] > 0), float(e)))
    return CheckResult(ctx.n, rows, _rms(r0), _rms(r_all))


def _rms(r: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(r ** 2, axis=0))


def format_check(chk: CheckResult) -> str:
    lines = [f"Check (held-out logs, {chk.n_samples} samples; shrink of the finding's joint on top of the "
             "other findings, 95 % interval):",
             "  finding                          joint   predicted (validation)    for their motion   checked"]
    for r in chk.rows:
        verdict = "holds" if r.holds else "DOES NOT HOLD on the check logs"
        lines.append(f"  {r.finding + 1}. {r.effect:28s} {r.joint:3d}   {r.predicted_pct:5.1f} % "
                     f"[{r.predicted_ci[0]:5.1f}, {r.predicted_ci[1]:5.1f}]   {r.extrapolated_pct:5.1f} %"
                     f"            {r.checked_pct:5.1f} % "
                     f"[{r.checked_ci[0]:5.1f}, {r.checked_ci[1]:5.1f}]  {verdict}")
    b, f = chk.baseline_rms, chk.final_rms
    lines.append("  joint RMS on the check logs [Nm], baseline -> with every finding: " +
                 ", ".join(f"{j + 1}: {b[j]:.3f} -> {f[j]:.3f}" for j in range(len(b))))
    return "\n".join(lines)
