"""Sim-to-real gap diagnosis: where the baseline model's residual lies, which unmodelled effect of
the catalogue (:mod:`urident.simcontroller.effects`) explains it, and how far it shrinks once that
effect is added.

    from urident.gap import diagnose, GapConfig
    result = diagnose(ident_recordings, valid_recordings, spec)       # Recordings + robot only
    print(format_report(result)); json.dump(result.as_dict(), fh)

Pipeline (one small module each): :mod:`.data` (recordings → prepared sets with the auxiliary
signals), :mod:`.residual` (the paper's baseline: OLS, tanh friction, ε = 0.01 rad/s, and the
residual on the validation data), :mod:`.maps` (where: binned maps over velocity, signed load,
angle, time and frequency; angle-domain spectrum), :mod:`.candidates` (which: one set of regressor
columns per catalogue effect and joint), :mod:`.scoring` (refit on the identification logs or
blocked cross-validation inside the validation logs, held-out scores), :mod:`.bootstrap` (block
bootstrap over time), :mod:`.significance` (the held-out tests of a candidate), :mod:`.selection`
(stepwise selection, confounds), :mod:`.where` (the where-text), :mod:`.config` (settings),
:mod:`.results` (result types and JSON), :mod:`.diagnose` (the entry points), :mod:`.report`
(console table and markdown), :mod:`.check` (the findings scored on held-out logs, ``--check``). How the thresholds were calibrated: ``docs/gap-calibration.md``.
"""

from urident.gap.config import NO_EFFECT, GapConfig
from urident.gap.diagnose import diagnose, diagnose_prepared
from urident.gap.report import format_report
from urident.gap.results import Finding, GapResult

__all__ = ["NO_EFFECT", "Finding", "GapConfig", "GapResult", "diagnose", "diagnose_prepared",
           "format_report"]
