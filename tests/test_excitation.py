"""Excitation trajectories: Fourier series at rest, capsule distances against coal, the dense check,
trajectory files, the CLI and the optimiser (small sizes)."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from urident.cli.main import main
from urident.errors import ConfigError, SafetyError
from urident.excitation import (FourierTrajectory, Limits, Margins, check_trajectory, load_trajectory,
                                sample, trajectory_document, write_trajectory)
from urident.excitation import collision
from urident.excitation.collision import CoalDistances, capsule_model, segment_distances
from urident.excitation.fourier import FourierBasis, base_frequency, free_coefficients, rest_elimination
from urident.excitation.optimize import (PAPER_Q0, ExcitationProblem, ExcitationSettings,
                                         optimize_excitation, random_feasible_criteria)
from urident.excitation.criteria import evaluate_criteria
from urident.model import load_robot
from urident.model.base import base_parameters

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
SMALL = dict(harmonics=3, duration_s=8.0, reduced=True, candidates=6, starts=1, iterations=12,
             criterion_samples=60, collision_samples=160, limit_samples=300)


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


def random_trajectory(rng, harmonics=4, duration=10.0, omega=None, scale=0.3):
    free = rng.normal(size=(6, 2 * (harmonics - 1))) * scale
    omega = base_frequency(duration) if omega is None else omega
    return FourierTrajectory.from_free(free, omega, rng.uniform(-1, 1, 6), duration)


def feasible_trajectory(spec, seed=3, harmonics=3, duration=8.0):
    """A small, safe trajectory about the paper's offsets (random, shrunk until collision-free)."""
    settings = ExcitationSettings(**{**SMALL, "harmonics": harmonics, "duration_s": duration})
    problem = ExcitationProblem(spec, settings)
    x = problem.random_coefficients(np.random.default_rng(seed), 1)
    x = problem.shrink_to_collision_free(x, factor=0.8)[0] * 0.5
    traj = problem.trajectory(x)
    assert check_trajectory(spec, traj, collision_backend="numpy").ok
    return traj


# -- Fourier series ------------------------------------------------------------------------------

def test_rest_at_start_and_end_and_periodic(rng):
    for harmonics in (2, 3, 5, 8):
        duration = rng.uniform(5, 30)
        periods = int(rng.integers(1, 4))
        traj = random_trajectory(rng, harmonics, duration, base_frequency(duration, periods), scale=1.0)
        q, qd, qdd = traj.evaluate(np.array([0.0, duration]))
        np.testing.assert_allclose(qd, 0.0, atol=1e-12)
        np.testing.assert_allclose(qdd, 0.0, atol=1e-11)
        np.testing.assert_allclose(q[0], q[1], atol=1e-12)
        np.testing.assert_allclose(traj.q_start, q[0])
        # ... but it does move in between.
        assert np.abs(traj.evaluate(np.linspace(0, duration, 50))[1]).max() > 0.1


def test_rest_constraint_per_joint_frequency(rng):
    duration = 12.0
    omega = base_frequency(duration) * np.array([1, 2, 1, 3, 1, 2])
    traj = random_trajectory(rng, 4, duration, omega)
    _, qd, qdd = traj.evaluate(np.array([0.0, duration]))
    np.testing.assert_allclose(qd, 0.0, atol=1e-12)
    np.testing.assert_allclose(qdd, 0.0, atol=1e-11)


def test_rest_elimination_satisfies_the_linear_constraint(rng):
    for harmonics in (2, 4, 7):
        e = rest_elimination(harmonics)
        coeffs = e @ rng.normal(size=2 * (harmonics - 1))
        a, b = coeffs[:harmonics], coeffs[harmonics:]
        assert abs(a.sum()) < 1e-12
        assert abs((np.arange(1, harmonics + 1) * b).sum()) < 1e-12
    with pytest.raises(ValueError, match="at least 2 harmonics"):
        rest_elimination(1)


def test_matches_paper_eq25_for_one_joint(rng):
    traj = random_trajectory(rng, 5, 20.0)
    t = rng.uniform(0, 20, 30)
    w = traj.omega[1]
    expected = traj.q0[1] + sum(traj.a[1, k] / (w * (k + 1)) * np.sin(w * (k + 1) * t)
                                - traj.b[1, k] / (w * (k + 1)) * np.cos(w * (k + 1) * t) for k in range(5))
    np.testing.assert_allclose(traj.evaluate(t)[0][:, 1], expected, atol=1e-12)


def test_analytic_derivatives_match_finite_differences(rng):
    traj = random_trajectory(rng, 5, 10.0, scale=1.0)
    t = rng.uniform(0.1, 9.9, 40)
    h = 1e-6
    q_p, qd_p, _ = traj.evaluate(t + h)
    q_m, qd_m, _ = traj.evaluate(t - h)
    _, qd, qdd = traj.evaluate(t)
    np.testing.assert_allclose((q_p - q_m) / (2 * h), qd, atol=1e-7)
    np.testing.assert_allclose((qd_p - qd_m) / (2 * h), qdd, atol=1e-6)


def test_basis_and_free_coefficients_reproduce_evaluate(rng):
    traj = random_trajectory(rng, 4, 10.0)
    free = free_coefficients(traj)
    again = FourierTrajectory.from_free(free, traj.omega, traj.q0, traj.duration)
    np.testing.assert_allclose(again.a, traj.a)
    np.testing.assert_allclose(again.b, traj.b)
    t = np.linspace(0, 10, 37)
    basis = FourierBasis.build(t, traj.omega, 4)
    dq, qd, qdd = (x[0] for x in basis.evaluate(free[None]))
    q_ref, qd_ref, qdd_ref = traj.evaluate(t)
    np.testing.assert_allclose(dq + traj.q0, q_ref, atol=1e-12)
    np.testing.assert_allclose(qd, qd_ref, atol=1e-12)
    np.testing.assert_allclose(qdd, qdd_ref, atol=1e-12)
    # the optimiser's single-set path: the same products, bit for bit
    assert all(np.array_equal(a, b) for a, b in zip(basis.evaluate_one(free), (dq, qd, qdd)))
    assert np.array_equal(basis.evaluate_one(free, "qd")[0], qd)


def test_sample_at_controller_rate(rng):
    traj = random_trajectory(rng, 3, 2.0)
    t, q, qd, qdd = sample(traj, 125.0)
    assert t.shape == (251,) and q.shape == qd.shape == qdd.shape == (251, 6)
    assert t[-1] == pytest.approx(2.0) and np.allclose(np.diff(t), 1 / 125)
    assert q.dtype == np.float64


def test_invalid_trajectory_arguments():
    with pytest.raises(ValueError, match="duration"):
        FourierTrajectory(np.zeros((6, 2)), np.zeros((6, 2)), 1.0, np.zeros(6), 0.0)
    with pytest.raises(ValueError, match=r"\(6, L\)"):
        FourierTrajectory(np.zeros((5, 2)), np.zeros((5, 2)), 1.0, np.zeros(6), 1.0)
    with pytest.raises(ValueError, match="finite"):
        FourierTrajectory(np.full((6, 2), np.nan), np.zeros((6, 2)), 1.0, np.zeros(6), 1.0)


# -- collision distances --------------------------------------------------------------------------

def test_segment_distances_against_dense_sampling(rng):
    p1, q1, p2, q2 = rng.normal(size=(4, 80, 3))
    q2[:20] = p2[:20] + (q1[:20] - p1[:20]) * 0.7   # parallel segments
    q1[20:30] = p1[20:30]                           # a point
    q2[25:35] = p2[25:35]                           # points
    d = segment_distances(p1, q1, p2, q2)
    s = np.linspace(0, 1, 201)
    a = p1[:, None] + (q1 - p1)[:, None] * s[None, :, None]
    b = p2[:, None] + (q2 - p2)[:, None] * s[None, :, None]
    brute = np.linalg.norm(a[:, :, None] - b[:, None, :], axis=-1).min(axis=(1, 2))
    assert np.all(d <= brute + 1e-12)
    np.testing.assert_allclose(d, brute, atol=1e-2)


@pytest.mark.parametrize("name", ["ur5", "ur5e"])
def test_numpy_capsule_distances_equal_coal(name, rng):
    spec = load_robot(name)
    capsules = capsule_model(spec, 0.05, floor_height_m=-0.01)
    q = rng.uniform(-np.pi, np.pi, (300, 6))
    d_np = capsules.distances(spec, q)
    d_coal = CoalDistances(spec, capsules).distances(q)
    assert (d_np < 0).any() and (d_np > 0).any()   # both collisions and free configurations
    np.testing.assert_allclose(d_np, d_coal, atol=1e-9)


def test_compiled_capsule_distances_equal_numpy_with_degenerate_capsules(ur5, rng):
    assert collision.kernel_available()   # CI installs with a compiler; numpy is the fallback
    capsules = capsule_model(ur5, 0.05, floor_height_m=-0.01)
    b = capsules.b.copy()
    b[[1, 4]] = capsules.a[[1, 4]]             # two capsules shrunk to spheres (degenerate segments)
    for model in (capsules, replace(capsules, b=b)):
        q = rng.uniform(-2 * np.pi, 2 * np.pi, (500, 6))
        np.testing.assert_allclose(model.distances(ur5, q), model.numpy_distances(ur5, q), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="capsule kernel"):   # an index past the capsules
        replace(capsules, first=capsules.first + len(capsules.frame)).distances(ur5, q)


@pytest.mark.parametrize("name", ["ur5", "ur10e"])
def test_capsule_distance_jacobians_match_finite_differences(name, rng):
    spec = load_robot(name)
    capsules = capsule_model(spec, 0.05, floor_height_m=-0.01)
    q = rng.uniform(-np.pi, np.pi, (200, 6))
    d, jac = capsules.distance_jacobians(spec, q)
    np.testing.assert_allclose(d, capsules.distances(spec, q), atol=1e-12)
    h = 1e-6
    fd = np.stack([(capsules.distances(spec, q + h * e) - capsules.distances(spec, q - h * e)) / (2 * h)
                   for e in np.eye(6)], axis=-1)
    assert np.abs(jac).max() > 0.1            # the distances do move with the joints
    np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-7)
    where = rng.random(d.shape) < 0.2        # only some entries (the optimiser's: those inside a clearance)
    partial = capsules.distance_derivatives(spec, q, where)
    assert np.array_equal(partial[where], jac[where]) and not partial[~where].any()
    b = capsules.b.copy()
    b[[1, 4]] = capsules.a[[1, 4]]             # two capsules shrunk to spheres (degenerate segments)
    for model in (capsules, replace(capsules, b=b)):  # the compiled kernel against the numpy formulas
        np.testing.assert_allclose(model.distance_derivatives(spec, q, where),
                                   model.numpy_distance_derivatives(spec, q, where), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="capsule kernel"):   # an index past the capsules
        replace(capsules, second=capsules.second + len(capsules.frame)).distance_derivatives(spec, q, where)


def test_required_distances_relax_only_pairs_close_by_construction(ur5):
    capsules = capsule_model(ur5, 0.05)
    required = dict(zip(capsules.pair_names, capsules.required))
    assert required["elbow_0/wrist_2_0"] == -np.inf          # constant 3 mm apart: not checked
    assert 0 < required["base_0/shoulder_lift_0"] < 0.05     # never more than 38 mm apart
    assert required["shoulder_lift_0/wrist_3_0"] == 0.05
    assert required["wrist_3_0/floor"] == 0.05
    assert sum(r == 0.05 for r in capsules.required) >= len(capsules.required) - 4


# -- dense check ----------------------------------------------------------------------------------

def test_check_accepts_a_safe_trajectory(ur5):
    traj = feasible_trajectory(ur5)
    report = check_trajectory(ur5, traj)
    assert report.ok and not report.violations
    assert report.n_samples == 8 * 125 + 1 and report.rate_hz == 125
    for constraint in ("position", "velocity", "acceleration", "torque", "rest"):
        assert report.margins[constraint].shape == (6,) and np.all(report.margins[constraint] >= 0)
    assert report.min_distance_m > 0 and report.collision_margin_m >= 0
    report.raise_if_unsafe("x.yaml")  # no error
    assert json.loads(json.dumps(report.as_dict()))["ok"] is True


def test_check_rejects_velocity_violation_on_the_right_joint(ur5):
    traj = feasible_trajectory(ur5)
    limits = Limits.from_robot(ur5)
    factor = 1.05 * limits.qd_max[2] / np.abs(sample(traj, 1000)[2][:, 2]).max()
    fast = traj.scaled([1, 1, factor, 1, 1, 1])
    report = check_trajectory(ur5, fast, limits=limits, collision_backend="numpy")
    velocity = [v for v in report.violations if v.constraint == "velocity"]
    assert [v.where for v in velocity] == ["elbow"]
    assert velocity[0].margin < 0 and report.margins["velocity"][2] < 0
    assert np.all(report.margins["velocity"][[0, 1, 3, 4, 5]] > 0)
    t_worst = velocity[0].time_s
    assert abs(fast.evaluate(t_worst)[1][0, 2]) > limits.qd_max[2]
    with pytest.raises(SafetyError, match=r"^bad\.yaml: unsafe trajectory: .*joint 3 \(elbow\) at t = "):
        report.raise_if_unsafe("bad.yaml")


def test_check_rejects_floor_collision_position_and_rest(ur5):
    flat = FourierTrajectory(np.zeros((6, 2)), np.zeros((6, 2)), 1.0, np.zeros(6), 2.0)  # arm horizontal
    report = check_trajectory(ur5, flat)
    assert "shoulder_lift_0/floor" in {v.where for v in report.violations if v.constraint == "collision"}
    assert not [v for v in report.violations if v.constraint != "collision"]
    near_limit = FourierTrajectory(np.zeros((6, 2)), np.zeros((6, 2)), 1.0,
                                   np.array(PAPER_Q0) + [0, 0, 3.0, 0, 0, 0], 2.0)
    report = check_trajectory(ur5, near_limit, collision_backend="numpy")
    assert ("position", "elbow") in {(v.constraint, v.where) for v in report.violations}
    restless = FourierTrajectory(np.full((6, 2), 0.1), np.zeros((6, 2)), np.pi, np.array(PAPER_Q0), 2.0)
    report = check_trajectory(ur5, restless, collision_backend="numpy")
    assert {v.where for v in report.violations if v.constraint == "rest"} == set(ur5.joint_names)


# -- trajectory files -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def good_file(tmp_path_factory, ur5):
    traj = feasible_trajectory(ur5)
    path = tmp_path_factory.mktemp("traj") / "good.yaml"
    doc = trajectory_document("ur5", traj, Limits.from_robot(ur5), {"criterion": "cond", "seed": 3},
                              {"cond_theta": 123.0}, {"min_distance_m": 0.04})
    write_trajectory(path, doc, header="test trajectory")
    return path, traj


def test_file_round_trip(good_file, ur5):
    path, traj = good_file
    loaded = load_trajectory(path)
    assert loaded.robot == "ur5" and loaded.spec.name == "ur5"
    np.testing.assert_array_equal(loaded.trajectory.a, traj.a)
    np.testing.assert_array_equal(loaded.trajectory.b, traj.b)
    np.testing.assert_array_equal(loaded.trajectory.q0, traj.q0)
    assert loaded.trajectory.duration == traj.duration
    np.testing.assert_array_equal(loaded.trajectory.q_start, traj.q_start)
    assert loaded.margins == Margins() and loaded.limits.clearance_m == 0.05
    assert loaded.criterion == "cond" and loaded.criteria["cond_theta"] == 123.0
    assert loaded.min_distance_m == 0.04
    with pytest.raises(Exception):
        loaded.robot = "x"  # frozen


def _mutated(good_path, tmp_path, mutate):
    doc = yaml.safe_load(good_path.read_text())
    mutate(doc)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    return bad


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["trajectory"].update(amplitude=1), r"trajectory.amplitude: unknown key"),
    (lambda d: d.update(extra=1), r"extra: unknown key"),
    (lambda d: d["trajectory"]["a_rad_s"].pop(), r"trajectory.a_rad_s: must be a 6x3 list"),
    (lambda d: d["trajectory"]["b_rad_s"][2].append(0.0), r"trajectory.b_rad_s: must be a 6x3"),
    (lambda d: d["trajectory"]["q0_rad"].__setitem__(1, float("nan")), r"trajectory.q0_rad: must hold finite"),
    (lambda d: d["trajectory"].update(duration_s=0.0), r"trajectory.duration_s: must be positive"),
    (lambda d: d["trajectory"].update(duration_s=-3), r"trajectory.duration_s: must be positive"),
    (lambda d: d["trajectory"].update(base_frequency_rad_s="fast"), r"trajectory.base_frequency_rad_s: has the wrong type"),
    (lambda d: d.update(robot="ur99"), r"robot: unknown robot 'ur99'"),
    (lambda d: d["trajectory"].pop("harmonics"), r"trajectory.harmonics: missing key"),
    (lambda d: d["limits"].update(velocity_fraction=1.5), r"limits: velocity_fraction must be in"),
    (lambda d: d["limits"]["qd_max_rad_s"].__setitem__(0, 9.0), r"limits.qd_max_rad_s: does not match"),
    (lambda d: d["trajectory"]["q_start_rad"].__setitem__(0, 1.0), r"trajectory.q_start_rad: does not match"),
    (lambda d: d.update(format_version=2), r"format_version: 2 is not supported"),
    (lambda d: d["optimization"].update(seed=[1]), r"optimization.seed: must be a finite number"),
])
def test_malformed_files_are_rejected_naming_file_and_key(good_file, tmp_path, mutate, message):
    bad = _mutated(good_file[0], tmp_path, mutate)
    with pytest.raises(ConfigError, match=r"bad\.yaml: .*" + message) as info:
        load_trajectory(bad)
    assert "\n" not in str(info.value)


def test_yaml_syntax_error_names_the_line(tmp_path):
    bad = tmp_path / "syntax.yaml"
    bad.write_text("format: urident-excitation-trajectory\nformat_version: 1\nrobot: [ur5\n")
    with pytest.raises(ConfigError, match=r"syntax\.yaml:\d+: malformed YAML"):
        load_trajectory(bad)
    with pytest.raises(ConfigError, match="not found"):
        load_trajectory(tmp_path / "missing.yaml")


# -- CLI ------------------------------------------------------------------------------------------

def test_cli_check_trajectory_ok_and_json(good_file, capsys):
    path, _ = good_file
    assert main(["check-trajectory", str(path)]) == 0
    out = capsys.readouterr().out
    assert "velocity" in out and "ok" in out
    assert main(["check-trajectory", str(path), "--json", "--rate", "50"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] and report["rate_hz"] == 50 and report["n_samples"] == 8 * 50 + 1


def test_cli_check_trajectory_rejects_violation(ur5, tmp_path, capsys):
    traj = feasible_trajectory(ur5)
    limits = Limits.from_robot(ur5)
    factor = 1.1 * limits.qd_max[4] / np.abs(sample(traj, 1000)[2][:, 4]).max()
    path = tmp_path / "fast.yaml"
    write_trajectory(path, trajectory_document("ur5", traj.scaled([1, 1, 1, 1, factor, 1]), limits))
    assert main(["check-trajectory", str(path)]) == SafetyError.exit_code
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith(f"urident: error: {path}: unsafe trajectory:")
    assert "joint 5 (wrist_2)" in err and "margin -" in err
    assert main(["check-trajectory", str(tmp_path / "nope.yaml")]) == ConfigError.exit_code


def test_cli_excite_writes_a_checked_file(tmp_path, capsys):
    out = tmp_path / "small.yaml"
    code = main(["excite", "--robot", "ur5", "--out", str(out), "--harmonics", "2", "--duration", "6",
                 "--iterations", "4", "--starts", "1", "--reduced", "--seed", "5", "--budget", "600", "--quiet"])
    assert code == 0
    printed = capsys.readouterr().out
    # 4 iterations on the search's grid, then the polish's 4 on the finer one
    assert "cond" in printed and "search: stopped at the iteration limit after 8 iterations" in printed
    loaded = load_trajectory(out)
    assert loaded.trajectory.harmonics == 2 and loaded.trajectory.duration == 6.0
    assert loaded.optimization["seed"] == 5 and loaded.optimization["reduced"] is True
    assert loaded.criteria["cond_lambda"] == pytest.approx(loaded.criteria["cond_theta"] ** 2)
    assert loaded.check["ok"] is True and loaded.check["min_distance_m"] > 0
    assert loaded.optimization["stop_reason"] == "iterations" and loaded.optimization["converged"] is False
    assert loaded.optimization["budget_s"] == 600
    assert check_trajectory(loaded.spec, loaded.trajectory, limits=loaded.limits).ok


# -- optimiser ------------------------------------------------------------------------------------

def test_optimized_cond_beats_random_and_is_reproducible(ur5):
    # two starts screened, one continued: the result does not depend on where the starts run (two
    # worker processes, or this one)
    settings = ExcitationSettings(**{**SMALL, "starts": 2, "finalists": 1, "screen_iterations": 4, "hop_rounds": 1},
                                  seed=7)
    first = optimize_excitation(ur5, replace(settings, workers=2))
    second = optimize_excitation(ur5, replace(settings, workers=0))
    np.testing.assert_array_equal(first.trajectory.a, second.trajectory.a)
    report = check_trajectory(ur5, first.trajectory, limits=first.limits)
    assert report.ok
    _, qd, qdd = first.trajectory.evaluate(np.array([0.0, settings.duration_s]))
    assert np.abs(qd).max() < 1e-9 and np.abs(qdd).max() < 1e-9
    random = random_feasible_criteria(ur5, settings, 30, seed=1)
    assert first.coarse_criteria.cond_theta < np.median(random)
    assert first.criteria.cond_lambda == pytest.approx(first.criteria.cond_theta ** 2)
    # the search's iterations, then as many polishing on the finer grid
    assert first.convergence.iterations == 2 * settings.iterations and first.convergence.reason == "iterations"


def test_perturbed_restarts_keep_the_best_and_stop_at_the_evaluation_cap(ur5):
    # each round of restarts from the best adds its starts; the result is the best of all, so never
    # worse; no round starts once the search used hop_evaluations
    settings = ExcitationSettings(**{**SMALL, "starts": 2, "finalists": 1, "screen_iterations": 4, "polish": 0},
                                  seed=3, workers=0)
    without = optimize_excitation(ur5, replace(settings, hops=0))
    with_hops = optimize_excitation(ur5, replace(settings, hops=2, hop_rounds=2))
    assert len(with_hops.history) == len(without.history) + 4
    assert with_hops.history[:2] == without.history
    assert min(with_hops.history) <= min(without.history)
    assert check_trajectory(ur5, with_hops.trajectory, limits=with_hops.limits).ok
    capped = optimize_excitation(ur5, replace(settings, hops=2, hop_rounds=2, hop_evaluations=without.evaluations))
    assert capped.history == without.history
    for bad in ({"hops": -1}, {"hop_rounds": -1}, {"hop_evaluations": -1}):
        with pytest.raises(ValueError, match="hops"):
            ExcitationSettings(**bad)


def test_finalised_selection_ranks_the_finalists_as_written(ur5):
    # the same search; 'finalised' ranks each finalist after it is made collision-free without the
    # search's buffer, so what is written is never worse on the criterion grid than the default's pick
    settings = ExcitationSettings(**{**SMALL, "starts": 2, "finalists": 1, "screen_iterations": 4, "hop_rounds": 2},
                                  seed=6, workers=0, collision_buffer_m=0.015)
    plain = optimize_excitation(ur5, replace(settings, select="objective"))
    chosen = optimize_excitation(ur5, settings)          # the default
    assert settings.select == "finalised"
    assert chosen.history == plain.history
    assert chosen.coarse_criteria.cond_theta <= plain.coarse_criteria.cond_theta * (1 + 1e-9)
    assert check_trajectory(ur5, chosen.trajectory, limits=chosen.limits).ok
    with pytest.raises(ValueError, match="select"):
        ExcitationSettings(select="penalty")


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the overflowing trials this test is about
def test_a_line_search_trial_beyond_the_limits_is_refused_not_raised(ur5):
    # a wide collision buffer made BFGS try coefficients whose regressor overflows (NaN in eigh)
    settings = ExcitationSettings(**{**SMALL, "starts": 2, "finalists": 1, "screen_iterations": 4, "hop_rounds": 2},
                                  seed=1, workers=0, collision_buffer_m=0.03)
    result = optimize_excitation(ur5, settings)
    assert np.isfinite(result.criteria.cond_theta)
    assert check_trajectory(ur5, result.trajectory, limits=result.limits).ok


def test_polish_continues_the_best_on_the_finer_criterion_grid(ur5):
    # the search's criterion is on criterion_samples; the polish continues the best on polish_samples,
    # (within the start's iteration limit), and the reported coarse criterion and the iteration count
    # include it
    settings = ExcitationSettings(**{**SMALL, "starts": 2, "finalists": 1, "screen_iterations": 4, "hops": 0,
                                     "iterations": 40, "window": 5, "tolerance": 5e-2}, seed=3, workers=0)
    plain = optimize_excitation(ur5, replace(settings, polish=0))
    polished = optimize_excitation(ur5, replace(settings, polish=1, polish_samples=90))
    assert plain.coarse_criteria.n_samples == settings.criterion_samples
    assert polished.coarse_criteria.n_samples == 90
    assert plain.convergence.iterations < polished.convergence.iterations <= 2 * settings.iterations
    assert check_trajectory(ur5, polished.trajectory, limits=polished.limits).ok
    # the polish has its own tolerance (tighter than the search's by default) and iteration cap
    assert settings.polish_tolerance < settings.tolerance
    loose = optimize_excitation(ur5, replace(settings, polish=1, polish_samples=90, polish_tolerance=5e-2))
    tight = optimize_excitation(ur5, replace(settings, polish=1, polish_samples=90, polish_tolerance=0.0))
    assert loose.convergence.iterations < tight.convergence.iterations
    assert min(tight.history) <= min(loose.history)
    capped = optimize_excitation(ur5, replace(settings, polish=1, polish_samples=90, polish_iterations=3))
    assert plain.convergence.iterations < capped.convergence.iterations <= plain.convergence.iterations + 3
    for bad in ({"polish": -1}, {"polish_iterations": -1}, {"polish_tolerance": -1.0}):
        with pytest.raises(ValueError, match="polish"):
            ExcitationSettings(**bad)
    with pytest.raises(ValueError, match="polish"):
        ExcitationSettings(polish_samples=0)


def counts_as_fields(counts: dict) -> dict:
    return {"criterion_samples": counts["criterion"], "polish_samples": counts["polish"],
            "collision_samples": counts["collision"], "limit_samples": counts["limits"]}


def test_search_grids_follow_the_highest_harmonic(ur5):
    # a fixed count aliases Λ once the trajectory has more cycles: the counts scale with
    # harmonics · periods unless set, and the problem and the written file use the scaled ones
    default = ExcitationSettings()
    counts = {g: default.samples(g) for g in ("criterion", "polish", "collision", "limits")}
    assert counts == {"criterion": 60, "polish": 100, "collision": 200, "limits": 400}
    four = replace(default, periods=4)
    assert all(four.samples(g) == 4 * n for g, n in counts.items())
    assert replace(four, harmonics=2).samples("criterion") == 60 * 2 * 4 // 5
    assert replace(four, criterion_samples=70).samples("criterion") == 70     # set: kept
    # at most one per controller tick (20 s at 125 Hz: 2,500), a count set is kept
    many = replace(default, harmonics=10, periods=10).resolved(125.0)
    assert (many.criterion_samples, many.polish_samples, many.collision_samples, many.limit_samples) \
        == (1200, 2000, 2500, 2500)
    assert replace(default, harmonics=10, periods=10, limit_samples=9000).resolved(125.0).limit_samples == 9000
    assert default.resolved(500.0) == replace(default, **counts_as_fields(counts))
    problem = ExcitationProblem(ur5, replace(four, reduced=True))
    assert (len(problem.basis_criterion.t), len(problem.basis_collision.t), len(problem.basis_limits.t)) \
        == (240, 800, 1600)
    # on four periods the default order's 60 samples misstate cond: the scaled grid is near the dense one
    traj = load_trajectory(EXPERIMENTS / "ur5e_sim_gap.yaml")
    spec, T = traj.spec, traj.trajectory.duration
    base = base_parameters(spec)
    cond = lambda n: evaluate_criteria(spec, base, *traj.trajectory.evaluate(np.arange(n) * (T / n))).cond_theta  # noqa: E731
    dense = cond(int(T * spec.controller_rate_hz))
    assert abs(cond(four.samples("criterion")) / dense - 1) < 0.02 < abs(cond(60) / dense - 1)


@pytest.mark.parametrize("criterion", ["cond", "logdet"])
@pytest.mark.parametrize("scale", [1.0, 1.4])  # feasible, and past the limits and collision clearance
def test_objective_gradient_matches_finite_differences(ur5, criterion, scale):
    problem = ExcitationProblem(ur5, ExcitationSettings(**SMALL, criterion=criterion))
    x = problem.shrink_to_collision_free(problem.random_coefficients(np.random.default_rng(4), 1))[0]
    x = (x * scale).ravel()
    value, grad = problem.value_and_gradient(x)
    # λ_min of Λ is only defined to about eps·cond Λ (here 1e-11) and the two paths use different
    # LAPACK solvers (against 40-digit eigenvalues: the search's 1.4e-11 off, value()'s 6e-11)
    assert value == pytest.approx(problem.value(x.reshape(1, 6, -1))[0], rel=1e-10)
    h = 1e-5
    fd = np.array([(problem.value((x + h * e).reshape(1, 6, -1))[0]
                    - problem.value((x - h * e).reshape(1, 6, -1))[0]) / (2 * h) for e in np.eye(x.size)])
    assert np.max(np.abs(grad - fd)) < 1e-3 * np.max(np.abs(fd))


def test_search_converges_or_stops_at_the_budget_and_says_so(ur5):
    settings = ExcitationSettings(**{**SMALL, "iterations": 400, "window": 10, "tolerance": 5e-3}, seed=3,
                                  workers=0)
    done = optimize_excitation(ur5, settings)
    c = done.convergence
    assert c.converged and c.iterations < 400 and c.improvement < settings.tolerance
    assert "converged after" in c.describe("cond") and done.convergence.as_dict()["converged"] is True
    cut = optimize_excitation(ur5, replace(settings, budget_s=1e-3))
    assert cut.convergence.reason == "budget" and not cut.convergence.converged
    assert cut.convergence.iterations < c.iterations
    assert "stopped by the time budget" in cut.convergence.describe("cond")
    assert check_trajectory(ur5, cut.trajectory, limits=cut.limits).ok


# -- shipped experiments --------------------------------------------------------------------------

@pytest.mark.parametrize("robot", ["ur5", "ur5e"])
def test_shipped_experiment_files_are_safe_and_distinct(robot):
    ident = load_trajectory(EXPERIMENTS / f"{robot}_ident.yaml")
    valid = load_trajectory(EXPERIMENTS / f"{robot}_valid.yaml")
    for f in (ident, valid):
        assert f.robot == robot
        assert f.trajectory.harmonics == 5 and f.trajectory.duration == 20.0
        np.testing.assert_allclose(f.trajectory.q0, PAPER_Q0)
        # the default margins, but |q̇| at 0.7 of the limit where servoJ's lag asks for it (experiments/README.md)
        assert f.margins.velocity_fraction in (Margins().velocity_fraction, 0.7)
        assert replace(f.margins, velocity_fraction=Margins().velocity_fraction) == Margins()
        report = check_trajectory(f.spec, f.trajectory, limits=f.limits)
        assert report.ok, report.violations[:1]
    assert not np.allclose(ident.trajectory.a, valid.trajectory.a)
