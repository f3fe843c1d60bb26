"""The measured torque's lead over the motion, chosen by ``--preset auto`` and applied by validate."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import urident as ur
from urident.errors import ConfigError
from urident.ident import PreprocessConfig, load_params, prepare, resolve_preset, save_params
from urident.ident.preprocess import lead_motion
from urident.ident.synthetic import random_multisine, synthetic_recording
from urident.model import load_robot

LEAD = 0.006   # [s]


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


def run(spec, seed: int, lead: float):
    """A 10 s, 125 Hz multi-sine run whose currents lead its logged motion by ``lead`` [s]."""
    traj = random_multisine(spec, np.random.default_rng(seed))
    rec, _, _ = synthetic_recording(spec, 10.0, 125.0, current_noise_a=0.02, seed=seed, trajectory=traj)
    q, qd, _ = traj(rec.t - lead)
    return replace(rec, q=q, qd=qd)


def test_lead_motion_pairs_the_torque_with_later_motion():
    t = np.r_[np.arange(0, 1, 0.01), np.arange(0, 0.5, 0.01)]
    x = np.column_stack([t, 2 * t])
    seg = np.r_[np.zeros(100, int), np.ones(50, int)]
    out = lead_motion(t, x, 0.02, seg)
    np.testing.assert_allclose(out[:98], x[2:100])       # two samples later, inside each segment
    np.testing.assert_allclose(out[98:100], x[[99, 99]])  # held at the segment's end, never the next one's
    np.testing.assert_allclose(out[100:148], x[102:150])
    with pytest.raises(ConfigError, match="torque_lead_s"):
        PreprocessConfig(torque_lead_s=0.2)


def test_auto_finds_the_lead_and_validate_applies_it(spec, tmp_path):
    plain = resolve_preset(spec, prepare([run(spec, 5, 0.0)], spec), "auto")
    assert plain.torque_lead_s == 0.0 and plain.data is None
    assert "torque lead over the motion chosen by 5-fold blocked CV" in plain.text()

    ident = ur.identify([run(spec, 5, LEAD)], "ur5", "ols", preset="auto")
    assert ident.model.preprocess.torque_lead_s == pytest.approx(LEAD, abs=0.0021)
    assert "torque lead over the motion" in ident.report
    path = tmp_path / "p.yaml"
    save_params(ident.model, path)
    loaded = load_params(path)
    assert loaded.preprocess.torque_lead_s == ident.model.preprocess.torque_lead_s
    other = run(spec, 6, LEAD)   # another run of the same arm: validate pairs it as identified
    with_lead = ur.validate(loaded, [other]).rms_nm
    without = ur.validate(replace(loaded, preprocess=replace(loaded.preprocess, torque_lead_s=0.0)), [other]).rms_nm
    assert np.mean(with_lead) < 0.8 * np.mean(without)
