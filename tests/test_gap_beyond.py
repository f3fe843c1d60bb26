"""Gap diagnosis beyond its catalogue: time-localised events, structure left in the residual, and
a JSON report with no NaN, None or infinity (validated against the shipped schema)."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest

from urident.gap.events import find_events, without_events
from urident.gap.results import json_safe
from urident.gap.schema import errors, report_schema
from urident.gap.structure import angle_harmonics, angle_nyquist, linear_dependence, time_localised

FS = 100.0


def test_json_safe_leaves_out_what_cannot_be_computed_and_says_why():
    doc = json_safe({"a": 1.0, "gain_factor": float("nan"), "b": None, "s": [1.0, None, np.inf],
                     "nested": {"hi": np.inf}})
    assert doc["a"] == 1.0 and "gain_factor" not in doc and "b" not in doc
    assert "no positive gain" in doc["absent"]["gain_factor"] and doc["absent"]["b"]
    assert doc["s"] == {"1": 1.0} and set(doc["absent"]) >= {"s[2]", "s[3]"}
    assert "hi" not in doc["nested"] and "unbounded" in doc["nested"]["absent"]["hi"]
    json.dumps(doc, allow_nan=False)
    with pytest.raises(ValueError):
        json_safe([float("nan")])


def test_the_validator_rejects_null_nan_and_missing_keys():
    schema = report_schema()
    assert errors({}, schema)                   # every required key missing
    s = {"type": "object", "required": ["x"], "properties": {"x": {"type": "number"}},
         "additionalProperties": {"$ref": "#/definitions/v"},
         "definitions": {"v": {"type": ["number", "string", "object", "array", "boolean"],
                               "items": {"$ref": "#/definitions/v"}}}}
    assert errors({"x": 1.0, "y": ["a", 2]}, s) == []
    assert errors({"x": float("nan")}, s) and errors({"x": None}, s) and errors({"x": 1, "y": [None]}, s)


def _bumps(n, pushes, joints=(1,), height=30.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    r = rng.normal(0, 0.3, (n, 6)) + 2.0 * np.sin(0.7 * t)[:, None]     # noise and a smooth misfit
    for a, b in pushes:
        w = (t >= a) & (t < b)
        for j in joints:
            r[w, j] += height * np.sin(np.pi * (t[w] - a) / (b - a))
    return t, r


def test_events_cover_each_push_and_nothing_on_a_smooth_residual():
    t, r = _bumps(3000, [(5.0, 6.2), (14.0, 15.0), (22.0, 22.8)], joints=(1, 2))
    ev = find_events(r, t, np.zeros_like(r), FS)
    assert len(ev) == 3
    for e, (a, b) in zip(ev, [(5.0, 6.2), (14.0, 15.0), (22.0, 22.8)]):
        assert a - 0.2 <= e.t_start_s and e.t_end_s <= b + 0.2 and (e.t_end_s - e.t_start_s) > 0.5 * (b - a)
        assert set(e.joints) == {1, 2} and e.kind == "external_contact"
        assert max(abs(p) for p in e.peak_nm) > 20
    t, r = _bumps(3000, [])
    assert find_events(r, t, np.zeros_like(r), FS) == []
    # a spike of a few samples at each reversal (a delay, Stribeck) is no event
    r[::300, 0] += 5.0
    r[1::300, 0] += 5.0
    assert find_events(r, t, np.zeros_like(r), FS) == []


def test_an_event_ends_with_its_push_when_the_push_leaves_a_new_hold_level():
    """A held joint's friction keeps the pose a push leaves: the residual settles ~10 N·m off its
    earlier level. The event ends where the residual settles (the level is taken without the
    flagged samples), within a few samples of the push, and two pushes stay two events."""
    rng = np.random.default_rng(3)
    t = np.arange(3000) / FS
    r = rng.normal(0, 0.3, (3000, 6)) + 2.0 * np.sin(0.7 * t)[:, None]
    pushes = [(5.0, 6.5, 60.0), (7.0, 8.2, 60.0), (18.0, 19.0, -40.0)]
    level = np.zeros(3000)
    for a, b, h in pushes:
        r[:, 1] += h * np.clip((t - a) / 0.3, 0, 1) * np.clip((b - t) / 0.2, 0, 1)
        level[t >= b] = -10.0 * np.sign(h)
    ev = find_events(r + level[:, None] * (np.arange(6) == 1), t, np.zeros_like(r), FS)
    assert len(ev) == 3
    for e, (a, b, _) in zip(ev, pushes):
        assert abs(e.t_start_s - a) <= 0.05 and abs(e.t_end_s - b) <= 0.05, (e.t_start_s, e.t_end_s)


def test_without_events_splits_the_segments():
    from test_gap_diagnose import simulate, sines
    from urident.gap.data import build_set
    from urident.model import load_robot

    spec = load_robot("ur10e")
    data = build_set([simulate(spec, sines(5, duration=6.0), None, seed=5)], spec)
    t = data.run_time
    r = np.zeros((len(t), 6))
    r[(t > 2.0) & (t < 3.0), 2] = 50.0
    r += np.random.default_rng(1).normal(0, 0.2, r.shape)
    ev = find_events(r, t, data.prepared.qd, data.sample_rate)
    assert len(ev) == 1 and ev[0].joints == (2,)
    sub = without_events(data, ev)
    assert len(sub) == len(data) - (ev[0].stop - ev[0].start)
    assert len(np.unique(sub.prepared.segment)) == 2 and len(sub.run_time) == len(sub)


def test_structure_a_white_noise_level_test_misses():
    rng = np.random.default_rng(3)
    n = 20000
    t = np.arange(n) / 500.0
    q = 0.8 * np.sin(0.5 * t)
    qd = 0.4 * np.cos(0.5 * t)
    sign = np.tanh(qd / 0.01)
    noise = rng.normal(0, 0.2, n)
    assert angle_nyquist(qd, 500.0) >= 202
    ripple = 0.15 * np.sin(202 * q + 0.3)
    found = angle_harmonics(noise + ripple, q, qd, 500.0, sign)
    assert found and found[0]["k"] == 202 and found[0]["mode"] == "torque"
    assert abs(found[0]["fitted_rms_nm"] - 0.15 / np.sqrt(2)) < 0.02
    assert angle_harmonics(noise, q, qd, 500.0, sign) == []
    lin = {f["signal"]: f for f in linear_dependence(noise + 3.0 * qd * np.abs(qd), {"v": qd, "time": t})}
    assert abs(lin["v"]["correlation"]) > 0.5 and abs(lin["time"]["correlation"]) < 0.1
    burst = noise.copy()
    w = (t > 10) & (t < 12)
    burst[w] += rng.normal(0, 1.0, int(w.sum()))
    loc = time_localised(burst, t, 500.0)
    assert len(loc) == 1 and 9.9 <= loc[0]["t_start_s"] and loc[0]["t_end_s"] <= 12.1
    assert time_localised(noise, t, 500.0) == []


def test_a_pushed_validation_run_reports_the_push_names_nothing_and_its_json_conforms(tmp_path):
    """An effect-free arm pushed for a second on joints 2-3: one external_contact event, its
    samples set aside, no effect named; the JSON conforms to the schema (no NaN, None)."""
    from test_gap_diagnose import FAST, simulate, sines
    from urident.gap import diagnose, format_report
    from urident.model import load_robot

    spec = load_robot("ur10e")
    ident = simulate(spec, sines(1), None, seed=11)
    valid = simulate(spec, sines(2), None, seed=12)
    t = valid.t
    w = (t > 8.0) & (t < 9.0)
    push = np.zeros_like(valid.current)
    push[w, 1] = 3.0 * np.sin(np.pi * (t[w] - 8.0))
    push[w, 2] = -2.0 * np.sin(np.pi * (t[w] - 8.0))
    from dataclasses import replace

    pushed = replace(valid, current=valid.current + push)
    res = diagnose([ident], [pushed], spec, config=FAST)
    assert len(res.events) == 1, format_report(res)
    e = res.events[0]
    assert 7.8 <= e.t_start_s <= 8.3 and 8.7 <= e.t_end_s <= 9.2 and set(e.joints) == {1, 2}
    assert res.findings == [], format_report(res)
    doc = json.loads(json.dumps(res.as_dict(), allow_nan=False))
    assert errors(doc) == []
    assert doc["events"][0]["kind"] == "external_contact"
    assert doc["events_summary"]["n_samples_set_aside"] == e.stop - e.start
    assert "Events" in format_report(res)
    jsonschema.validate(doc, report_schema())


def test_a_finding_whose_form_the_residual_contradicts_is_a_partial_explanation():
    """After a Stribeck-like finding, a residual that still grows with speed (quadratic drag the
    baseline's linear viscous term only partly takes) is left along the joint's velocity: the
    finding is a partial explanation; white noise leaves nothing."""
    from types import SimpleNamespace

    from urident.gap.structure import form_left

    rng = np.random.default_rng(4)
    n = 6000
    t = np.arange(n) / 200.0
    qd = np.zeros((n, 6))
    qd[:, 1] = 1.2 * np.sin(0.6 * t)
    ctx = SimpleNamespace(qd=qd, tau_hat=np.zeros((n, 6)), n=n, data=SimpleNamespace(run_time=t))
    drag = 3.0 * qd[:, 1] * np.abs(qd[:, 1])
    drag -= qd[:, 1] * (qd[:, 1] @ drag) / (qd[:, 1] @ qd[:, 1])     # the baseline's viscous share
    noise = rng.normal(0, 0.3, n)
    left = form_left("stribeck", 1, noise + drag, ctx, 0.3, 3.0, 0.5)
    assert left and left["axis"] == "velocity of joint 2" and left["shrink_pct"] > 10
    assert form_left("stribeck", 1, noise, ctx, 0.3, 3.0, 0.5) is None
    assert form_left("payload_error", 1, noise + drag, ctx, 0.3, 3.0, 0.5) is None   # no own axis


def test_friction_growing_faster_than_linearly_is_named_not_stribeck():
    from test_gap_diagnose import FAST, simulate, sines
    from urident.gap import diagnose, format_report
    from urident.model import load_robot

    spec = load_robot("ur10e")
    eff = "effects:\n  - name: quadratic_viscous\n    joints: [2]\n    coefficient_nm_s2: 6.0\n"
    res = diagnose([simulate(spec, sines(3, vmax=1.0), eff, seed=5)],
                   [simulate(spec, sines(4, vmax=1.0), eff, seed=6)], spec, config=FAST)
    first = res.findings[0]
    assert (first.effect, first.joint, first.claim) == ("quadratic_viscous", 2, "cause"), format_report(res)
    assert first.magnitude["coefficient_nm_s2"] == pytest.approx(6.0, rel=0.15)


@pytest.mark.parametrize("effect, form", [
    ("{name: asymmetric_coulomb, joints: [2], coulomb_difference_nm: 3.0}", ("asymmetric_coulomb", "coulomb_difference_nm", 3.0)),
    ("{name: current_lag, joints: [2], time_constant_s: 0.008}", ("current_lag", "time_constant_s", 0.008)),
    ("{name: current_delay, joints: [2], delay_s: 0.008}", ("current_delay", "delay_s", 0.008)),
])
def test_asymmetric_coulomb_and_a_lag_are_named_and_a_delay_stays_a_delay(effect, form):
    from test_gap_diagnose import FAST, simulate, sines
    from urident.gap import diagnose, format_report
    from urident.model import load_robot

    spec = load_robot("ur10e")
    eff = f"effects:\n  - {effect}\n"
    res = diagnose([simulate(spec, sines(3, vmax=1.0), eff, seed=5)],
                   [simulate(spec, sines(4, vmax=1.0), eff, seed=6)], spec, config=FAST)
    first = res.findings[0]
    assert (first.effect, first.joint) == (form[0], 2), format_report(res)
    assert first.magnitude[form[1]] == pytest.approx(form[2], rel=0.2), first.magnitude


def test_a_ripple_at_twice_the_gear_ratio_is_a_candidate():
    """Cogging at 2·101 cycles per revolution (beyond the 150 of the angle-domain map): the
    identification residual's clear peak up to the angle-Nyquist becomes a ripple candidate."""
    from test_gap_diagnose import FAST, simulate, sines
    from urident.gap import diagnose, format_report
    from urident.model import load_robot

    spec = load_robot("ur10e")
    eff = ("effects:\n  - name: position_ripple\n    joints: [3]\n    amplitude_nm: 0.6\n"
           "    harmonic: 202\n    mode: torque\n")
    res = diagnose([simulate(spec, sines(7, duration=12.0, vmax=0.4), eff, seed=7, rate=250.0)],
                   [simulate(spec, sines(8, duration=12.0, vmax=0.4), eff, seed=8, rate=250.0)], spec, config=FAST)
    first = res.findings[0]
    assert (first.effect, first.joint, first.magnitude["harmonic"]) == ("position_ripple", 3, 202), format_report(res)


@pytest.mark.skipif(not (__import__("shared_data").UR10E_DATA / "ur-20_01_22-push_pose_2.csv").is_file(),
                    reason="needs the shared UR10e recordings")
def test_the_real_pushed_run_gives_events_no_effect_and_a_conforming_json():
    from shared_data import UR10E_DATA

    from urident.gap import diagnose
    from urident.logs import load_log
    from urident.model import load_robot

    spec = load_robot("ur10e")
    ident = load_log(UR10E_DATA / "ur-20_02_10-30sec_12harm.csv", format="dynamic_calibration",
                     robot="ur10e", rows=(635, 3510))
    pushed = load_log(UR10E_DATA / "ur-20_01_22-push_pose_2.csv", format="dynamic_calibration", robot="ur10e")
    from test_gap_diagnose import FAST

    res = diagnose([ident], [pushed], spec, config=FAST)
    kinds = {e.kind for e in res.events}
    assert len(res.events) >= 4 and kinds == {"external_contact"}
    assert max(max(abs(p) for p in e.peak_nm) for e in res.events) > 30
    assert res.findings == []                 # nothing named from the pushes or the hold levels
    doc = json.loads(json.dumps(res.as_dict(), allow_nan=False))
    assert errors(doc) == [] and doc["where"]["at_rest"]["joints"] == [1, 2, 3, 4, 5, 6]


def test_friction_driven_by_a_neighbours_load_is_named_with_its_neighbour():
    from test_gap_diagnose import FAST, simulate, sines
    from urident.gap import diagnose, format_report
    from urident.model import load_robot

    spec = load_robot("ur10e")
    eff = "effects:\n  - name: neighbour_load_friction\n    joints: [1]\n    coefficient: 0.05\n    neighbour: 2\n"
    res = diagnose([simulate(spec, sines(3), eff, seed=5)], [simulate(spec, sines(4), eff, seed=6)], spec,
                   config=FAST)
    first = res.findings[0]
    assert (first.effect, first.joint, first.magnitude["neighbour_joint"]) == ("neighbour_load_friction", 1, 2), \
        format_report(res)
    assert first.magnitude["coefficient"] == pytest.approx(0.05, rel=0.15)


def test_a_stribeck_bump_that_scales_with_another_friction_is_its_transition_not_its_own():
    from urident.gap.structure import transition_of

    rng = np.random.default_rng(3)
    t = np.arange(0, 60, 1 / FS)
    v = 0.3 * np.sin(2 * np.pi * t / 7) * np.sin(2 * np.pi * t / 2.3)     # many slow reversals
    amp = 2.0 * np.sin(2 * np.pi * t / 11 + 0.4)     # its amplitude differs from reversal to reversal
    eps, vs = 0.01, 0.01
    s = np.tanh(v / eps)
    near = np.exp(-(v / vs) ** 2)
    bump = near * s                                                       # the Stribeck column
    other = amp * s                                                       # the other finding's correction
    noise = 0.05 * rng.standard_normal(len(t))
    sharper = amp * (np.tanh(v / 0.003) - s) + noise                     # its sign changes more sharply
    hit = transition_of(bump, sharper, [("position_ripple", other)], near, 0.05)
    assert hit and hit["of"] == "position_ripple" and hit["scaled_pct"] > hit["constant_pct"]
    static = 0.8 * bump + noise                                           # a static friction of its own
    assert transition_of(bump, static, [("position_ripple", other)], near, 0.05) is None


def test_a_neighbours_load_is_a_candidate_only_across_perpendicular_axes():
    from urident.gap.candidates import perpendicular_neighbours
    from urident.model import load_robot

    spec = load_robot("ur10e")      # axes: 1 vertical; 2, 3, 4 parallel; 5 ⊥ 4; 6 ⊥ 5
    assert [perpendicular_neighbours(spec, j) for j in range(6)] == [[1], [0], [], [4], [3, 5], [4]]


def test_a_second_finding_that_only_mends_the_first_ones_form_is_no_cause_of_its_own():
    from urident.gap.structure import misfit_of

    rng = np.random.default_rng(4)
    t = np.arange(0, 60, 1 / FS)
    v = 0.4 * np.sin(2 * np.pi * t / 6) + 0.2 * np.sin(2 * np.pi * t / 2.1)
    load = 20 + 10 * np.sin(2 * np.pi * t / 9)                            # a neighbour's load
    s = np.tanh(v / 0.01)
    first = 0.03 * load * s                                               # the first finding's correction
    bins = np.digitize(v, np.quantile(v, np.linspace(0, 1, 13)[1:-1]))
    noise = 0.05 * rng.standard_normal(len(t))
    warm = -np.expm1(-t / 15) * v                                         # a second finding's column
    mend = 0.01 * load * (np.tanh(v / 0.004) - s) + noise                 # the first one's sharper sign
    hit = misfit_of(warm, mend + 0.3 * np.abs(v) * s, [("neighbour_load_friction", first)], bins, 0.05)
    assert hit and hit["of"] == "neighbour_load_friction"
    own = 0.5 * warm + noise                                              # a warm-up of its own
    assert misfit_of(warm, own, [("neighbour_load_friction", first)], bins, 0.05) is None


def test_structure_only_the_identification_logs_hold_is_listed_with_its_candidate():
    """An effect in every run that the validation motion barely excites (a cold start on a joint
    the validation run hardly moves early) leaves the validation residual at the noise; the
    identification logs still hold it: the joint is listed with what would shrink it there."""
    from types import SimpleNamespace

    from urident.gap.structure import describe, identification_only
    from urident.gap.where import describe_unexplained

    rng = np.random.default_rng(5)
    r_id = rng.normal(0, 0.2, (3000, 6))
    ss = np.sum(r_id ** 2, axis=0)
    cold = SimpleNamespace(mode="ident", joint=5, name="thermal_drift on joint 6 [ident]")
    tiny = SimpleNamespace(mode="ident", joint=1, name="stribeck on joint 2 [ident]")
    taken = SimpleNamespace(mode="ident", joint=2, name="load_friction on joint 3 [ident]")
    cv = SimpleNamespace(mode="cv", joint=4, name="current_offset on joint 5 [cv]")
    drop = {id(cold): 0.3 * ss[5], id(tiny): 0.001 * ss[1], id(cv): 0.5 * ss[4]}

    class Scorer:
        ident = SimpleNamespace(residual=r_id, n=3000)

        def ident_ss(self, cands):
            return float(ss.sum() - sum(drop.get(id(c), 0.0) for c in cands if c is not taken))

    last = [SimpleNamespace(candidate=cold, shrink_pct=1.2)]
    got = identification_only(Scorer(), [cold, tiny, taken, cv], [taken], last, 3.0)
    assert list(got) == [5]
    assert got[5]["shrink_pct"] == pytest.approx(100 * (1 - np.sqrt(0.7)))
    assert got[5]["validation_shrink_pct"] == 1.2 and "thermal_drift" in describe(got[5])
    # listed beyond the catalogue though the validation residual on joint 6 is white noise
    n = 4000
    ctx = SimpleNamespace(q=np.zeros((n, 6)), qd=np.zeros((n, 6)), tau_hat=np.zeros((n, 6)),
                          data=SimpleNamespace(run_time=np.arange(n) / FS, sample_rate=FS),
                          sign=lambda: np.zeros((n, 6)))
    white = rng.normal(0, 0.2, (n, 6))
    assert describe_unexplained(ctx, white) == []
    out = describe_unexplained(ctx, white, ident_structure=got)
    assert [u["joint"] for u in out] == [6] and out[0]["structure"][0]["kind"] == "identification_logs"


def test_a_stribeck_bump_within_an_offset_of_its_sign_is_that_levels_sharper_sign():
    """A Coulomb level that differs by direction by 2c reads as an offset c plus a bump of c's sign
    no taller than |c| (its sharper sign change): a Stribeck finding there is partial; one taller
    than the offset, or of the other sign, stays its own."""
    from types import SimpleNamespace

    from urident.gap.diagnose import offset_transition

    v = np.linspace(-0.3, 0.3, 2001)
    col = np.exp(-(v / 0.01) ** 2) * np.tanh(v / 0.01)
    offset = SimpleNamespace(effect="current_offset", joint=3, magnitude={"offset_nm": 1.9})
    elsewhere = SimpleNamespace(effect="current_offset", joint=2, magnitude={"offset_nm": 1.9})

    def stribeck(fs):
        return SimpleNamespace(effect="stribeck", joint=3, magnitude={"extra_static_friction_nm": fs})
    hit = offset_transition(stribeck(1.5), 1.5 * col, [elsewhere, offset])
    assert hit and hit["offset_nm"] == 1.9 and "differs by direction" in hit["text"]
    assert offset_transition(stribeck(1.5), 1.5 * col, [elsewhere]) is None
    assert offset_transition(stribeck(8.0), 8.0 * col, [offset]) is None          # taller: its own
    neg = SimpleNamespace(effect="current_offset", joint=3, magnitude={"offset_nm": -1.9})
    assert offset_transition(stribeck(1.5), 1.5 * col, [neg]) is None             # other sign
