"""Presets and explicit model options resolved in one place (urident.ident.presets.resolve_model),
for the command line and the API alike."""

from __future__ import annotations

import re

import pytest

from urident.cli.cmd_identify import OPTION_FLAGS
from urident.errors import ConfigError
from urident.ident import ModelConfig
from urident.ident.presets import PRESETS, resolve_model


def test_presets_and_overrides():
    # real-robot and --model best are auto: each joint's terms chosen on the data, not a fixed set
    for alias in ("best", "real-robot"):
        assert resolve_model(alias) == resolve_model("auto")
    auto = resolve_model("auto")
    assert auto.preset == "auto" and auto.select_friction and not auto.model.extras
    fixed_set = resolve_model("ur10e-2020")
    assert fixed_set.model == PRESETS["ur10e-2020"].model and set(fixed_set.model.extras) == {"load", "sqrtvisc", "stribeck"}
    assert fixed_set.weighting == "joint" and fixed_set.select_dahl_rad and not fixed_set.select_friction
    plain = resolve_model(None)
    assert plain == resolve_model(None, {k: None for k in OPTION_FLAGS if k != "preset"})
    assert plain.model == ModelConfig() and plain.weighting == "none" and not plain.select_dahl_rad
    # a distance given fixes δ; a tanh state makes the preset's δ selection moot
    fixed = resolve_model("ur10e-2020", {"dahl_rad": 1e-4})
    assert fixed.model.dahl_rad == 1e-4 and not fixed.select_dahl_rad
    assert not resolve_model("ur10e-2020", {"coulomb": "tanh"}).select_dahl_rad
    chosen = resolve_model(None, {"coulomb": "dahl", "dahl_rad": "auto", "extras": ("load",), "reduced": True})
    assert chosen.select_dahl_rad and chosen.model.extras == ("load",) and chosen.model.reduced
    auto = resolve_model("auto", {"reduced": False, "friction_eps": 0.02})
    assert auto.select_friction and auto.weighting == "joint"
    assert auto.model == ModelConfig(reduced=False, friction_eps=0.02, coulomb="dahl", dahl_source="velocity",
                                     dahl_rad=2e-4)
    given = ModelConfig(coulomb="hold")
    assert resolve_model("paper", {"weighting": "joint"}, model=given).model == given


@pytest.mark.parametrize("preset, overrides, names, message", [
    ("auto", {"extras": ("load",)}, OPTION_FLAGS, "--friction-extra conflicts with --preset auto"),
    ("auto", {"weighting": "none"}, None, "weighting conflicts with preset auto"),
    ("auto", {"select_dahl_rad": True}, None, "select_dahl_rad conflicts with preset auto"),
    (None, {"dahl_rad": "auto"}, OPTION_FLAGS, "--dahl-rad auto needs a Dahl state: --coulomb dahl or --friction-extra dahl"),
    (None, {"select_dahl_rad": True}, None, "select_dahl_rad needs a Dahl state"),
    (None, {"colomb": "dahl"}, None, "model option 'colomb' unknown"),
    ("real-robot", {"weighting": "none"}, OPTION_FLAGS,
     "--weighting conflicts with --preset real-robot (= auto), which chooses the friction terms and weighting "
     "itself from the identification logs (--preset ur10e-2020: a fixed set of terms that options can change)"),
    ("fast", {}, None, "preset 'fast' unknown (known: paper, auto, ur10e-2020, real-robot, best)"),
])
def test_conflicts_and_unknowns_are_named_as_the_caller_spells_them(preset, overrides, names, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        resolve_model(preset, overrides, names=names)


def test_the_command_lines_preset_names_are_the_presets_and_their_aliases():
    from urident.cli.cmd_identify import PRESET_NAMES
    from urident.ident.presets import PRESET_ALIASES

    assert PRESET_NAMES == (*PRESETS, *PRESET_ALIASES)
    assert all(target in PRESETS for target in PRESET_ALIASES.values())
