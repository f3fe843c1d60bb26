"""Robot files, kinematics against UR's DH parameters, the regressor against Pinocchio, base
parameters against the paper."""

import numpy as np
import pinocchio as pin
import pytest

from urident.errors import ConfigError, UnknownRobotError
from urident.model import available_robots, joint_torques, load_robot, parameter_names, regressor
from urident.model.base import base_parameters
from urident.model.check import dh_poses
from urident.model.kinematics import frame_poses
from urident.model.regressor import kernel_available, weighted_state_derivatives
from urident.model.parameters import body_params
from urident.model.pinocchio_model import TorqueModel, build_collision_model, build_model

ROBOTS = available_robots()
FAMILY = ["ur3", "ur3e", "ur5", "ur5e", "ur10", "ur10e", "ur16e", "ur20", "ur30"]


def test_every_ur_arm_ships_a_robot_file():
    assert sorted(FAMILY) == ROBOTS


def random_physical_params(rng, spec):
    """A random but physically valid 78-vector: masses, CoMs, PD inertias, positive drive terms."""
    p = np.zeros(78)
    for i in range(6):
        m = rng.uniform(0.3, 10.0)
        com = rng.uniform(-0.3, 0.3, 3)
        a = rng.normal(size=(3, 3))
        inertia = a @ a.T * 0.01 + 1e-3 * np.eye(3)
        p[10 * i:10 * i + 10] = body_params(m, com, inertia)
    p[60:] = rng.uniform(0.01, 5.0, 18)
    return p




@pytest.mark.parametrize("name", ROBOTS)
def test_frames_reproduce_ur_dh_kinematics(name, rng):
    spec = load_robot(name)
    base_to_controller = np.diag([-1.0, -1.0, 1.0])  # K_0 is the controller base rotated by pi about z
    for q in rng.uniform(-np.pi, np.pi, (20, 6)):
        _, pos = frame_poses(spec, q[None])
        tool_dh = dh_poses(spec, q)[-1][:3, 3]
        np.testing.assert_allclose(base_to_controller @ pos[0, 6], tool_dh, atol=1e-12)


BACKENDS = ["numpy", "c"] if kernel_available() else ["numpy"]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_regressor_equals_pinocchio_plus_rotor_and_friction(name, backend, rng):
    spec = load_robot(name)
    for trial in range(3):
        p = random_physical_params(rng, spec)
        eps = rng.uniform(0.005, 0.1)
        q, qd, qdd = rng.uniform(-3, 3, (3, 40, 6))
        tau = (regressor(spec, q, qd, qdd, friction_eps=eps, backend=backend) @ p).reshape(-1, 6)
        model = TorqueModel(spec, p, friction_eps=eps)
        expected = model.torques(q, qd, qdd)
        rel = np.abs(tau - expected).max() / np.abs(expected).max()
        assert rel < 1e-9


def test_compiled_kernel_is_built():
    # CI installs with a compiler: the fast path must be there (the numpy path is the fallback).
    assert kernel_available()


def test_regressor_rejects_bad_shapes():
    spec = load_robot("ur5")
    with pytest.raises(ValueError, match="must be"):
        regressor(spec, np.zeros((3, 5)), np.zeros((3, 5)), np.zeros((3, 5)))


def test_regressor_layout_is_sample_major(rng):
    spec = load_robot("ur5")
    q, qd, qdd = rng.uniform(-2, 2, (3, 7, 6))
    w = regressor(spec, q, qd, qdd)
    assert w.shape == (42, 78)
    p = spec.nominal_params
    np.testing.assert_allclose((w @ p).reshape(7, 6), joint_torques(spec, p, q, qd, qdd))
    single = regressor(spec, q[3:4], qd[3:4], qdd[3:4])
    np.testing.assert_allclose(w[18:24], single)


@pytest.mark.parametrize("name", ROBOTS)
def test_nominal_gravity_torque_matches_pinocchio_model(name, rng):
    spec = load_robot(name)
    model = build_model(spec)
    data = model.createData()
    q = rng.uniform(-3, 3, 6)
    g = pin.computeGeneralizedGravity(model, data, q)
    zero = np.zeros((1, 6))
    tau = joint_torques(spec, spec.nominal_params, q[None], zero, zero)[0]
    np.testing.assert_allclose(tau, g, atol=1e-9)
    # Sanity: a horizontal arm (q2 = 0) needs a large share of the shoulder's rated torque against
    # gravity (the arm's own weight at about half its reach), and no more than the drive can give.
    shoulder = abs(joint_torques(spec, spec.nominal_params, zero, zero, zero)[0, 1])
    weight_moment = sum(j.mass for j in spec.joints[1:]) * 9.81 * spec.reach_m / 2
    assert 0.3 * weight_moment < shoulder < min(2 * weight_moment, spec.tau_max[1])


@pytest.mark.parametrize("name", ROBOTS)
def test_base_parameter_counts(name):
    spec = load_robot(name)
    assert base_parameters(spec).n_base == 52
    assert base_parameters(spec, reduced=True).n_base == 33


@pytest.mark.parametrize("reduced", [False, True])
def test_base_regressor_reproduces_full_model(reduced, rng):
    spec = load_robot("ur5")
    base = base_parameters(spec, reduced=reduced)
    p = random_physical_params(rng, spec)
    mask = np.zeros(78, dtype=bool)
    mask[base.modelled] = True
    p[~mask] = 0.0
    q, qd, qdd = rng.uniform(-3, 3, (3, 30, 6))
    w = regressor(spec, q, qd, qdd)
    np.testing.assert_allclose(base.columns(w) @ base.from_standard(p), w @ p, rtol=1e-9, atol=1e-9)


def test_base_parameter_expressions_match_paper_structure():
    spec = load_robot("ur5")
    expressions = dict(zip(base_parameters(spec).names, base_parameters(spec).expressions()))
    # Paper eq. (42), with our K2 placement (the numbers depend only on the UR5's link lengths).
    assert expressions["B3"] == "B3 + 0.1539 m4 + 0.1539 m5 + 0.1539 m6"
    assert expressions["A4"] == "A4 - C4 + B5 + 0.008959 m6"
    assert expressions["C5"] == "C5 + C6"
    assert expressions["A5"] == "A5 - B5 + C6"
    assert expressions["mrz2"] == "mrz2 + 0.425 m3 + 0.425 m4 + 0.425 m5 + 0.425 m6"
    reduced = dict(zip(base_parameters(spec, reduced=True).names,
                       base_parameters(spec, reduced=True).expressions()))
    assert reduced["m3"] == "m3 + m4 + m5 + m6"
    assert reduced["B2"] == "B2 + IM2"


@pytest.mark.parametrize("name", ROBOTS)
def test_base_parameter_expressions_are_readable_and_exact_to_their_rounding(name, rng):
    import re

    spec = load_robot(name)
    for reduced in (False, True):
        base = base_parameters(spec, reduced=reduced)
        names = parameter_names()
        p = random_physical_params(rng, spec)
        values = base.from_standard(p)
        term = re.compile(r"^(?:(\d+(?:\.\d+)?(?:e-\d+)?) )?([A-Za-z]+\d)$")
        for k, (label, expr) in enumerate(zip(base.names, base.expressions())):
            terms = re.split(r" (?=[+-] )", expr)
            assert terms[0] == label, expr  # each base parameter is led by its own standard one
            total = 0.0
            for t in terms:
                sign = -1.0 if t.startswith("- ") else 1.0
                match = term.match(t[2:] if t[:2] in ("+ ", "- ") else t)
                assert match, f"{name}: unreadable term {t!r} in {expr!r}"
                coef, pname = match.groups()
                total += sign * float(coef or 1.0) * p[names.index(pname)]
            # coefficients are printed to 4 significant digits
            assert total == pytest.approx(values[k], rel=2e-3, abs=2e-3 * np.abs(p).max()), expr


def test_unknown_robot_and_malformed_files(tmp_path):
    with pytest.raises(UnknownRobotError, match="unknown robot 'ur99'.*ur10, ur10e, ur16e, ur20, ur3, ur30, ur3e, ur5, ur5e"):
        load_robot("ur99")
    good = load_robot("ur5").source.read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(good.replace("torque_limit: 150.0", "torque_limt: 150.0", 1))
    with pytest.raises(ConfigError, match=r"bad.yaml: joints\[0\].torque_limt: unknown key"):
        load_robot(bad)
    bad.write_text(good.replace("mass: 3.7", "mass: -3.7"))
    with pytest.raises(ConfigError, match=r"joints\[0\].link.mass: must be positive"):
        load_robot(bad)
    bad.write_text("name: [unclosed\n")
    with pytest.raises(ConfigError, match=r"bad.yaml:\d+: malformed YAML"):
        load_robot(bad)


@pytest.mark.parametrize("name", ROBOTS)
def test_collision_model_distances(name, rng):
    spec = load_robot(name)
    model = build_model(spec)
    geom = build_collision_model(spec, model)
    assert len(geom.collisionPairs) > 10
    data, gdata = model.createData(), pin.GeometryData(geom)
    q_up = np.array([0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0])  # arm pointing up
    pin.computeDistances(model, data, geom, gdata, q_up)
    assert min(r.min_distance for r in gdata.distanceResults) > 0.0
    q_folded = np.array([0.0, -np.pi / 2, 2.9, 0.0, 0.0, 0.0])  # forearm folded into the upper arm
    pin.computeDistances(model, data, geom, gdata, q_folded)
    assert min(r.min_distance for r in gdata.distanceResults) < 0.0


def test_model_cli_json(capsys):
    import json

    from urident.cli.main import main

    assert main(["model", "--robot", "ur5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["robot"] == "ur5" and out["n_params"] == 78 and out["n_base"] == 52
    assert {"name": "C5", "expression": "C5 + C6"} in out["base_parameters"]
    assert main(["model", "--robot", "ur5", "--reduced", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_base"] == 33
    assert main(["model", "--robot", "nope"]) == 2
    assert "unknown robot 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["ur5", "ur10e", "ur3", "ur20"])
def test_weighted_state_derivatives_kernel_matches_regressor_differences(name, rng):
    # the kernel differentiates exactly (reverse mode); the numpy path differences 19 regressors
    spec = load_robot(name)
    q, qd, qdd = rng.uniform(-3, 3, (3, 50, 6))
    weights = rng.standard_normal((50, 6, 78))
    fast = weighted_state_derivatives(spec, q, qd, qdd, weights, 1e-8)
    slow = weighted_state_derivatives(spec, q, qd, qdd, weights, 1e-8, backend="numpy")
    assert fast.shape == (18, 50) and np.abs(slow).max() > 1.0
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-6 * np.abs(slow).max())
    np.testing.assert_allclose(fast[12:], slow[12:], rtol=0, atol=1e-12 * np.abs(slow).max())  # both exact in q̈
    # against central differences of the weighted sum (no kernel involved): their own error is
    # ~1e-10 here, a forward step of 1e-8 (the numpy path) is 4e-8 to 1.3e-7 off
    total = lambda a, b, c: np.einsum("kjp,kjp->k", weights, regressor(spec, a, b, c).reshape(50, 6, 78))  # noqa: E731
    h, e = 1e-6, np.eye(6)
    central = np.stack([(total(q + h * e[j], qd, qdd) - total(q - h * e[j], qd, qdd)) / (2 * h) for j in range(6)]
                       + [(total(q, qd + h * e[j], qdd) - total(q, qd - h * e[j], qdd)) / (2 * h) for j in range(6)])
    if kernel_available():
        np.testing.assert_allclose(fast[:12], central, rtol=0, atol=1e-8 * np.abs(central).max())
    np.testing.assert_allclose(slow[:12], central, rtol=0, atol=1e-5 * np.abs(central).max())
    with pytest.raises(ValueError, match="weights"):
        weighted_state_derivatives(spec, q, qd, qdd, weights[:, :, :70], 1e-8)


def test_threaded_kernel_equals_single_thread(rng, monkeypatch):
    spec = load_robot("ur10e")
    q, qd, qdd = rng.uniform(-3, 3, (3, 5000, 6))  # above the parallel threshold
    monkeypatch.setenv("URIDENT_REGRESSOR_THREADS", "3")
    threaded = regressor(spec, q, qd, qdd)
    monkeypatch.setenv("URIDENT_REGRESSOR_THREADS", "1")
    single = regressor(spec, q, qd, qdd)
    assert np.array_equal(threaded, single)
    np.testing.assert_allclose(threaded, regressor(spec, q, qd, qdd, backend="numpy"), atol=1e-9)
