"""The unmodelled-effects catalogue, shared by the simulated controller and offline simulation.

Each effect has a stable snake_case name (the gap diagnosis reports these names):

* ``stribeck``: static (Stribeck) friction near zero velocity;
* ``load_friction``: friction proportional to the load torque;
* ``thermal_drift``: viscous/Coulomb friction drifting as the joints warm up;
* ``position_ripple``: torque ripple or friction at a gear harmonic, A·sin(k·q + φ);
* ``current_delay``: the reported current lags by d seconds;
* ``torque_constant_error``: the true drive gain differs from the robot file's;
* ``current_offset``: constant offset of the measured current;
* ``payload_error``: an unmodelled point mass at the tool;
* ``joint_elasticity``: finite joint stiffness (link lags motor, filtered spring torque);
* ``quadratic_viscous``: friction growing with the square of the speed;
* ``neighbour_load_friction``: bearing friction driven by a neighbour joint's load;
* ``asymmetric_coulomb``: a Coulomb level that differs by direction;
* ``current_lag``: the reported current through a first-order lag 1/(τs + 1).

An effects file (YAML, see :mod:`.config`) enables effects per joint with their magnitudes;
:func:`load_effects` turns a file or a preset name (``realistic``) into an :class:`EffectSet`
whose ``extra_torque``/``measure_current`` are the :class:`~urident.simcontroller.plant.Plant`
hooks and whose ``offline_*`` methods are the same on whole runs. :func:`catalogue` lists every
effect with its parameters and defaults.
"""

from urident.simcontroller.effects.base import Effect, EffectContext, EffectUsageError
from urident.simcontroller.effects.catalogue import (
    APPLY_ORDER,
    EFFECT_NAMES,
    CatalogueEntry,
    catalogue,
    format_catalogue,
)
from urident.simcontroller.effects.config import (
    EffectConfig,
    EffectsConfig,
    available_presets,
    parse_effects,
    parse_effects_text,
)
from urident.simcontroller.effects.dynamics import payload_params
from urident.simcontroller.effects.effectset import EffectSet, load_effects

__all__ = [
    "APPLY_ORDER",
    "EFFECT_NAMES",
    "CatalogueEntry",
    "Effect",
    "EffectConfig",
    "EffectContext",
    "EffectSet",
    "EffectUsageError",
    "EffectsConfig",
    "available_presets",
    "catalogue",
    "format_catalogue",
    "load_effects",
    "parse_effects",
    "parse_effects_text",
    "payload_params",
]
