"""The presliding candidate (diagnosis only): found where a Dahl holding friction is truly in the
data, not named where there is none, and no simulator effect."""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from test_gap_diagnose import FAST, simulate
from urident.gap import candidates as C
from urident.gap import diagnose
from urident.model import load_robot


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur10e")


_GB = Path(__file__).resolve().parent.parent / "benchmarks" / "gap_blind.py"


def _ptp(seed: int, duration: float):
    """A point-to-point run with stops and slow moves (benchmarks/gap_blind.py's)."""
    mod = sys.modules.get("gap_blind")
    if mod is None:
        s = importlib.util.spec_from_file_location("gap_blind", _GB)
        mod = importlib.util.module_from_spec(s)
        sys.modules["gap_blind"] = mod
        s.loader.exec_module(mod)
    return mod.random_ptp(np.random.default_rng(seed), duration)


def _with_presliding(spec, rec, joint: int, holding_nm: float, delta: float):
    """``rec`` with a Dahl holding friction F·(z − tanh(q̇/ε)) added to one joint's current."""
    from urident.ident.friction import dahl_state, velocity_displacement

    if holding_nm == 0:
        return rec
    z = dahl_state(velocity_displacement(rec.t, rec.qd), delta)
    extra = holding_nm * (z[:, joint] - np.tanh(rec.qd[:, joint] / 0.01))
    current = rec.current.copy()
    current[:, joint] += extra / spec.drive_gains[joint]
    return dataclasses.replace(rec, current=current)


def _presliding_pair(spec, holding_nm: float):
    ident = simulate(spec, _ptp(21, 30.0), None, 4)
    valid = simulate(spec, _ptp(22, 30.0), None, 5)
    return [_with_presliding(spec, r, 4, holding_nm, 1e-3) for r in (ident, valid)]


def test_holding_friction_before_a_stop_is_found_as_presliding(spec):
    ident, valid = _presliding_pair(spec, 1.5)
    res = diagnose([ident], [valid], spec, config=FAST)
    first = res.findings[0]
    assert (first.effect, first.joint) == ("presliding", 5), res.verdict
    assert first.magnitude["holding_friction_nm"] == pytest.approx(1.5, rel=0.2)
    assert first.shrink_pct > 30


def test_no_presliding_is_named_where_there_is_none(spec):
    ident, valid = _presliding_pair(spec, 0.0)
    res = diagnose([ident], [valid], spec, config=FAST)
    assert not any(f.effect == "presliding" for f in res.findings), res.verdict


def test_presliding_is_not_a_simulator_effect_nor_expressible():
    from urident.gap.sim_baseline import EXPRESSIBLE
    from urident.simcontroller.effects import EFFECT_NAMES

    assert "presliding" in C.EFFECTS and "presliding" not in EFFECT_NAMES
    assert all("presliding" not in names for names in EXPRESSIBLE.values())
