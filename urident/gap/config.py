"""The diagnosis' settings: :class:`GapConfig` and the verdict text when nothing is found.

Each threshold carries one line of rationale; how they were calibrated on the blind benchmark is in
``docs/gap-calibration.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

from urident.errors import ConfigError
from urident.gap.candidates import EFFECTS

NO_EFFECT = "no unmodelled effect found"

#: 3 % materiality floor: above the largest shrink effect-free data showed (docs/gap-calibration.md).
MIN_SHRINK_CALIBRATION = "3 %: 2.3 x the largest effect-free shrink (1.3 %) over 80 scenarios"


@dataclass(frozen=True)
class GapConfig:
    effects: tuple[str, ...] = EFFECTS
    n_folds: int = 5                 # CV blocks inside the validation logs
    n_boot: int = 1000               # bootstrap resamples
    level: float = 0.95              # interval level
    min_shrink_pct: float = 3.0      # a finding must shrink its joint's RMS by at least this
                                     # (calibration: MIN_SHRINK_CALIBRATION)
    cv_min_noise_ratio: float = 0.5  # a CV-mode finding's correction RMS on its joint must be at
                                     # least this multiple of the joint's white-noise torque
    ident_max_projection: float = 1.5  # an identification-mode finding's joint may hold at most this
                                     # multiple of its correction along it (0: no limit)
    max_effects: int = 3
    confound_corr: float = 0.8
    parsimony_tol: float = 0.05      # a confounded alternative with fewer columns is chosen when
                                     # its held-out gain is within this share of the best's
    shortlist_ratio: float = 0.8     # phase A: in-sample gain at least this share of the best's
    shortlist_size: int = 4
    block_s: float = 1.0             # bootstrap block length [s]
    friction_eps: float = 0.01       # [rad/s] the baseline's tanh slope
    seed: int = 0
    test: str = "own"                # held-out test: "own" (interval of the gain on the
                                     # candidate's joint above 0, summed gain positive) or "total"
                                     # (interval of the gain summed over joints above 0)

    def __post_init__(self) -> None:
        unknown = [e for e in self.effects if e not in EFFECTS]
        if unknown:
            raise ConfigError(f"effect {unknown[0]!r} unknown (known: {', '.join(EFFECTS)})")
        if self.test not in ("own", "total"):
            raise ConfigError(f"gap config: test must be 'own' or 'total', not {self.test!r}")
        if not (0 <= self.parsimony_tol < 1):
            raise ConfigError("gap config: parsimony_tol in [0, 1)")
        if not (0 < self.level < 1) or self.n_boot < 50 or self.max_effects < 0:
            raise ConfigError("gap config: level in (0, 1), n_boot >= 50, max_effects >= 0")
