"""The shipped excitation designs (urident.excitation.library): current for today's robot files,
safe as written, and starts of the default search."""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml

from urident.errors import ConfigError
from urident.excitation import check_trajectory, load_trajectory, make_designs
from urident.excitation.constraints import Margins
from urident.excitation.fourier import sample_times
from urident.excitation.library import LIBRARY_FILE, load_designs, starts_for
from urident.excitation.make_designs import design_cond, recheck
from urident.excitation.optimize import ExcitationSettings, optimize_excitation
from urident.model import available_robots, load_robot


def test_every_arm_has_a_current_design_of_each_model_that_passes_the_checks():
    """Each design's cond at the controller rate is the one recorded when it was made (a changed
    robot file or criterion makes it stale: remake it, module doc), and it passes every dense check
    with the default margins (recheck); each records the seed of the long search that found it."""
    designs = load_designs()
    assert all(d.seed is not None for d in designs)
    assert sorted((d.robot, d.model) for d in designs) == sorted(
        (robot, model) for robot in available_robots() for model in ("reduced", "full"))
    for d in designs:
        assert design_cond(d) == pytest.approx(d.cond_theta, rel=1e-3), (d.robot, d.model)
        assert recheck(d) is not None, (d.robot, d.model)


def _short(**over) -> ExcitationSettings:
    return ExcitationSettings(**{**dict(reduced=True, candidates=4, starts=2, finalists=1, screen_iterations=3,
                                        iterations=6, hops=0, polish=0, workers=0), **over})


def test_the_default_search_starts_from_the_arms_shipped_designs():
    """With the library the best start is the arm's shipped design (no iterations: the result is that
    design as written, its recorded cond) and the result says it began there; without it, a search
    from random candidates ends far above."""
    spec = load_robot("ur5e")
    shipped = [d.cond_theta for d in load_designs() if d.robot == "ur5e" and d.reduced]
    assert starts_for("ur5e", 5).shape == (2, 6, 8) and starts_for("ur5e", 4).shape == (0, 6, 6)
    with_designs = optimize_excitation(spec, _short(screen_iterations=0, iterations=0))
    assert with_designs.shipped_designs == 2 and with_designs.from_shipped
    assert with_designs.criteria.cond_theta == pytest.approx(shipped[0], rel=1e-6)
    assert check_trajectory(spec, with_designs.trajectory, limits=with_designs.limits).ok
    alone = optimize_excitation(spec, _short(library=False))
    assert alone.shipped_designs == 0 and not alone.from_shipped
    assert alone.criteria.cond_theta > 1.5 * shipped[0]
    # another order has no design: the same search as without the library
    other = optimize_excitation(spec, _short(harmonics=4, duration_s=10.0))
    assert other.shipped_designs == 0
    # another seed asks for another trajectory: random candidates only, unless the designs are asked for
    assert optimize_excitation(spec, _short(seed=1, screen_iterations=0, iterations=0)).shipped_designs == 0
    forced = optimize_excitation(spec, _short(seed=1, library=True, screen_iterations=0, iterations=0))
    assert forced.shipped_designs == 2 and forced.criteria.cond_theta == pytest.approx(shipped[0], rel=1e-6)


def test_a_shipped_design_is_projected_onto_the_users_tighter_limits():
    """A design made for the default margins is a start under tighter ones too: projected, so the
    search still ends inside them (a velocity fraction of 0.5 instead of 0.8)."""
    spec = load_robot("ur10e")
    margins = Margins(velocity_fraction=0.5)
    result = optimize_excitation(spec, _short(margins=margins))
    assert result.shipped_designs == 2
    report = check_trajectory(spec, result.trajectory, limits=result.limits)
    assert report.ok
    qd = result.trajectory.evaluate(sample_times(20.0, spec.controller_rate_hz))[1]
    assert np.allclose(result.limits.qd_max, 0.5 * spec.qd_max)
    assert np.all(np.abs(qd) <= result.limits.qd_max + 1e-9)


def test_excite_records_whether_the_shipped_designs_took_part(tmp_path):
    """By default with seed 0 only; --library and --no-library say otherwise; the file records it."""
    from urident.cli.main import main

    cases = (([], 2), (["--no-library"], 0), (["--seed", "1"], 0), (["--seed", "1", "--library"], 2))
    for k, (flag, count) in enumerate(cases):
        out = tmp_path / f"t{k}.yaml"
        args = ["excite", "--robot", "ur5e", "--reduced", "--out", str(out), "--starts", "1", "--iterations", "2",
                "--quiet", *flag]
        assert main(args) == 0
        optimization = yaml.safe_load(out.read_text())["optimization"]
        assert optimization["shipped_designs"] == count
        assert load_trajectory(out).trajectory.harmonics == 5


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["designs"][0].update(free_rad_s=[[0.1] * 8] * 5), "designs[0].free_rad_s"),
    (lambda d: d["designs"][1].update(free_rad_s=[[float("nan")] * 8] * 6), "designs[1].free_rad_s"),
    (lambda d: d["designs"][0].pop("q0_rad"), "designs[0]"),
    (lambda d: d["designs"][0].update(model="tiny"), "designs[0]"),
    (lambda d: d.update(format_version=7), "format_version"),
])
def test_a_malformed_designs_file_is_one_line_naming_the_key(tmp_path, edit, key):
    document = yaml.safe_load(LIBRARY_FILE.read_text())
    edit(document)
    path = tmp_path / "designs.yaml"
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(ConfigError) as info:
        load_designs(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {key}") and "\n" not in message


def test_make_designs_keeps_the_best_of_its_seeds_and_the_shipped_design(tmp_path, monkeypatch, capsys):
    """A remake keeps the shipped design where the new searches end above it, and with --replace the
    lowest of its seeds, recording that seed; the other pairs' entries are left as they were."""
    monkeypatch.setattr(make_designs, "LONG_SEARCH", dict(candidates=4, starts=1, finalists=1, screen_iterations=3,
                                                          iterations=4, hops=0, polish=0, hop_rounds=0, workers=0))
    path = tmp_path / "designs.yaml"
    path.write_text(LIBRARY_FILE.read_text())
    shipped = {(d.robot, d.model): d for d in load_designs()}
    args = ["--robots", "ur5e", "--models", "reduced", "--seeds", "3,4", "--file", str(path)]
    assert make_designs.main(args) == 0
    assert "ur5e reduced: kept the shipped design" in capsys.readouterr().out
    kept = {(d.robot, d.model): d for d in load_designs(path)}
    assert kept.keys() == shipped.keys()
    assert np.array_equal(kept["ur5e", "reduced"].free, shipped["ur5e", "reduced"].free)
    assert make_designs.main([*args, "--replace"]) == 0
    printed = capsys.readouterr().out
    conds = {int(seed): float(cond) for seed, cond in re.findall(r"^ur5e reduced seed (\d+): cond\(Θ̄_B\) (\S+)$", printed, re.M)}
    new = {(d.robot, d.model): d for d in load_designs(path)}
    assert sorted(conds) == [3, 4] and new["ur5e", "reduced"].seed == min(conds, key=conds.get)
    assert new["ur5e", "reduced"].cond_theta > shipped["ur5e", "reduced"].cond_theta
    assert design_cond(new["ur5e", "reduced"]) == pytest.approx(new["ur5e", "reduced"].cond_theta, rel=1e-3)
    assert all(np.array_equal(new[k].free, shipped[k].free) for k in shipped if k != ("ur5e", "reduced"))
