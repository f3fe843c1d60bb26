"""Named identification configurations: ``paper`` (the paper's method), ``auto`` (also spelled
``real-robot`` and ``best``) and ``ur10e-2020``, and the one place a preset meets a caller's
explicit options (:func:`resolve_model`: the command line's flags and the API's keywords alike) and
what it leaves to the data (:func:`choose_on_data`).

``auto``: the reduced base set, per-joint weighting, a Dahl presliding Coulomb state (driven by
∫q̇, δ chosen by blocked CV) and each joint's friction terms chosen by blocked CV on the
identification data given (:mod:`urident.ident.friction_select`): the same procedure on any arm.
With those terms, the measured torque's lead over the motion is chosen by the same CV from
:data:`TORQUE_LEAD_GRID` (:func:`urident.ident.crossval.select_torque_lead`; 8 ms on the UR10e run).
Last, the acceleration filter's corner, by the same CV from :data:`ACCELERATION_CORNER_GRID`
(:func:`urident.ident.crossval.select_acceleration_corner`; 45 Hz on the UR10e run, whose torque
follows the arm's fast motion). ``PresetChoice.data`` is then the data to fit, and
``PresetChoice.preprocess_config`` the preprocessing recorded (lead and corner).
``real-robot`` and ``best`` name it since it predicted the UR10e's held-out recordings better than
the fixed set below (docs/friction-selection.md).

``paper``: full base set (52 parameters), r_v·q̇ + r_c·tanh(q̇/ε) friction with ε = 0.01 rad/s,
plain least squares (Kovincic et al. 2019).

``ur10e-2020`` (what ``real-robot`` meant before it named ``auto``; kept so that figures measured
with it can be reproduced): one fixed set of terms, the configuration that predicted the real UR10e
best in blocked 5-fold cross-validation *inside the identification run* (ur-20_02_10-30sec_12harm.csv rows 635-3510,
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

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from urident.errors import ConfigError
from urident.ident.crossval import CVScore, select_acceleration_corner, select_dahl_rad, select_torque_lead
from urident.ident.design import ModelConfig
from urident.ident.friction_select import DAHL_GRID, FrictionSelection, select_friction  # noqa: F401 (DAHL_GRID re-exported)
from urident.ident.preprocess import (PreprocessConfig, Prepared, sample_rate, with_acceleration_corner,
                                      with_torque_lead)

CV_FOLDS = 5
#: [s] leads of the measured torque over the motion that ``auto`` compares by blocked CV (the torque
#: at t paired with the motion at t + lead; negative: the torque lags)
TORQUE_LEAD_GRID = tuple(round(k * 0.002, 3) for k in range(-5, 6))
#: [Hz] corners of the acceleration filter that ``auto`` compares by blocked CV, those up to
#: :data:`MAX_CORNER_FRACTION` of the log's rate (the data's own corner, 10 Hz by default, is the base)
ACCELERATION_CORNER_GRID = (10.0, 15.0, 20.0, 30.0, 45.0, 70.0, 100.0, 150.0, 200.0)
MAX_CORNER_FRACTION = 0.45   # of the sample rate: below Nyquist with room for the bilinear transform


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
    "auto": Preset(
        "auto", ModelConfig(reduced=True, coulomb="dahl", dahl_source="velocity", dahl_rad=2e-4),
        "joint", False,
        "reduced base set, per-joint weighting, Dahl presliding Coulomb state driven by the "
        "integrated velocity, and each joint's friction terms (offset, asymmetry, sigmoid with "
        "offset, Stribeck, square-root/quadratic viscous, load-dependent Coulomb, Dahl, position "
        "harmonics), the Dahl distance, the torque's lead and the acceleration filter's corner "
        "chosen by 5-fold blocked CV on the identification data",
        select_friction=True),
    "ur10e-2020": Preset(
        "ur10e-2020",
        ModelConfig(reduced=True, coulomb="dahl", dahl_source="velocity", dahl_rad=2e-4,
                    extras=("load", "sqrtvisc", "stribeck"), stribeck_vs=0.05),
        "joint", True,
        "one fixed set of terms chosen on a UR10e's 2020 run (real-robot's meaning before it named "
        "auto): reduced base set, per-joint weighting, Dahl presliding Coulomb state driven by the "
        "integrated velocity (distance chosen by 5-fold blocked CV), load-dependent Coulomb, "
        "square-root viscous and Stribeck (v_s 0.05 rad/s) friction"),
}


#: Other names of presets: ``real-robot`` (and ``--model best``) is ``auto``, which predicted the
#: UR10e's held-out recordings better than the fixed set it named before (now ``ur10e-2020``).
PRESET_ALIASES = {"real-robot": "auto", "best": "auto"}
#: What a caller may set over a preset: ModelConfig fields, the weighting, and whether δ is
#: chosen by CV (``dahl_rad='auto'`` or ``select_dahl_rad=True``).
OVERRIDES = ("reduced", "friction_eps", "coulomb", "hold_velocity", "dahl_rad", "dahl_source", "extras",
             "stribeck_vs", "weighting", "select_dahl_rad")
#: What ``auto`` chooses itself from the data (setting it too is a conflict), in the order reported.
AUTO_CHOSEN = ("coulomb", "hold_velocity", "dahl_rad", "dahl_source", "extras", "stribeck_vs", "weighting",
               "select_dahl_rad")


@dataclass(frozen=True)
class ModelChoice:
    """A preset with a caller's explicit options applied, before any data are seen: the model and
    weighting to fit, and whether δ (``select_dahl_rad``) or each joint's friction terms
    (``select_friction``) are then chosen by blocked CV on the identification data."""

    preset: str | None       # the canonical preset name (aliases resolved), None without one
    model: ModelConfig
    weighting: str
    select_dahl_rad: bool = False
    select_friction: bool = False


def resolve_model(preset: str | None = None, overrides: Mapping[str, object] | None = None, *,
                  model: ModelConfig | None = None, names: Mapping[str, str] | None = None) -> ModelChoice:
    """The model of ``preset`` (or the paper's defaults) with ``overrides`` applied: keys of
    :data:`OVERRIDES`, None meaning not given. ``model``: a whole ModelConfig instead of the
    preset's (the overrides still apply). ``names``: how the caller spells each key and
    ``preset`` in its error messages (the command line's flags); default the keys themselves.
    ConfigError when an override conflicts with ``auto`` or asks for δ selection without a Dahl
    state."""
    given = {k: v for k, v in dict(overrides or {}).items() if v is not None}
    unknown = sorted(set(given) - set(OVERRIDES))
    if unknown:
        raise ConfigError(f"model option {unknown[0]!r} unknown (known: {', '.join(OVERRIDES)})")
    say = lambda key: dict(names or {}).get(key, key)  # noqa: E731
    name = PRESET_ALIASES.get(preset, preset) if preset else None
    p = get_preset(name) if name else None
    if p is not None and p.select_friction:
        clash = [k for k in AUTO_CHOSEN if k in given]
        if clash:
            spelled = name if preset == name else f"{preset} (= {name})"
            raise ConfigError(f"{say(clash[0])} conflicts with {say('preset')} {spelled}, which chooses the friction "
                              f"terms and weighting itself from the identification logs ({say('preset')} ur10e-2020: "
                              "a fixed set of terms that options can change)")
    base = model if model is not None else (p.model if p else ModelConfig())
    weighting = given.pop("weighting", None) or (p.weighting if p else "none")
    select = bool(p and p.select_dahl_rad)
    asked = None                 # the override that asked for δ selection, if one did
    dahl = given.pop("dahl_rad", None)
    if isinstance(dahl, str) and dahl == "auto":
        select, asked = True, "dahl_rad"
    elif dahl is not None:
        given["dahl_rad"], select = dahl, False
    if "select_dahl_rad" in given:
        select = bool(given.pop("select_dahl_rad"))
        asked = "select_dahl_rad" if select else None
    chosen = replace(base, **given)
    if select and not (chosen.coulomb == "dahl" or "dahl" in chosen.extras):
        if asked:
            raise ConfigError(f"{say(asked)}{' auto' if asked == 'dahl_rad' else ''} needs a Dahl state: "
                              f"{say('coulomb')} dahl or {say('extras')} dahl")
        select = False   # the preset's δ selection is moot once the Dahl state is overridden
    return ModelChoice(name, chosen, weighting, select, bool(p and p.select_friction))


@dataclass(frozen=True)
class PresetChoice:
    """A preset resolved on identification data: the model, the weighting and the CV scores of
    the δ grid (empty when δ was not selected)."""

    preset: str | None
    model: ModelConfig
    weighting: str
    cv_scores: tuple[CVScore, ...] = ()
    selection: FrictionSelection | None = None   # the per-joint choice (preset auto)
    folds: int = CV_FOLDS
    torque_lead_s: float = 0.0                   # [s] chosen by CV (preset auto), PreprocessConfig's
    lead_scores: tuple[CVScore, ...] = ()        # the CV scores of TORQUE_LEAD_GRID, in its order
    data: Prepared | None = field(default=None, repr=False, compare=False)   # the data to fit, with that lead and corner (None: as given)
    filter_hz: float | None = None               # [Hz] acceleration corner chosen by CV (preset auto); None: not chosen
    base_hz: float | None = None                 # [Hz] the corner the identification data were prepared with
    corner_grid: tuple[float, ...] = ()          # the corners compared
    corner_scores: tuple[CVScore, ...] = ()      # their CV scores, in that order

    def apply(self, data: Prepared, prewarp: bool = True) -> Prepared:
        """``data`` (prepared as the identification data were) with the chosen lead and corner."""
        data = with_torque_lead(data, self.torque_lead_s)
        if self.filter_hz is None or self.filter_hz == self.base_hz:
            return data
        return with_acceleration_corner(data, self.filter_hz, prewarp)

    def preprocess_config(self, config: PreprocessConfig) -> PreprocessConfig:
        """``config`` (the identification data's preprocessing) with what was chosen on the data:
        the torque lead added, the acceleration corner set; what predicting with the model needs."""
        return replace(config, torque_lead_s=round(config.torque_lead_s + self.torque_lead_s, 6),
                       filter_hz=config.filter_hz if self.filter_hz is None else self.filter_hz)

    def text(self) -> str:
        """What was chosen on the data, for the report ('' when nothing was)."""
        if self.selection is not None:
            return self.lead_text() + self.corner_text() + self.selection.text()
        if not self.cv_scores:
            return ""
        return (f"dahl_rad selected by {self.folds}-fold blocked CV on the identification data: "
                f"{self.model.dahl_rad:g} rad (mean held-out RMS [N·m] per distance: "
                + ", ".join(f"{s.model.dahl_rad:g}: {s.mean_rms_nm:.3f}" for s in self.cv_scores) + ")")

    def lead_text(self) -> str:
        if not self.lead_scores:
            return ""
        return (f"torque lead over the motion chosen by {self.folds}-fold blocked CV of the chosen model: "
                f"{1000 * self.torque_lead_s:g} ms (the torque at t paired with the motion at t + lead; mean "
                "held-out RMS [N·m] per lead [ms]: "
                + ", ".join(f"{1000 * s:g}: {c.mean_rms_nm:.3f}" for s, c in zip(TORQUE_LEAD_GRID, self.lead_scores))
                + ")\n")

    def corner_text(self) -> str:
        if not self.corner_scores:
            return ""
        kept = " (the data's own: no other lowers it by 0.5 %)" if self.filter_hz == self.base_hz else ""
        return (f"acceleration filter corner chosen by {self.folds}-fold blocked CV of the chosen model: "
                f"{self.filter_hz:g} Hz{kept} (mean held-out RMS [N·m] per corner [Hz]: "
                + ", ".join(f"{f:g}: {c.mean_rms_nm:.3f}" for f, c in zip(self.corner_grid, self.corner_scores))
                + ")\n")


def corner_grid(data: Prepared, base_hz: float) -> tuple[float, ...]:
    """The corners ``auto`` compares on ``data``: the base and those of
    :data:`ACCELERATION_CORNER_GRID` up to :data:`MAX_CORNER_FRACTION` of the slowest segment's rate."""
    rate = min(sample_rate(data.t[data.segment == s]) for s in np.unique(data.segment))
    return tuple(sorted({float(base_hz), *(f for f in ACCELERATION_CORNER_GRID if f <= MAX_CORNER_FRACTION * rate)}))


def get_preset(name: str) -> Preset:
    try:
        return PRESETS[PRESET_ALIASES.get(name, name)]
    except KeyError:
        raise ConfigError(f"preset {name!r} unknown (known: {', '.join([*PRESETS, *PRESET_ALIASES])})") from None


def choose_on_data(spec, data: Prepared, choice: ModelChoice, folds: int = CV_FOLDS,
                   config: PreprocessConfig | None = None, select_corner: bool = True) -> PresetChoice:
    """What ``choice`` leaves to the identification data, chosen by blocked CV on ``data``: each
    joint's friction terms, the torque's lead and the acceleration filter's corner (``auto``;
    ``config``: the preprocessing ``data`` had, default :class:`PreprocessConfig`'s; the corner
    only with ``select_corner`` and undecimated data) or δ from :data:`DAHL_GRID`; else ``choice``
    as it is."""
    if choice.select_friction:
        config = config or PreprocessConfig()
        sel = select_friction(spec, data, choice.model, folds)
        lead, scores = select_torque_lead(spec, data, sel.model, TORQUE_LEAD_GRID, choice.weighting, "ols", folds)
        out = PresetChoice(choice.preset, sel.model, choice.weighting, (), sel, folds, lead, tuple(scores))
        if select_corner and config.decimate == 1:   # decimated data no longer hold the rate the filter ran at
            grid = corner_grid(data, config.filter_hz)
            corner, corner_scores = select_acceleration_corner(
                spec, out.apply(data), sel.model, grid, config.filter_hz, choice.weighting, "ols", folds, config.prewarp)
            out = replace(out, filter_hz=corner, base_hz=float(config.filter_hz), corner_grid=grid,
                          corner_scores=tuple(corner_scores))
        changed = out.torque_lead_s or out.filter_hz != out.base_hz
        return replace(out, data=out.apply(data, config.prewarp) if changed else None)
    if choice.select_dahl_rad:
        model, scores = select_dahl_rad(spec, data, choice.model, DAHL_GRID, choice.weighting, "ols", folds)
        return PresetChoice(choice.preset, model, choice.weighting, tuple(scores), None, folds)
    return PresetChoice(choice.preset, choice.model, choice.weighting, (), None, folds)


def resolve_preset(spec, data: Prepared, name: str, folds: int = CV_FOLDS) -> PresetChoice:
    """The preset's model and weighting, with δ or the friction terms selected by blocked CV on
    ``data`` if the preset asks for it (identification data only)."""
    return choose_on_data(spec, data, resolve_model(name), folds)
