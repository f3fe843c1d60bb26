"""Named identification configurations: ``paper`` (the paper's method), ``real-robot`` and ``auto``.

``auto``: the reduced base set, per-joint weighting, a Dahl presliding Coulomb state (driven by
∫q̇, δ chosen by blocked CV) and each joint's friction terms chosen by blocked CV on the
identification data given (:mod:`urident.ident.friction_select`): the same procedure on any arm.

``paper``: full base set (52 parameters), r_v·q̇ + r_c·tanh(q̇/ε) friction with ε = 0.01 rad/s,
plain least squares (Kovincic et al. 2019).

``real-robot``: the configuration that predicted the real UR10e best in blocked 5-fold
cross-validation *inside the identification run* (ur-20_02_10-30sec_12harm.csv rows 635-3510,
robot-file drive gains; score: mean over joints of the held-out RMS, N·m; the validation log played
no part in any choice). Forward selection: a candidate was kept when it lowered the CV mean by at
least 1 %; continuous hyper-parameters are the argmin of a grid.

==========================================================================  ======
model (each row changes the previous one)                                     CV mean
==========================================================================  ======
paper: full base set, tanh ε = 0.01 rad/s, plain OLS                           1.674
reduced base set (33) + per-joint weighting                                    1.586
+ load-dependent Coulomb friction |τ_L|·z (extra ``load``)                     1.385
+ sub-linear viscous sign(q̇)·sqrt|q̇| (extra ``sqrtvisc``)                       1.352
Coulomb state z: Dahl presliding state (∫q̇ dt, δ = 1.5e-4 rad) instead of tanh  1.293
+ Stribeck tanh(q̇/ε)·exp(−(q̇/0.05)²) (extra ``stribeck``), δ re-selected: 2e-4  1.271
==========================================================================  ======

Checked and not adopted (gain < 1 % or worse), at the last or an earlier stage: the colleague's
``hold`` state (1.635 vs 1.586 for tanh; 1.355 vs 1.293 with load + sqrtvisc), tanh ε 0.002-0.05
(≥ 1.584), a constant offset (1.270 vs 1.271), asymmetric Coulomb, a quadratic instead of a
square-root viscous term, separate motoring/braking load coefficients, a second Maxwell-slip
element, position dependence (cos/sin q_j, harmonic-drive ripple at 1-4 x the gear ratio), the
full base set (1.275), no weighting (1.284), a zero-phase torque low-pass before fitting (5-20 Hz,
scored on raw torques: no gain) and other acceleration-filter corners (5-20 Hz: within 0.5 %).
Stribeck velocity: flat over 0.03-0.1 rad/s (1.271-1.276), the default 0.05 kept. Removing a kept
term at the end: without sqrtvisc 1.364, tanh instead of Dahl 1.342.

Why ∫q̇ rather than q drives the Dahl state: with the identification log's q (1e-6 rad steps) the
two are within 0.3 % (1.290 vs 1.293 at δ = 1.5e-4), but with q rounded to 1e-4 rad, the
resolution some logs store (the UR10e point-to-point log does), the position-driven state degrades
to 1.325 while the velocity-driven one is unchanged (1.293): the model must not depend on how a log
rounds its positions.

The presliding distance δ is selected per identification data set from :data:`DAHL_GRID` by blocked
CV (``resolve_preset``, or ``urident identify --dahl-rad auto``): 2e-4 rad on the UR10e run.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from urident.errors import ConfigError
from urident.ident.crossval import CVScore, select_dahl_rad
from urident.ident.design import ModelConfig
from urident.ident.friction_select import DAHL_GRID, FrictionSelection, select_friction  # noqa: F401 (DAHL_GRID re-exported)
from urident.ident.preprocess import Prepared

CV_FOLDS = 5


@dataclass(frozen=True)
class Preset:
    name: str
    model: ModelConfig
    weighting: str
    select_dahl_rad: bool      # choose δ from DAHL_GRID by blocked CV on the identification data
    description: str
    select_friction: bool = False   # choose each joint's friction terms by blocked CV (friction_select)


PRESETS = {
    "paper": Preset("paper", ModelConfig(), "none", False,
                    "the paper's method: full base set, tanh friction (eps 0.01 rad/s), plain OLS"),
    "real-robot": Preset(
        "real-robot",
        ModelConfig(reduced=True, coulomb="dahl", dahl_source="velocity", dahl_rad=2e-4,
                    extras=("load", "sqrtvisc", "stribeck"), stribeck_vs=0.05),
        "joint", True,
        "reduced base set, per-joint weighting, Dahl presliding Coulomb state driven by the "
        "integrated velocity (distance chosen by 5-fold blocked CV), load-dependent Coulomb, "
        "square-root viscous and Stribeck (v_s 0.05 rad/s) friction"),
    "auto": Preset(
        "auto", ModelConfig(reduced=True, coulomb="dahl", dahl_source="velocity", dahl_rad=2e-4),
        "joint", False,
        "reduced base set, per-joint weighting, Dahl presliding Coulomb state driven by the "
        "integrated velocity, and each joint's friction terms (offset, asymmetry, sigmoid with "
        "offset, Stribeck, square-root/quadratic viscous, load-dependent Coulomb, Dahl, position "
        "harmonics) and the Dahl distance chosen by 5-fold blocked CV on the identification data",
        select_friction=True),
}


@dataclass(frozen=True)
class PresetChoice:
    """A preset resolved on identification data: the model, the weighting and the CV scores of
    the δ grid (empty when δ was not selected)."""

    preset: str
    model: ModelConfig
    weighting: str
    cv_scores: tuple[CVScore, ...] = ()
    selection: FrictionSelection | None = None   # the per-joint choice (preset auto)


def get_preset(name: str) -> Preset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ConfigError(f"preset {name!r} unknown (known: {', '.join(PRESETS)})") from None


def resolve_preset(spec, data: Prepared, name: str, folds: int = CV_FOLDS) -> PresetChoice:
    """The preset's model and weighting, with δ selected by blocked CV on ``data`` if the preset
    asks for it (identification data only)."""
    p = get_preset(name)
    model = p.model
    scores: tuple[CVScore, ...] = ()
    if p.select_friction:
        sel = select_friction(spec, data, model, folds)
        return PresetChoice(p.name, sel.model, p.weighting, (), sel)
    if p.select_dahl_rad:
        model, s = select_dahl_rad(spec, data, model, DAHL_GRID, p.weighting, "ols", folds)
        scores = tuple(s)
    return PresetChoice(p.name, replace(model), p.weighting, scores)
