"""Pure pieces of the gap diagnosis: maps, angle spectrum, bootstrap, candidate columns."""

from __future__ import annotations

import numpy as np
import pytest

from urident.gap import maps
from urident.gap.bootstrap import block_bootstrap_means, interval


def test_velocity_map_puts_near_zero_energy_in_its_band(rng):
    qd = rng.uniform(-1, 1, 5000)
    r = rng.normal(0, 0.1, 5000) + 2.0 * (np.abs(qd) < 0.02)
    bins = maps.velocity_map(r, qd)
    band = bins[0]
    assert band.label.startswith("|q̇| < 0.02")
    assert band.sample_share == pytest.approx(0.02, abs=0.01)
    assert band.energy_share > 0.8
    assert sum(b.sample_share for b in bins) == pytest.approx(1.0)
    assert sum(b.energy_share for b in bins) == pytest.approx(1.0)
    reg = maps.concentrated_regimes(1, {"velocity": bins})
    assert reg and reg[0].axis == "velocity" and reg[0].text().startswith("joint 2: ")
    assert "which holds 2 % of the samples" in reg[0].text()


def test_no_regime_when_the_residual_is_white(rng):
    qd = rng.uniform(-1, 1, 5000)
    q = np.cumsum(qd) * 0.01
    r = rng.normal(0, 0.1, 5000)
    found = maps.concentrated_regimes(0, maps.joint_maps(r, qd, rng.normal(size=5000), q,
                                                         np.arange(5000) * 0.01))
    assert found == []


@pytest.mark.parametrize("k", [3, 37, 101])
def test_angle_spectrum_finds_a_gear_harmonic(rng, k):
    t = np.linspace(0, 60, 30000)
    q = 0.8 * np.sin(0.3 * t) + 0.3 * np.sin(1.1 * t)
    qd = np.gradient(q, t)
    r = 0.3 * np.sin(k * q + 0.4) + rng.normal(0, 0.2, len(t))
    spec = maps.angle_spectrum(r, q, qd)
    assert spec.peaks(1)[0] == k
    assert spec.amplitude[k - 1] == pytest.approx(0.3, rel=0.35)


def test_angle_spectrum_friction_mode(rng):
    t = np.linspace(0, 60, 30000)
    q = 0.8 * np.sin(0.5 * t)
    qd = np.gradient(q, t)
    r = 0.3 * np.sin(50 * q) * np.tanh(qd / 0.01) + rng.normal(0, 0.1, len(t))
    spec = maps.angle_spectrum(r, q, qd)
    assert spec.peaks(1, friction=True)[0] == 50
    assert spec.amplitude_friction[49] > 3 * spec.amplitude[49]


def test_frequency_map_recovers_a_delay(rng):
    t = np.arange(0, 30, 0.004)
    tau = 20 * np.sin(2 * t) + 5 * np.sin(7 * t)
    dtau = np.gradient(tau, t)
    d = 0.006
    r = np.interp(t - d, t, tau) - tau + rng.normal(0, 0.05, len(t))
    fm = maps.frequency_map(r, 250.0, dtau)
    assert fm.delay_s == pytest.approx(d, rel=0.1)
    assert fm.corr_dtau < -0.9


def test_block_bootstrap_interval_covers_the_mean_and_widens_with_correlation(rng):
    white = rng.normal(1.0, 1.0, 4000)
    lo, hi = interval(block_bootstrap_means(white, 40, 500, 1))
    assert lo < 1.0 < hi and hi - lo < 0.15
    walk = 1.0 + np.repeat(rng.normal(0, 1.0, 40), 100)      # strongly correlated in blocks of 100
    lo2, hi2 = interval(block_bootstrap_means(walk, 100, 500, 1))
    assert hi2 - lo2 > 3 * (hi - lo)
    both = block_bootstrap_means(np.c_[white, walk], 100, 200, 2)
    assert both.shape == (200, 2)


def test_effect_names_are_the_catalogue_s():
    from urident.gap.candidates import DIAGNOSIS_ONLY, EFFECTS
    from urident.simcontroller.effects import EFFECT_NAMES

    assert EFFECTS == EFFECT_NAMES + DIAGNOSIS_ONLY
    assert not set(DIAGNOSIS_ONLY) & set(EFFECT_NAMES)


def test_implausible_fits_are_not_findings():
    """Sign/size constraints of the catalogue's physics on fitted coefficients."""
    from urident.gap.candidates import current_delay, current_offset, load_friction, stribeck
    from urident.gap.significance import MIN_PAYLOAD_KG, plausible

    assert plausible(stribeck(1, 0.02), np.array([0.5]))
    assert not plausible(stribeck(1, 0.02), np.array([-0.5]))     # less friction at rest
    assert not plausible(load_friction(0), np.array([-0.01]))
    assert plausible(current_delay(2), np.array([-0.004]))        # coefficient −d, d > 0
    assert not plausible(current_delay(2), np.array([0.004]))
    assert plausible(current_offset(3), np.array([-0.3]))         # either sign

    class _Payload:
        effect = "payload_error"

    assert plausible(_Payload, np.array([1.0, 0.01, 0.0, 0.05]))
    assert plausible(_Payload, np.array([-1.0, 0.0, 0.0, 0.0]))    # a modelled payload removed
    assert not plausible(_Payload, np.array([MIN_PAYLOAD_KG / 2, 0.0, 0.0, 0.0]))
    assert not plausible(_Payload, np.array([0.2, 0.5, 0.0, 0.0]))  # centre 2.5 m away


def test_payload_joint_is_the_largest_share_of_the_joint_torque():
    from urident.gap.significance import main_joint

    tau = np.ones((50, 6)) * np.array([10.0, 100.0, 50.0, 2.0, 2.0, 1.0])
    change = np.ones((50, 6)) * np.array([0.0, 8.0, 5.0, 0.4, 0.1, 0.05])
    assert main_joint(change, tau) == 3          # 20 % of joint 4's torque beats 8 % of joint 2's


def test_noise_sigma_sees_the_white_noise_not_the_slow_structure(rng):
    from urident.gap.significance import noise_sigma

    t = np.arange(4000) / 200.0
    r = rng.normal(0, 0.17, (len(t), 6))
    r[:, 2] += 1.5 * np.sin(0.5 * t) + 0.8          # slow structure and an offset on joint 3
    sigma = noise_sigma(r)
    assert sigma == pytest.approx(np.full(6, 0.17), rel=0.1)


def test_cv_findings_need_a_correction_above_the_noise_floor():
    from urident.gap.significance import material_cv

    sigma = 0.17
    assert not material_cv(np.full(100, 0.043), sigma, 0.5)   # a 5 mA offset on joint 3: 0.25 σ
    assert material_cv(np.full(100, 0.5), sigma, 0.5)         # a 60 mA offset: ~3 σ
    assert material_cv(np.full(100, 0.01), sigma, 0.0)        # floor off
