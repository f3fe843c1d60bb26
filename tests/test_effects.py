"""The unmodelled-effects catalogue: files, presets, each effect's regime, hook vs offline form."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from urident.errors import ConfigError
from urident.model import joint_torques, load_robot
from urident.model.pinocchio_model import build_model
from urident.simcontroller.effects import (
    EFFECT_NAMES,
    EffectUsageError,
    available_presets,
    catalogue,
    load_effects,
    parse_effects,
    parse_effects_text,
    payload_params,
)

RATE = 125.0
DT = 1.0 / RATE


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


def run_arrays(spec, n=376, seed=0):
    """A smooth multi-sine motion sampled at 125 Hz, its model torque and a warming temperature."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    amp = rng.uniform(0.2, 0.6, 6)
    w = rng.uniform(1.0, 3.0, 6)
    phase = rng.uniform(0, np.pi, 6)
    q0 = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
    q = q0 + amp * np.sin(w * t[:, None] + phase)
    qd = amp * w * np.cos(w * t[:, None] + phase)
    qdd = -amp * w * w * np.sin(w * t[:, None] + phase)
    tau = joint_torques(spec, spec.nominal_params, q, qd, qdd)
    temps = 30.0 + 0.5 * t[:, None] * np.arange(1, 7) / 6.0 + 0.0 * q
    return t, q, qd, qdd, tau, temps


def effects_text(*entries: str) -> str:
    return "effects:\n" + "".join(f"  - {e}\n" for e in entries)


def stepped(es, t, q, qd, qdd, tau, temps, current=None):
    """Drive the Plant hooks sample by sample."""
    torque = np.array([es.extra_torque(t[k], q[k], qd[k], qdd[k], tau[k], temps[k])
                       for k in range(len(t))])
    cur = None
    if current is not None:
        cur = np.array([es.measure_current(t[k], current[k], q[k], qd[k], temps[k])
                        for k in range(len(t))])
    return torque, cur


# ---------------------------------------------------------------------- catalogue and presets
def test_catalogue_names_are_the_public_interface():
    assert EFFECT_NAMES == ("stribeck", "load_friction", "thermal_drift", "position_ripple",
                            "current_delay", "torque_constant_error", "current_offset",
                            "payload_error", "joint_elasticity", "quadratic_viscous",
                            "neighbour_load_friction", "asymmetric_coulomb", "current_lag")
    for entry in catalogue():
        assert entry.summary and "\n" not in entry.summary
        assert entry.params
        assert entry.name in entry.format()


def test_presets_load(spec):
    assert {"realistic", "none"} <= set(available_presets())
    realistic = load_effects("realistic", spec=spec)
    assert {"stribeck", "current_delay", "current_offset", "thermal_drift"} <= set(realistic.names)
    assert realistic.joints_of("stribeck") == (1, 2, 3, 4, 5, 6)
    assert "realistic" in realistic.describe()
    assert len(load_effects("none", spec=spec)) == 0
    assert load_effects(None, spec=spec).names == ()
    delay = [e for e in realistic.entries if e.name == "current_delay"][0]
    assert 0.002 <= delay.values["delay_s"][0] <= 0.004


def test_file_and_preset_resolution(tmp_path):
    path = tmp_path / "fx.yaml"
    path.write_text(effects_text("{name: current_offset, joints: [2], offset_a: 0.1}"))
    config = parse_effects(path)
    assert config.names == ("current_offset",)
    assert config.as_dict()["effects"] == [{"name": "current_offset", "joints": [2], "offset_a": [0.1]}]
    with pytest.raises(ConfigError, match="no such effects file or preset; presets: .*realistic"):
        parse_effects("realistik")
    with pytest.raises(ConfigError, match="effects file not found"):
        parse_effects(tmp_path / "missing.yaml")


# ---------------------------------------------------------------------- strict validation
@pytest.mark.parametrize("text, message", [
    (effects_text("{name: stribek}"),
     r"FX: effects\[0\]\.name: unknown effect 'stribek'; catalogue: stribeck, load_friction"),
    (effects_text("{name: stribeck, static_friction: 3}"),
     r"FX: effects\[0\]\.static_friction: unknown parameter of stribeck; parameters: joints"),
    (effects_text("{name: current_offset, joints: [1, 7]}"),
     r"FX: effects\[0\]\.joints\[1\]: joint must be an integer 1-6, got 7"),
    (effects_text("{name: current_offset, joints: [0]}"), r"effects\[0\]\.joints\[0\]"),
    (effects_text("{name: current_offset, joints: [1, 1]}"), r"joint 1 listed twice"),
    (effects_text("{name: current_offset, joints: []}"), r"effects\[0\]\.joints: expected a non-empty"),
    (effects_text("{name: current_offset, joints: [1, 2], offset_a: [0.1, 0.2, 0.3]}"),
     r"FX: effects\[0\]\.offset_a: expected 2 values \(one per joint in 'joints'\)"),
    (effects_text("{name: current_offset, offset_a: .nan}"),
     r"FX: effects\[0\]\.offset_a: expected a finite number, got nan"),
    (effects_text("{name: current_delay, joints: [1, 2], delay_s: [0.1, .nan]}"),
     r"FX: effects\[0\]\.delay_s\[1\]: expected a finite number"),
    (effects_text("{name: current_delay, delay_s: -0.1}"), r"delay_s: must be >= 0 and <= 1, got -0.1"),
    (effects_text("{name: current_delay, delay_s: yes}"), r"delay_s: expected a number, got True"),
    (effects_text("{name: position_ripple, mode: sideways}"), r"mode: must be one of torque, friction"),
    (effects_text("{name: payload_error, offset_m: [0, 0]}"), r"offset_m: expected a list of 3"),
    (effects_text("{name: stribeck, static_friction_nm: 9, static_friction_ratio: 1.2}"),
     r"give static_friction_nm or static_friction_ratio, not both"),
    (effects_text("{name: current_offset, joints: [1]}", "{name: current_offset, joints: [2, 1]}"),
     r"FX: effects\[1\]\.joints: joint 1 already has current_offset \(effects\[0\]\)"),
    (effects_text("{joints: [1]}"), r"effects\[0\]\.name: missing; catalogue: stribeck"),
    (effects_text("current_offset"), r"effects\[0\]: expected a mapping"),
    ("effects: {name: stribeck}\n", r"FX: effects: expected a list of effects"),
    ("effect: []\n", r"FX: effect: unknown key; allowed: description, effects"),
    ("description: x\n", r"FX: effects: missing key"),
    ("", r"FX: effects file is empty"),
    ("effects: [\n", r"FX:\d+: malformed YAML"),
    ("effects: []\neffects: []\n", r"FX:2: effects: duplicate key"),
])
def test_malformed_effects_files_give_one_line_errors(text, message):
    with pytest.raises(ConfigError, match=message) as info:
        parse_effects_text(text, "FX")
    assert "\n" not in str(info.value)


def test_error_names_the_file(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(effects_text("{name: current_offset, offset_a: [1, 2]}"))
    with pytest.raises(ConfigError, match=rf"^{path}: effects\[0\]\.offset_a: expected 6 values"):
        parse_effects(path)


def test_defaults_fill_every_parameter():
    config = parse_effects_text(effects_text("{name: stribeck, joints: [2]}"))
    (entry,) = config.entries
    assert entry.joints == (1,)
    assert entry.values["static_friction_ratio"][1] == 1.3
    assert entry.values["static_friction_nm"] is None
    assert config.as_dict()["effects"][0] == {"name": "stribeck", "joints": [2],
                                              "static_friction_ratio": [1.3],
                                              "stribeck_velocity_rad_s": [0.02]}


# ---------------------------------------------------------------------- each effect's regime
def only_joint(extra, joint):
    others = np.delete(extra, joint, axis=1)
    assert np.all(others == 0.0)


def test_stribeck_only_near_zero_velocity_on_its_joint(spec):
    es = load_effects(parse_effects_text(effects_text(
        "{name: stribeck, joints: [2], static_friction_nm: 9.0, stribeck_velocity_rad_s: 0.02}")),
        spec=spec)
    n = 401
    t = np.arange(n) * DT
    qd = np.zeros((n, 6))
    qd[:, 1] = np.linspace(-0.4, 0.4, n)
    q = np.tile([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], (n, 1))
    zeros = np.zeros((n, 6))
    tau = joint_torques(spec, spec.nominal_params, q, qd, zeros)
    extra = es.offline_extra_torque(t, q, qd, zeros, tau, zeros + 30)
    only_joint(extra, 1)
    v = qd[:, 1]
    fc = spec.nominal_params[72 + 1]
    near = (np.abs(v) > 0.01) & (np.abs(v) < 0.02)
    far = np.abs(v) > 0.1
    assert np.all(np.abs(extra[near, 1]) > 0.3 * (9.0 - fc))
    assert np.all(np.abs(extra[far, 1]) < 1e-6)
    assert np.all(np.sign(extra[np.abs(v) > 1e-3, 1]) == np.sign(v[np.abs(v) > 1e-3]))
    assert np.max(np.abs(extra[:, 1])) <= 9.0 - fc + 1e-12


def test_load_friction_scales_with_load(spec):
    t, q, qd, qdd, tau, temps = run_arrays(spec)
    es = load_effects(parse_effects_text(effects_text(
        "{name: load_friction, joints: [3], coefficient: 0.05}")), spec=spec)
    extra = es.offline_extra_torque(t, q, qd, qdd, tau, temps)
    only_joint(extra, 2)
    p = spec.nominal_params
    link = tau[:, 2] - p[62] * qdd[:, 2] - p[68] * qd[:, 2] - p[74] * np.tanh(qd[:, 2] / 0.01)
    np.testing.assert_allclose(extra[:, 2], 0.05 * np.abs(link) * np.tanh(qd[:, 2] / 0.01), atol=1e-12)


def test_thermal_drift_grows_with_warm_up(spec):
    n = 2000
    t = np.arange(n) * 0.1          # 200 s
    q = np.tile([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], (n, 1))
    qd = np.full((n, 6), 0.5)
    zeros = np.zeros((n, 6))
    temps = np.full((n, 6), 35.0)
    es = load_effects(parse_effects_text(effects_text(
        "{name: thermal_drift, joints: [1], viscous_change_per_c: -0.02, coulomb_change_per_c: 0,"
        " warmup_c: 10, warmup_time_constant_s: 100}")), spec=spec)
    extra = es.offline_extra_torque(t, q, qd, zeros, zeros, temps)
    only_joint(extra, 0)
    expected = -0.02 * 10 * (1 - np.exp(-t / 100)) * spec.nominal_params[66] * 0.5
    np.testing.assert_allclose(extra[:, 0], expected, atol=1e-12)
    assert extra[0, 0] == 0.0 and np.all(np.diff(extra[:, 0]) < 0)
    # a measured temperature rise acts the same way as the grease warm-up
    es2 = load_effects(parse_effects_text(effects_text(
        "{name: thermal_drift, joints: [1], viscous_change_per_c: -0.02, coulomb_change_per_c: 0,"
        " warmup_c: 0}")), spec=spec)
    warmer = temps + 5.0 * (t[:, None] > 100)
    extra2 = es2.offline_extra_torque(t, q, qd, zeros, zeros, warmer)
    assert np.all(extra2[t <= 100, 0] == 0)
    np.testing.assert_allclose(extra2[t > 100, 0], -0.02 * 5 * spec.nominal_params[66] * 0.5)


def test_position_ripple(spec):
    t, q, qd, qdd, tau, temps = run_arrays(spec)
    es = load_effects(parse_effects_text(effects_text(
        "{name: position_ripple, joints: [4], amplitude_nm: 0.4, harmonic: 3, phase_rad: 0.5}")),
        spec=spec)
    extra = es.offline_extra_torque(t, q, qd, qdd, tau, temps)
    only_joint(extra, 3)
    np.testing.assert_allclose(extra[:, 3], 0.4 * np.sin(3 * q[:, 3] + 0.5))


def test_current_delay_shifts_by_d(spec):
    t, q, qd, qdd, tau, temps = run_arrays(spec)
    current = tau / spec.drive_gains
    es = load_effects(parse_effects_text(effects_text(
        f"{{name: current_delay, joints: [2], delay_s: {2 * DT}}}",
        f"{{name: current_delay, joints: [5], delay_s: {0.5 * DT}}}")))
    out = es.offline_measure_current(t, current, q, qd, temps)
    np.testing.assert_array_equal(np.delete(out, [1, 4], axis=1), np.delete(current, [1, 4], axis=1))
    np.testing.assert_allclose(out[2:, 1], current[:-2, 1], atol=1e-12)
    np.testing.assert_allclose(out[:3, 1], current[0, 1])
    np.testing.assert_allclose(out[1:, 4], 0.5 * (current[1:, 4] + current[:-1, 4]), atol=1e-12)


def test_current_lag_is_a_first_order_filter_not_a_delay(spec):
    t = np.arange(400) * DT
    step = np.zeros((400, 6))
    step[100:] = 1.0
    tc = 5 * DT
    es = load_effects(parse_effects_text(effects_text(f"{{name: current_lag, joints: [3], time_constant_s: {tc}}}")))
    out = es.offline_measure_current(t, step, step, step, step)
    np.testing.assert_array_equal(np.delete(out, 2, axis=1), np.delete(step, 2, axis=1))
    k = np.arange(100, 400)
    np.testing.assert_allclose(out[k, 2], 1 - np.exp(-(t[k] - t[99]) / tc), atol=1e-12)
    assert out[99, 2] == 0 and 0 < out[100, 2] < 0.25   # it moves at once (a delay would hold 0)
    noise = np.random.default_rng(0).normal(size=(20000, 6))
    lagged = es.offline_measure_current(np.arange(20000) * DT, noise, noise, noise, noise)[:, 2]
    a = np.exp(-1 / 5)                         # the sensor noise comes out coloured, AR(1) with a
    assert np.corrcoef(lagged[1:], lagged[:-1])[0, 1] == pytest.approx(a, abs=0.02)


def test_asymmetric_coulomb_differs_by_direction_and_not_at_rest(spec):
    t, q, qd, qdd, tau, temps = run_arrays(spec)
    es = load_effects(parse_effects_text(effects_text(
        "{name: asymmetric_coulomb, joints: [2], coulomb_difference_nm: 1.2}")), spec=spec)
    qd = np.zeros_like(qd)
    qd[:, 1] = np.linspace(-1, 1, len(qd))
    qd[100, 1] = 0.0
    extra = es.offline_extra_torque(t, q, qd, qdd, tau, temps)
    only_joint(extra, 1)
    friction = es.context.coulomb[1] * es.context.sign(qd[:, 1]) + extra[:, 1]
    assert friction[-1] - (-friction[0]) == pytest.approx(1.2, rel=1e-6)   # forwards − backwards level
    assert extra[100, 1] == 0                                               # nothing at rest


def test_torque_constant_error_scales_and_offset_adds(spec):
    t, q, qd, qdd, tau, temps = run_arrays(spec)
    current = tau / spec.drive_gains
    es = load_effects(parse_effects_text(effects_text(
        "{name: torque_constant_error, joints: [1, 6], gain_factor: [1.1, 0.8]}",
        "{name: current_offset, joints: [6], offset_a: 0.07}")))
    out = es.offline_measure_current(t, current, q, qd, temps)
    np.testing.assert_allclose(out[:, 0], current[:, 0] / 1.1)
    np.testing.assert_allclose(out[:, 5], current[:, 5] / 0.8 + 0.07)
    np.testing.assert_array_equal(out[:, 1:5], current[:, 1:5])


def test_payload_error_matches_pinocchio(spec):
    t, q, qd, qdd, tau, temps = run_arrays(spec, n=40)
    es = load_effects(parse_effects_text(effects_text(
        "{name: payload_error, mass_kg: 1.5, offset_m: [0.01, -0.02, 0.05]}")), spec=spec)
    extra = es.offline_extra_torque(t, q, qd, qdd, tau, temps)
    # independent: add the point mass to body 6 of a Pinocchio model and difference the torques
    plain = build_model(spec)
    loaded = build_model(spec)
    com = spec.tool_xyz + spec.tool_rotation @ np.array([0.01, -0.02, 0.05])
    loaded.inertias[6] = loaded.inertias[6] + pin.Inertia(1.5, com, np.zeros((3, 3)))
    d_plain, d_loaded = plain.createData(), loaded.createData()
    ref = np.array([pin.rnea(loaded, d_loaded, *x) - pin.rnea(plain, d_plain, *x)
                    for x in zip(q, qd, qdd)])
    np.testing.assert_allclose(extra, ref, atol=1e-9)
    # static check: gravity torque of joint 2 at least m·g·(horizontal reach) order
    assert np.max(np.abs(extra[:, 1])) > 1.5 * 9.81 * 0.1
    assert payload_params(spec, 1.5, np.zeros(3))[50] == 1.5


def test_joint_elasticity_lags_and_matches_the_continuous_model(spec):
    n = 2501
    t = np.arange(n) * DT
    f = 2.0
    w = 2 * np.pi * f
    q = np.tile([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], (n, 1))
    qd = np.zeros((n, 6))
    qdd = np.zeros((n, 6))
    q[:, 0] += 0.2 * np.sin(w * t)
    qd[:, 0] = 0.2 * w * np.cos(w * t)
    qdd[:, 0] = -0.2 * w * w * np.sin(w * t)
    tau = joint_torques(spec, spec.nominal_params, q, qd, qdd)
    k, zeta, inertia = 2000.0, 0.05, 2.0
    es = load_effects(parse_effects_text(effects_text(
        f"{{name: joint_elasticity, joints: [1], stiffness_nm_per_rad: {k}, damping_ratio: {zeta},"
        f" link_inertia_kg_m2: {inertia}}}")), spec=spec)
    extra = es.offline_extra_torque(t, q, qd, qdd, tau, np.zeros((n, 6)))
    only_joint(extra, 0)
    p = spec.nominal_params
    link = tau[:, 0] - p[60] * qdd[:, 0] - p[66] * qd[:, 0] - p[72] * np.tanh(qd[:, 0] / 0.01)
    spring = link + extra[:, 0]
    steady = t > 10.0                   # transients decayed (ζ ω_n ≈ 1.6 1/s)
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones(n)])[steady]
    a_link = np.linalg.lstsq(basis, link[steady], rcond=None)[0]
    a_spring = np.linalg.lstsq(basis, spring[steady], rcond=None)[0]
    h_measured = complex(a_spring[0], a_spring[1]) / complex(a_link[0], a_link[1])
    d = 2 * zeta * np.sqrt(k * inertia)
    s = 1j * w
    h_true = (d * s + k) / (inertia * s * s + d * s + k)
    assert abs(h_measured - h_true) < 0.01 * abs(h_true)
    assert np.angle(h_measured) < 0                 # the spring torque lags the link torque
    # deflection: the link lags the motor by e ≈ τ_link / k when quasi-static
    e = es.offline_deflection(t, q, qd, qdd, tau)
    assert np.all(e[:, 1:] == 0)
    assert e[0, 0] == pytest.approx(link[0] / k)


# ---------------------------------------------------------------------- hook form == offline form
ALL_EFFECTS = effects_text(
    "{name: stribeck, joints: [1, 2], static_friction_ratio: 1.5}",
    "{name: stribeck, joints: [4], static_friction_nm: 2.0, stribeck_velocity_rad_s: 0.1}",
    "{name: load_friction, coefficient: 0.03}",
    "{name: thermal_drift, warmup_c: 20, warmup_time_constant_s: 5}",
    "{name: position_ripple, amplitude_nm: 0.3, harmonic: 7, mode: friction}",
    "{name: payload_error, mass_kg: 2.0, offset_m: [0, 0, 0.1]}",
    "{name: joint_elasticity, joints: [1, 2, 3], stiffness_nm_per_rad: 5000, damping_ratio: 0.05}",
    "{name: current_delay, joints: [1, 2, 3], delay_s: 0.011}",
    "{name: current_delay, joints: [4], delay_s: 0}",
    "{name: torque_constant_error, gain_factor: 0.95}",
    "{name: current_offset, offset_a: [0.1, -0.1, 0.05, 0, 0.02, -0.03]}",
    "{name: quadratic_viscous, joints: [2, 5], coefficient_nm_s2: 3.0}",
    "{name: neighbour_load_friction, joints: [1, 2], coefficient: 0.03, neighbour: [2, 3]}",
    "{name: asymmetric_coulomb, joints: [3, 4], coulomb_difference_nm: [1.5, -0.4]}",
    "{name: current_lag, joints: [2, 6], time_constant_s: [0.006, 0.002]}",
)


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_hook_form_equals_offline_form(spec, name):
    config = parse_effects_text(ALL_EFFECTS)
    text = effects_text(*[line.strip()[2:] for line in ALL_EFFECTS.splitlines()[1:]
                          if f"name: {name}," in line or line.strip().endswith(f"name: {name}}}")])
    es = load_effects(parse_effects_text(text), spec=spec)
    assert es.names == (name,) and len(config.entries) == 15
    t, q, qd, qdd, tau, temps = run_arrays(spec, n=250, seed=3)
    current = tau / spec.drive_gains
    offline_torque = es.offline_extra_torque(t, q, qd, qdd, tau, temps)
    offline_current = es.offline_measure_current(t, current, q, qd, temps)
    online_torque, online_current = stepped(es, t, q, qd, qdd, tau, temps, current)
    np.testing.assert_allclose(online_torque, offline_torque, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(online_current, offline_current, rtol=1e-9, atol=1e-12)
    assert np.any(offline_torque != 0) or np.any(offline_current != current)
    es.reset()                                    # a reset set replays the same run
    again, _ = stepped(es, t, q, qd, qdd, tau, temps)
    np.testing.assert_array_equal(again, online_torque)


def test_all_effects_together_hook_equals_offline(spec):
    es = load_effects(parse_effects_text(ALL_EFFECTS), spec=spec)
    t, q, qd, qdd, tau, temps = run_arrays(spec, n=250, seed=4)
    current = tau / spec.drive_gains
    online_torque, online_current = stepped(es, t, q, qd, qdd, tau, temps, current)
    np.testing.assert_allclose(online_torque, es.offline_extra_torque(t, q, qd, qdd, tau, temps),
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(online_current, es.offline_measure_current(t, current, q, qd, temps),
                               rtol=1e-9, atol=1e-12)


# ---------------------------------------------------------------------- misuse
def test_stateful_misuse_is_an_error(spec):
    es = load_effects(parse_effects_text(effects_text("{name: current_delay}")))
    z = np.zeros(6)
    es.measure_current(0.0, z, z, z, z)
    es.measure_current(DT, z, z, z, z)
    with pytest.raises(EffectUsageError, match="step once per controller period"):
        es.measure_current(DT, z, z, z, z)
    with pytest.raises(EffectUsageError, match="constant controller period"):
        es.measure_current(5 * DT, z, z, z, z)
    es.reset()
    es.measure_current(0.0, z, z, z, z)
    unbound = load_effects(parse_effects_text(effects_text("{name: stribeck}")))
    assert unbound.names == ("stribeck",) and "stribeck" in unbound.describe()
    with pytest.raises(EffectUsageError, match="pass spec= to load_effects"):
        unbound.extra_torque(0.0, z, z, z, z, z)
    bound = unbound.bind(spec)
    assert bound.extra_torque(0.0, z, z, z, z, z).shape == (6,)
