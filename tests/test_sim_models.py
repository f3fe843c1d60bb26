"""gap --sim with the models users have: Menagerie-like, DH-built and ROS-description-like models
(tests/sim_model_fixtures.py, written here) are the robot's chain whatever their base placement,
body frames, anchors, classes, includes, angle units and absent meshes; their geometry differences
are findings; --write-sim edits them and MuJoCo / Pinocchio load the result."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from urident.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from sim_model_fixtures import dh_mjcf, menagerie_like_mjcf, ros_like_urdf  # noqa: E402

VALID = ROOT / "logs" / "sample_valid.csv"      # a UR5 log


@pytest.fixture(scope="module")
def robots():
    from urident.model import load_robot

    return {"ur5e": load_robot("ur5e"), "ur5": load_robot("ur5")}


def _states(n=12, seed=2):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.5, 2.5, (n, 6)), rng.normal(0, 1, (n, 6)), rng.normal(0, 3, (n, 6))


def _torque_on_robot_geometry(spec, p78, armature, damping, q, qd, qdd):
    from urident.model import regressor_blocks

    return regressor_blocks(spec, q, qd, qdd) @ p78 + armature * qdd + damping * qd


def _body_params(p):
    return np.array([p[10 * i:10 * i + 10] for i in range(6)])


def test_models_as_users_have_them_are_the_robots_chain_and_give_its_torques(robots, tmp_path):
    """The invariant: a model that is the robot's chain has the robot's torques for its masses.
    Menagerie-like (base turned 90°, frames turned about the axes, anchors moved along them,
    includes, classes, degrees, absent meshes, a gripper with two slide joints), DH-built (joints
    joint1…, joint 1 at the base origin) and ROS-like URDF (base_link_inertia turned by π)."""
    from urident.sim.compare import geometry_torque
    from urident.sim.models import load_sim_model

    spec, cb3 = robots["ur5e"], robots["ur5"].nominal_params      # the CB3 UR5's masses on a UR5e
    q, qd, qdd = _states()
    men = load_sim_model(menagerie_like_mjcf(spec, cb3, tmp_path / "men", round_m=0, prefix="ur5e_"), spec)
    assert men.joint_names == tuple(f"ur5e_{j.name}_joint" for j in spec.joints)
    assert men.missing_meshes and abs(men.alignment.as_dict()["yaw_deg"] + 90) < 1e-5
    dh = load_sim_model(dh_mjcf(spec, cb3, tmp_path / "dh.xml", armature=0.2, damping=3.0), spec)
    assert dh.joint_names == tuple(f"joint{i}" for i in range(1, 7))
    assert abs(abs(dh.alignment.as_dict()["yaw_deg"]) - 180) < 1e-5
    ros = load_sim_model(ros_like_urdf(spec, cb3, tmp_path / "ur.urdf"), spec)
    for sim in (men, dh, ros):
        assert sim.alignment.offset_m.max() < 1e-6 and sim.alignment.angle_rad.max() < 1e-6
        expected = _body_params(cb3)
        if sim is men:      # the gripper's 0.6 kg is link 6's
            expected[5] = sim.link_params(spec)[5]
            assert abs(expected[5, 0] - cb3[50] - 0.6) < 1e-9
        np.testing.assert_allclose(sim.link_params(spec), expected, atol=1e-8)
        drive = sim.drive()
        p78 = np.r_[sim.link_params(spec).reshape(-1), np.zeros(18)]
        np.testing.assert_allclose(sim.predict(q, qd, qdd), _torque_on_robot_geometry(
            spec, p78, drive["armature"], drive["damping"], q, qd, qdd), atol=1e-6)
        np.testing.assert_allclose(geometry_torque(sim, spec, q, qd, qdd), 0, atol=1e-6)
    np.testing.assert_allclose(men.drive()["damping"], [200, 200, 200, 15, 15, 15])
    np.testing.assert_allclose(men.drive()["armature"], 0.1)


@pytest.mark.parametrize("round_m", [0.001, 0.005])
def test_rounded_link_lengths_are_findings_with_their_torque(robots, tmp_path, round_m):
    from urident.sim.compare import format_model_against_robot, model_against_robot
    from urident.sim.models import load_sim_model

    spec = robots["ur5e"]
    sim = load_sim_model(menagerie_like_mjcf(spec, spec.nominal_params, tmp_path / "m", round_m=round_m), spec)
    off = sim.alignment.offset_m
    assert 0.1 * round_m < off.max() < 10e-3
    q, qd, qdd = _states()
    doc = model_against_robot(sim, spec, q, qd, qdd)
    assert max(doc["geometry_torque_rms_nm"]) > 1e-4
    text = "\n".join(format_model_against_robot(doc, spec, "mjcf"))
    # written back with drive corrections: MuJoCo loads it, the chain and the offsets are the same
    from urident.sim.correct import write_corrected

    changes = {k: np.zeros(6) for k in ("armature", "mass")}
    changes.update(damping=np.full(6, -10.0), frictionloss=np.full(6, 2.0), first_moment=np.zeros((6, 3)),
                   inertia=np.zeros((6, 3, 3)), payload=None)
    new = load_sim_model(write_corrected(sim, spec, changes, tmp_path / "w.xml"), spec)
    np.testing.assert_allclose(new.alignment.offset_m, off, atol=2e-6)
    np.testing.assert_allclose(new.drive()["damping"], [190, 190, 190, 5, 5, 5], rtol=1e-5)
    yaw = float(re.search(r"turned (-?[\d.]+)° about the vertical", text).group(1))
    assert abs(yaw + 90) < 0.2 and "axis line offset [mm]" in text and "link2.obj … (7 files)" in text


def test_joint_names_among_more_joints_and_an_explicit_map(robots, tmp_path):
    from urident.sim.models import SimModelError, load_sim_model

    spec = robots["ur5e"]
    path = menagerie_like_mjcf(spec, spec.nominal_params, tmp_path / "m", prefix="left_", round_m=0)
    names = [f"left_{j.name}_joint" for j in spec.joints]
    sim = load_sim_model(path, spec, joint_map={j.name: n for j, n in zip(spec.joints, names)})
    assert sim.joint_names == tuple(names) and list(sim.qpos_adr) == list(range(6))
    with pytest.raises(SimModelError, match="has no hinge joint 'nope'"):
        load_sim_model(path, spec, joint_map={**{str(i): n for i, n in enumerate(names)}, "5": "nope"})
    with pytest.raises(SimModelError, match="'foo' is not a joint of ur5e"):
        load_sim_model(path, spec, joint_map={"foo": names[0]})
    # eight hinge joints (hinged fingers): the arm's six found by their names, the fingers held
    hinged = menagerie_like_mjcf(spec, spec.nominal_params, tmp_path / "h", prefix="ur5e_", finger="hinge", round_m=0)
    sim = load_sim_model(hinged, spec)
    assert sim.joint_names == tuple(f"ur5e_{j.name}_joint" for j in spec.joints) and sim.handle.nv == 8
    q, qd, qdd = _states()
    np.testing.assert_allclose(sim.predict(q, qd, qdd), load_sim_model(path, spec).predict(q, qd, qdd), atol=1e-6)
    # a ROS description with a gripper (a revolute and a mimic finger): the fingers held
    urdf = load_sim_model(ros_like_urdf(spec, spec.nominal_params, tmp_path / "g.urdf", prefix="ur_", fingers=True), spec)
    assert urdf.joint_names == tuple(f"ur_{n}_joint" for n in ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1",
                                                                "wrist_2", "wrist_3"))
    assert urdf.handle[0].nq == 6 and abs(urdf.link_params(spec)[5, 0] - spec.nominal_params[50] - 0.1) < 1e-9
    # a map in another order is another chain
    swapped = {str(i): n for i, n in enumerate(names)}
    swapped["1"], swapped["2"] = names[2], names[1]
    with pytest.raises(SimModelError, match="not the same kinematic chain"):
        load_sim_model(path, spec, joint_map=swapped)


def test_write_sim_round_trips_each_model_and_moves_its_torque_by_the_columns(robots, tmp_path):
    """Every correction on each kind of model: MuJoCo (Pinocchio) loads the written file, its torque
    moves by exactly the corrections' columns, and what the user wrote stays."""
    from urident.ident.features import payload_columns
    from urident.model import regressor_blocks
    from urident.model.parameters import body_slice, inertia_tensor
    from urident.sim.correct import write_corrected
    from urident.sim.models import load_sim_model

    spec = robots["ur5e"]
    p = spec.nominal_params
    changes = {"armature": np.array([0.3, 0.2, 0.1, 0.05, 0.05, 0.02]), "damping": np.array([5.0, 4, 3, 1, 1, 1]),
               "frictionloss": np.array([7.0, 6, 5, 2, 2, 2]), "mass": np.array([0, 0.3, -0.2, 0, 0.1, 0]),
               "first_moment": np.zeros((6, 3)), "inertia": np.zeros((6, 3, 3)), "payload": (0.8, np.zeros(3))}
    changes["first_moment"][1] = [0.01, 0.0, 0.02]
    p10 = np.zeros(10)
    p10[4:10] = [0.002, 0.003, 0.001, 0.0002, -0.0001, 0.0003]
    changes["inertia"][3] = inertia_tensor(p10)
    delta = np.zeros(78)
    delta[body_slice(1)][:4] = [0.3, 0.01, 0.0, 0.02]
    delta[body_slice(2)][0] = -0.2
    delta[body_slice(3)] = p10
    delta[body_slice(4)][0] = 0.1
    q, qd, qdd = _states()
    blocks = regressor_blocks(spec, q, qd, qdd)
    expected = blocks @ delta + 0.8 * payload_columns(blocks, spec.tool_xyz)[:, :, 0]
    out_dir = tmp_path / "written"
    out_dir.mkdir()
    models = {"men": menagerie_like_mjcf(spec, p, tmp_path / "men", round_m=0),
              "dh": dh_mjcf(spec, p, tmp_path / "dh.xml"), "ros": ros_like_urdf(spec, p, tmp_path / "ur.urdf")}
    for key, path in models.items():
        sim = load_sim_model(path, spec)
        out = write_corrected(sim, spec, changes, out_dir / f"{key}{path.suffix}", notes=["a note"])
        new = load_sim_model(out, spec)
        text = out.read_text()
        assert "a note" in text
        np.testing.assert_allclose(new.rigid(q, qd, qdd) - sim.rigid(q, qd, qdd),
                                   expected + (changes["armature"] * qdd if sim.fmt == "mjcf" else 0), atol=2e-3)
        np.testing.assert_allclose(new.drive()["damping"], sim.drive()["damping"] + changes["damping"], rtol=1e-5)
        np.testing.assert_allclose(new.drive()["frictionloss"], changes["frictionloss"], rtol=1e-5)
        if key == "men":
            # the user's classes, actuators, keyframe, meshes (reached from the new folder), comment
            for kept in ('class="big"', 'class="small"', '<key name="home"', 'file="link3.obj"',
                         'meshdir="../men/assets/"', "kept comment", 'name="gripper"'):
                assert kept in text, kept
            # the position actuators (MuJoCo writes them in their general form): same gains and ranges
            assert new.handle.nu == 6
            np.testing.assert_allclose(new.handle.actuator_gainprm[:, 0], sim.handle.actuator_gainprm[:, 0])
            np.testing.assert_allclose(new.handle.actuator_biasprm[:, :3], sim.handle.actuator_biasprm[:, :3])
            np.testing.assert_allclose(new.handle.actuator_forcerange, sim.handle.actuator_forcerange)
            np.testing.assert_allclose(new.handle.jnt_range[:6], sim.handle.jnt_range[:6], rtol=1e-5)
            np.testing.assert_allclose(new.drive()["armature"], 0.1 + changes["armature"], rtol=1e-5)
        if key == "ros":
            for kept in ("base_link_inertia", 'name="flange"', 'name="tool0"', 'name="payload"'):
                assert kept in text, kept


def test_negative_payload_takes_the_model_s_gripper_off(robots, tmp_path):
    """A model carrying a gripper the arm does not: the payload finding is negative; written into
    link 6 (the gripper body lumped into the wrist's), MuJoCo's torque moves by its columns."""
    from urident.ident.features import payload_columns
    from urident.model import regressor_blocks
    from urident.sim.correct import unrealisable_links, write_corrected
    from urident.sim.models import load_sim_model

    spec = robots["ur5e"]
    sim = load_sim_model(menagerie_like_mjcf(spec, spec.nominal_params, tmp_path / "m", round_m=0), spec)
    changes = {k: np.zeros(6) for k in ("armature", "damping", "frictionloss", "mass")}
    changes.update(first_moment=np.zeros((6, 3)), inertia=np.zeros((6, 3, 3)), payload=(-0.5, np.zeros(3)))
    assert unrealisable_links(sim, spec, changes) == []
    new = load_sim_model(write_corrected(sim, spec, changes, tmp_path / "off.xml"), spec)
    q, qd, qdd = _states()
    blocks = regressor_blocks(spec, q, qd, qdd)
    np.testing.assert_allclose(new.rigid(q, qd, qdd) - sim.rigid(q, qd, qdd),
                               -0.5 * payload_columns(blocks, spec.tool_xyz)[:, :, 0], atol=2e-3)


def test_gap_sim_on_a_menagerie_like_model_reports_and_writes_it(robots, tmp_path, capsys):
    """The CLI end to end on the UR5 sample log: the model's base placement, offsets, masses and
    drive terms are reported, damping 200 is corrected towards the log's viscous friction, and the
    written model (MuJoCo) shrinks the residual as predicted."""
    spec = robots["ur5"]
    model = menagerie_like_mjcf(spec, spec.nominal_params, tmp_path / "m", prefix="ur5_", gripper=False)
    out, js = tmp_path / "fixed.xml", tmp_path / "gap.json"
    assert main(["gap", "--robot", "ur5", "--sim", str(model), "--valid", str(VALID), "--write-sim", str(out),
                 "--json-out", str(js), "--max-effects", "14", "--effects", "current_offset"]) == 0
    text = capsys.readouterr().out
    yaw = float(re.search(r"turned (-?[\d.]+)° about the vertical", text).group(1))
    assert abs(yaw + 90) < 0.1 and re.search(r"damping \[N·m·s/rad\]\s+200\.00", text), text
    assert "mesh files not found" in text and "written values (model → written)" in text
    doc = json.loads(js.read_text())
    against = doc["baseline"]["sim_model"]["against_robot_file"]
    assert max(against["alignment"]["axis_offset_mm"]) < 2.0 and against["armature_kg_m2"] == [0.1] * 6
    written = doc["sim_corrected"]["values"]
    truth = spec.arrays["viscous_friction"]
    assert all(abs(written["damping"][j] - truth[j]) < 0.5 * truth[j] + 1 for j in range(3))
    before, after = np.array(doc["baseline"]["rms_nm"]), np.array(doc["sim_corrected"]["rms_nm"])
    predicted = np.array(doc["sim_predicted"]["rms_nm"])
    big = before > 0.3
    assert np.all(after[big] <= 0.5 * before[big])
    np.testing.assert_allclose(100 * (1 - after / before)[big], 100 * (1 - predicted / before)[big], atol=10)


def test_joint_map_flag_is_validated(capsys):
    code = main(["gap", "--robot", "ur5", "--sim", "x.xml", "--valid", str(VALID), "--joint-map", "a,b"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--joint-map" in err and "6 joint names" in err and err.count("\n") == 0
    code = main(["gap", "--robot", "ur5", "--valid", str(VALID), "--joint-map", "a,b,c,d,e,f"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--joint-map needs --sim MODEL" in err
