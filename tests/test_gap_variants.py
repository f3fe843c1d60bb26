"""The choice of a family's variant (urident.gap.significance.choose_variant): a ripple harmonic the
identification run's angle span cannot resolve is chosen by the validation fit, a resolved one by
the identification fit; a later finding that a friction curve free per velocity bin explains as
well; a Stribeck term of an offset's sign."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from urident.gap.candidates import position_ripple
from urident.gap.significance import choose_variant, unresolved_harmonics


def _family(j=4):
    return [position_ripple(j, k, "torque") for k in (2, 3, 4, 8)]


def _q(span):
    q = np.zeros((200, 6))
    q[:, 4] = np.linspace(0.0, span, 200)
    return q


def test_unresolved_harmonics_follow_the_angle_span():
    fam = _family()
    best = fam[1]                                        # k = 3
    short = unresolved_harmonics(fam, best, _q(1.5)[:, 4])          # 2π/1.5 ≈ 4.2: k 2, 3, 4
    assert [c.settings["k"] for c in short] == [2, 3, 4]
    long_ = unresolved_harmonics(fam, best, _q(2 * np.pi * 1.5)[:, 4])   # |Δk| < 0.67: k 3 alone
    assert [c.settings["k"] for c in long_] == [3]
    assert unresolved_harmonics(fam, best, np.zeros(10)) == [best]        # a joint at rest: no span


class _Scorer:
    """The two fits choose_variant reads: identification gains favour k = 3, validation k = 2."""

    def __init__(self, span):
        self.ident = SimpleNamespace(q=_q(span))
        self.valid = SimpleNamespace(residual=np.ones((200, 6)))
        self.train = {2: 38.0, 3: 41.7, 4: 38.3, 8: 2.0}
        self.valid_gain = {2: 76.0, 3: 62.0, 4: 67.0, 8: 1.0}

    def training_gain(self, c):
        return self.train[c.settings["k"]]

    def held_out_gains(self, variants, j, r):
        assert j == 4 and r.shape == (200,)
        return np.array([self.valid_gain[c.settings["k"]] for c in variants])


def test_choose_variant_asks_the_validation_run_only_when_unresolved():
    fam = _family()
    assert choose_variant(fam, _Scorer(1.5)).settings["k"] == 2          # unresolved: validation
    assert choose_variant(fam, _Scorer(4 * np.pi)).settings["k"] == 3    # resolved: identification


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
