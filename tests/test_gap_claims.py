"""Claims and plausibility beside a friction finding or an offset: a later finding that a friction
curve free per velocity bin explains as well; a Stribeck term of an offset's sign."""

from __future__ import annotations

import numpy as np


def test_a_friction_curve_free_per_velocity_bin_mends_a_later_finding():
    from urident.gap.structure import misfit_of

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 60.0, 3000)
    v = np.sin(t) * np.linspace(1.0, 0.3, len(t))        # faster early: velocity and time correlate
    bins = np.digitize(v, np.quantile(v, np.linspace(0, 1, 14)[1:-1]))
    r = 0.5 * v * np.abs(v) + 0.05 * rng.standard_normal(len(t))      # a friction curve left over
    drift = np.exp(-t / 15.0) * v                                      # a warm-up stands in for it
    bump = np.exp(-(v / 0.02) ** 2)                                    # an earlier finding, zero at speed
    assert misfit_of(drift, r, [("presliding", bump)], bins, 0.05) is None
    m = misfit_of(drift, r, [("presliding", bump), ("presliding", None)], bins, 0.05)
    assert m is not None and m["of"] == "presliding" and m["scaled_pct"] > m["own_pct"]
    assert misfit_of(np.sin(40 * t), np.sin(40 * t), [("presliding", None)], bins, 0.05) is None


def test_a_stribeck_term_may_take_the_sign_of_an_offset_on_its_joint():
    from urident.gap.candidates import stribeck
    from urident.gap.significance import plausible

    c = stribeck(2, 0.005)
    assert plausible(c, np.array([0.8])) and not plausible(c, np.array([-0.8]))
    assert plausible(c, np.array([-0.8]), offset=-1.7)        # a Coulomb level lower one way
    assert not plausible(c, np.array([-0.8]), offset=1.7)
