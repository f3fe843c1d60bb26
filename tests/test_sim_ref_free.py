"""A user's MJCF with a joint ``ref`` ≠ 0 or the arm on a free joint (as some downloaded scenes
have it): read as the same arm, with a one-line note each (fixtures written here)."""

from __future__ import annotations

import re

import numpy as np
import pytest

pytest.importorskip("mujoco")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    from urident.model import load_robot
    from urident.sim.mjcf import downloaded_like_standard, write_mjcf

    spec = load_robot("ur5")
    p = downloaded_like_standard(spec)
    p[-18:] = np.r_[np.full(6, 0.1), np.full(6, 2.0), np.full(6, 1.5)]     # armature, damping, friction
    return spec, write_mjcf(spec, p, tmp_path_factory.mktemp("reffree") / "ur5.xml")


def _states(n=40):
    rng = np.random.default_rng(5)
    return rng.uniform(-2, 2, (n, 6)), rng.uniform(-1, 1, (n, 6)), rng.uniform(-3, 3, (n, 6))


def test_a_joint_ref_is_an_offset_of_the_joints_zero(exported, tmp_path):
    from urident.sim.compare import format_model_against_robot, model_against_robot
    from urident.sim.correct import write_corrected
    from urident.sim.models import load_sim_model

    spec, xml = exported
    text = xml.read_text()
    assert '<joint name="elbow"' in text
    ref = tmp_path / "ref.xml"
    ref.write_text(text.replace('<joint name="elbow"', '<joint name="elbow" ref="0.3"').replace(
        '<joint name="wrist_2"', '<joint name="wrist_2" ref="-1.2"'))
    plain, shifted = load_sim_model(xml, spec), load_sim_model(ref, spec)
    q, qd, qdd = _states()
    np.testing.assert_allclose(shifted.predict(q, qd, qdd), plain.predict(q, qd, qdd), atol=1e-9)
    assert shifted.alignment.offset_m.max() < 1e-9 and not plain.notes
    assert [re.search(r"name='(\w+)'", n).group(1) for n in shifted.notes] == ["elbow", "wrist_2"]
    assert "ref = 0.3 rad" in shifted.notes[0] and "qpos = q + ref" in shifted.notes[0]
    lines = format_model_against_robot(model_against_robot(shifted, spec), spec, "mjcf")
    assert sum("note: <joint name='elbow'> has ref" in line for line in lines) == 1
    # --write-sim keeps the refs, and the written model is read the same way
    changes = {"armature": np.zeros(6), "damping": np.array([0, 0, 3.0, 0, 0, 0]), "frictionloss": np.zeros(6),
               "mass": np.zeros(6), "first_moment": np.zeros((6, 3))}
    again = load_sim_model(write_corrected(shifted, spec, changes, tmp_path / "out.xml"), spec)
    assert len(again.notes) == 2
    np.testing.assert_allclose(again.predict(q, qd, qdd) - shifted.predict(q, qd, qdd),
                               np.outer(np.ones(len(q)), changes["damping"]) * qd, atol=1e-3)


def test_an_arm_on_a_free_joint_is_held_at_its_qpos0(exported, tmp_path, capsys):
    from urident.cli.main import main
    from urident.sim.models import load_sim_model

    spec, xml = exported
    text = xml.read_text()
    yaw = 0.7
    base = (f'<body name="base" pos="0.4 -0.2 0.8" quat="{np.cos(yaw / 2)} 0 0 {np.sin(yaw / 2)}">'
            '<freejoint name="arm_free"/><inertial pos="0 0 0" mass="4" diaginertia="0.01 0.01 0.01"/>')
    free = tmp_path / "free.xml"
    free.write_text(text.replace('<body name="shoulder_pan_link"', base + '<body name="shoulder_pan_link"', 1)
                    .replace("</worldbody>", "</body></worldbody>"))
    plain, held = load_sim_model(xml, spec), load_sim_model(free, spec)
    q, qd, qdd = _states()
    np.testing.assert_allclose(held.predict(q, qd, qdd), plain.predict(q, qd, qdd), atol=1e-9)
    assert abs(np.rad2deg(held.alignment.yaw) + np.rad2deg(yaw)) < 1e-6
    assert len(held.notes) == 1 and "<joint name='arm_free' type='free'>: held still at its qpos0" in held.notes[0]
    # --write-sim keeps the free joint; the written model is read the same way
    from urident.sim.correct import write_corrected

    changes = {"armature": np.zeros(6), "damping": np.array([2.5, 0, 0, 0, 0, 0]), "frictionloss": np.zeros(6),
               "mass": np.zeros(6), "first_moment": np.zeros((6, 3))}
    again = load_sim_model(write_corrected(held, spec, changes, tmp_path / "out.xml"), spec)
    assert again.notes == held.notes
    np.testing.assert_allclose(again.predict(q, qd, qdd) - held.predict(q, qd, qdd),
                               np.outer(np.ones(len(q)), changes["damping"]) * qd, atol=1e-3)
    assert main(["gap", "--robot", "ur5", "--sim", str(free), "--valid", "logs/sample_valid.csv", "--rows",
                 "1-1500", "--max-effects", "2", "--effects", "current_offset"]) == 0
    out = capsys.readouterr().out
    assert "note: <joint name='arm_free' type='free'>" in out
