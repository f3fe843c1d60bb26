"""gap --sim MODEL: a simulator model as the gap's baseline, --write-sim, and bad model files."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from urident.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
VALID = ROOT / "logs" / "sample_valid.csv"      # a UR5 log


@pytest.fixture(scope="module")
def ur5_models(tmp_path_factory):
    from urident.ident.urdf import write_urdf
    from urident.model import load_robot
    from urident.sim.mjcf import downloaded_like_standard, write_mjcf

    out = tmp_path_factory.mktemp("simgap")
    spec = load_robot("ur5")
    p = downloaded_like_standard(spec)
    return {"spec": spec, "p": p, "xml": write_mjcf(spec, p, out / "ur5.xml"),
            "urdf": write_urdf(spec, p, out / "ur5.urdf"), "dir": out}


def _gap(model, capsys, robot="ur5", extra=()):
    code = main(["gap", "--robot", robot, "--sim", str(model), "--valid", str(VALID), *extra])
    err = capsys.readouterr().err.strip()
    return code, err


def _edit(src: Path, dst: Path, old: str, new: str, count: int = 1) -> Path:
    text = src.read_text()
    assert old in text
    dst.write_text(text.replace(old, new, count))
    return dst


def test_a_model_of_another_arm_is_refused_naming_the_joint(ur5_models, capsys):
    code, err = _gap(ur5_models["xml"], capsys, robot="ur5e")
    assert code == 2 and err.count("\n") == 0
    assert re.search(r"<joint name='\w+'> \(ur5e's joint \d, \w+\): its axis line is [\d.]+ mm from the robot's "
                     r"after aligning the bases \(limit 10 mm\): not the same kinematic chain", err), err


def test_axes_and_link_lengths_beyond_the_limits_are_refused_below_them_findings(ur5_models, capsys, tmp_path):
    from urident.sim.models import load_sim_model

    bad = _edit(ur5_models["xml"], tmp_path / "axis.xml", 'axis="0 1 0"', 'axis="0 1 0.05"')
    code, err = _gap(bad, capsys)
    assert code == 2 and re.search(r"<joint name='shoulder_lift'> \(ur5's joint 2, shoulder_lift\): its axis is "
                                   r"2\.\d\d° from the robot's", err), err
    flipped = _edit(ur5_models["xml"], tmp_path / "flip.xml", 'axis="0 1 0"', 'axis="0 -1 0"')
    code, err = _gap(flipped, capsys)
    assert code == 2 and "<joint name='shoulder_lift'>" in err and "points the other way" in err, err
    text = ur5_models["xml"].read_text()
    pos = re.search(r'<body name="elbow_link" pos="([^"]+)"', text).group(1)
    x, y, z = map(float, pos.split())
    longer = _edit(ur5_models["xml"], tmp_path / "long.xml", f'pos="{pos}"', f'pos="{x} {y} {z + 0.03}"')
    code, err = _gap(longer, capsys)
    assert code == 2 and "its axis line is" in err and "limit 10 mm" in err, err
    # 2 mm longer upper arm and a slightly tilted axis: the same chain, the offsets are findings
    close = _edit(ur5_models["xml"], tmp_path / "close.xml", f'pos="{pos}"', f'pos="{x} {y} {z + 0.002}"')
    sim = load_sim_model(close, ur5_models["spec"])
    assert sim.joint_names[2] == "elbow"
    assert 0.5e-3 < sim.alignment.offset_m.max() <= 2.0e-3 and sim.alignment.angle_rad.max() < 1e-4
    tilted = load_sim_model(_edit(ur5_models["xml"], tmp_path / "t.xml", 'axis="0 1 0"', 'axis="0 1 0.01"'),
                            ur5_models["spec"])
    assert abs(tilted.alignment.angle_rad[1] - 0.01) < 1e-3


def test_unparsable_and_incomplete_models_name_the_element(ur5_models, capsys, tmp_path):
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody>")
    code, err = _gap(broken, capsys)
    assert code == 2 and "broken.xml: not valid XML" in err
    unknown = _edit(ur5_models["xml"], tmp_path / "unknown.xml", "<worldbody>", '<worldbody><geom typo="1"/>')
    code, err = _gap(unknown, capsys)
    assert code == 2 and "MuJoCo cannot load it" in err and "typo" in err and err.count("\n") == 0
    text = ur5_models["xml"].read_text()
    start = text.index('<joint name="wrist_3"')
    short = tmp_path / "short.xml"
    short.write_text(text[:start] + re.sub(r'<(motor|general) name="wrist_3"[^>]*/>', "",
                                           text[text.index("/>", start) + 2:]))
    code, err = _gap(short, capsys)
    assert code == 2 and "5 hinge joints, ur5 has 6" in err, err
    slide = _edit(ur5_models["xml"], tmp_path / "slide.xml", '<joint name="shoulder_pan"',
                  '<joint name="shoulder_pan" type="slide"')
    code, err = _gap(slide, capsys)
    assert code == 2 and "<joint name='shoulder_pan' type='slide'>" in err


def test_urdf_mimic_and_continuous_joints_are_refused(ur5_models, capsys, tmp_path):
    cont = _edit(ur5_models["urdf"], tmp_path / "c.urdf", '<joint name="wrist_3" type="revolute">',
                 '<joint name="wrist_3" type="continuous">')
    code, err = _gap(cont, capsys)
    assert code == 2 and "<joint name='wrist_3' type='continuous'>" in err
    mimic = _edit(ur5_models["urdf"], tmp_path / "m.urdf", '<joint name="wrist_2" type="revolute">',
                  '<joint name="wrist_2" type="revolute"><mimic joint="wrist_1"/>')
    code, err = _gap(mimic, capsys)
    assert code == 2 and "<joint name='wrist_2'> has a <mimic> element" in err
    code, err = _gap(ur5_models["urdf"], capsys, extra=["--write-sim", str(tmp_path / "x.xml")])
    assert code == 2 and "--write-sim" in err and "URDF" in err


def test_write_sim_changes_exactly_what_it_says(ur5_models, tmp_path):
    from urident.model import regressor_blocks
    from urident.sim.correct import write_corrected
    from urident.sim.models import load_sim_model

    spec = ur5_models["spec"]
    sim = load_sim_model(ur5_models["xml"], spec)
    changes = {"armature": np.array([0.3, 0, 0, 0, 0, 0.01]), "damping": np.array([0, 4.0, 0, 0, 0, 0]),
               "frictionloss": np.array([0, 0, 5.0, 0, 0, 0]), "mass": np.array([0, 0, 0.5, 0, 0, 0]),
               "first_moment": np.zeros((6, 3)), "payload": (1.5, np.zeros(3))}
    changes["first_moment"][2] = [0.002, 0.001, 0.02]
    out = write_corrected(sim, spec, changes, tmp_path / "corrected.xml", notes=["a note"])
    new = load_sim_model(out, spec)
    assert "a note" in out.read_text()
    # MuJoCo's writer keeps 6 significant digits
    np.testing.assert_allclose(new.handle.dof_armature, sim.handle.dof_armature + changes["armature"], rtol=1e-5)
    np.testing.assert_allclose(new.handle.dof_damping, changes["damping"], rtol=1e-5)
    np.testing.assert_allclose(new.handle.dof_frictionloss.sum() + new.handle.tendon_frictionloss.sum(), 5.0, rtol=1e-5)
    # gravity torques at rest: exactly the mass/first-moment change and a point mass at the tool
    rng = np.random.default_rng(3)
    q = rng.uniform(-2, 2, (20, 6))
    zero = np.zeros_like(q)
    blocks = regressor_blocks(spec, q, zero, zero)
    delta = np.zeros(blocks.shape[2])
    delta[20:24] = [0.5, 0.002, 0.001, 0.02]
    from urident.ident.features import payload_columns

    expected = blocks @ delta + 1.5 * payload_columns(blocks, spec.tool_xyz)[:, :, 0]
    np.testing.assert_allclose(new.predict(q, zero, zero) - sim.predict(q, zero, zero), expected, atol=2e-4)
    # in motion too: the correction keeps the link's inertia about its joint frame, as its columns do
    qd, qdd = rng.normal(0, 1, q.shape), rng.normal(0, 3, q.shape)
    blocks = regressor_blocks(spec, q, qd, qdd)
    expected = blocks @ delta + 1.5 * payload_columns(blocks, spec.tool_xyz)[:, :, 0] + changes["armature"] * qdd
    np.testing.assert_allclose(new.rigid(q, qd, qdd) - sim.rigid(q, qd, qdd), expected, atol=1e-4)


def test_gap_sim_names_the_missing_drive_terms_and_mujoco_measures_the_written_model(ur5_models, tmp_path, capsys):
    from urident.ident import load_params

    # the baseline: a consistent estimate exported without its drive terms (armature, damping, frictionloss)
    params = tmp_path / "p.yaml"
    assert main(["identify", str(ROOT / "logs" / "sample_ident.csv"), "--robot", "ur5", "--method",
                 "consistent", "--out", str(params)]) == 0
    standard = load_params(params).standard.copy()
    standard[-18:] = 0
    from urident.sim.mjcf import write_mjcf

    bare = write_mjcf(ur5_models["spec"], standard, tmp_path / "bare.xml")
    out, js = tmp_path / "fixed.xml", tmp_path / "gap.json"
    capsys.readouterr()
    assert main(["gap", "--robot", "ur5", "--sim", str(bare), "--valid", str(VALID), "--write-sim", str(out),
                 "--json-out", str(js)]) == 0
    doc = json.loads(js.read_text())
    from urident.gap.schema import errors

    assert errors(doc) == []                  # the shipped schema: no NaN, None, infinity
    first = doc["findings"][0]
    assert first["effect"] in ("frictionloss", "damping", "armature") and first["expressible"] is True
    for f in doc["findings"]:
        assert f["expressible"] == (f["effect"] in ("armature", "damping", "frictionloss", "rigid_body", "link_inertia",
                                                    "payload_error"))
    # values of the final joint fit, where both terms of a joint were found: within 10 % of the
    # truth, the drive terms the sample logs were simulated with (the robot file's; logs/make_samples.py),
    # not the removed estimate, which carries the realistic effects' bias of its own log
    spec = ur5_models["spec"]
    found = {(f["effect"], f["joint"]): f["final_magnitude"] for f in doc["findings"]}
    both = [j for j in range(1, 7) if ("damping", j) in found and ("frictionloss", j) in found]
    assert len(both) >= 2, found
    for j in both:
        fc, fv = spec.arrays["coulomb_friction"][j - 1], spec.arrays["viscous_friction"][j - 1]
        assert abs(found[("frictionloss", j)]["frictionloss_nm"] - fc) <= 0.1 * fc
        assert abs(found[("damping", j)]["damping_nm_s_per_rad"] - fv) <= 0.1 * fv
    assert all(f["written_magnitude"] is not None for f in doc["findings"] if f["expressible"])
    before = np.array(doc["baseline"]["rms_nm"])
    measured = np.array(doc["sim_corrected"]["rms_nm"])
    predicted = np.array(doc["sim_predicted"]["rms_nm"])
    big = before > 0.5
    assert np.all(measured[big] < before[big])
    np.testing.assert_allclose(100 * (1 - measured[big] / before[big]), 100 * (1 - predicted[big] / before[big]),
                               atol=3.0)


def test_downloaded_like_ur5e_mjcf_against_a_realistic_run(tmp_path):
    """The acceptance scenario of benchmarks/sim_gap.py: nominal masses, cylinder inertias, no drive
    terms; a validation run of the simulated controller with the realistic effects (offline) on the
    fast validation trajectory, where every joint's armature is above the noise."""
    from urident.gap.sim_baseline import DRIVE_EFFECTS
    from urident.model import load_robot
    from urident.model.parameters import body_slice
    from urident.sim.mjcf import downloaded_like_standard, write_mjcf

    spec = load_robot("ur5e")
    downloaded = downloaded_like_standard(spec)
    model = write_mjcf(spec, downloaded, tmp_path / "downloaded.xml")
    log = tmp_path / "valid.csv"
    assert main(["simulate", "--trajectory", str(ROOT / "experiments" / "ur5e_sim_gap.yaml"), "--out", str(log),
                 "--effects", "realistic"]) == 0
    js = tmp_path / "gap.json"
    # the catalogue effects that bias the drive terms on this run (offsets, the 3 ms delay, load
    # friction, Stribeck, joint 2's elasticity): the others only cost time here; 20 findings: the 18
    # drive terms and what comes next
    assert main(["gap", "--robot", "ur5e", "--sim", str(model), "--valid", str(log), "--write-sim",
                 str(tmp_path / "fixed.xml"), "--json-out", str(js), "--max-effects", "20",
                 "--effects", "current_offset,current_delay,load_friction,stribeck,joint_elasticity"]) == 0
    doc = json.loads(js.read_text())
    effects = [f["effect"] for f in doc["findings"]]
    # friction and armature named first: every joint's first finding is one of them, the first 12
    # findings are, and all 18 are named (the wrist's armature, 0.15-0.3 N·m, may come after the big
    # joints' offsets: findings are listed by their unique contribution)
    assert set(effects[:12]) <= set(DRIVE_EFFECTS), effects
    for j in range(1, 7):
        assert next(f["effect"] for f in doc["findings"] if f["joint"] == j) in DRIVE_EFFECTS, effects
    assert {(f["effect"], f["joint"]) for f in doc["findings"] if f["effect"] in DRIVE_EFFECTS} == {
        (e, j) for e in DRIVE_EFFECTS for j in range(1, 7)}
    assert not doc["not_identified"]
    found = {(f["effect"], f["joint"]): f["final_magnitude"] for f in doc["findings"]}
    # armature as the data show it: rotor inertia plus what the model's link inertia errors add
    # along q̈_j on these states (gap --sim leaves that share to armature)
    from urident.gap.data import build_set
    from urident.logs import load_log
    from urident.model import regressor_blocks

    p = build_set([load_log(log)], spec).prepared
    bodies = np.r_[tuple(body_slice(j) for j in range(6))]
    link_error = regressor_blocks(spec, p.q, p.qd, p.qdd)[:, :, bodies] @ (spec.nominal_params - downloaded)[bodies]
    seen = spec.arrays["rotor_inertia"] + np.sum(link_error * p.qdd, axis=0) / np.sum(p.qdd ** 2, axis=0)
    for j in range(1, 7):     # the robot file's drive values are the simulated truth
        fc, fv = spec.arrays["coulomb_friction"][j - 1], spec.arrays["viscous_friction"][j - 1]
        assert abs(found[("frictionloss", j)]["frictionloss_nm"] / fc - 1) <= 0.1
        assert abs(found[("damping", j)]["damping_nm_s_per_rad"] / fv - 1) <= 0.1
        assert abs(found[("armature", j)]["armature_kg_m2"] / seen[j - 1] - 1) <= 0.1, (j, found, seen)
    before = np.array(doc["baseline"]["rms_nm"])
    after = np.array(doc["sim_corrected"]["rms_nm"])
    predicted = np.array(doc["sim_predicted"]["rms_nm"])
    noise = 0.02 * spec.drive_gains * 3       # 3 sigma of the simulated 0.02 A current noise [N·m]
    big = before > noise
    assert big.all()
    assert np.all(after[big] <= 0.5 * before[big])
    np.testing.assert_allclose(100 * (1 - after / before), 100 * (1 - predicted / before), atol=3.0)


def test_link_inertia_is_told_from_armature_only_where_the_chain_separates_them(ur5_models, tmp_path):
    """Joint 1's axis, and joint 2's (perpendicular to joint 1's), see their link's inertia about the
    axis only as I·q̈ on the joint itself, exactly as armature: those fields are folded into the
    armature; every other link's inertia field is a candidate of its own. The written correction
    changes the simulator's torque by exactly the candidate's columns."""
    from urident.gap.data import build_set
    from urident.gap.sim_baseline import INERTIA_FIELDS, link_inertia_candidates, link_inertia_columns, make_sim_context
    from urident.logs import load_log
    from urident.model import regressor_blocks
    from urident.model.parameters import body_slice, inertia_tensor
    from urident.sim.correct import write_corrected
    from urident.sim.models import load_sim_model

    spec = ur5_models["spec"]
    sim = load_sim_model(ur5_models["xml"], spec)
    ctx = make_sim_context(sim, build_set([load_log(VALID, robot="ur5")], spec))
    about_axis = {"x": "A", "y": "B", "z": "C"}
    kept, aliased = link_inertia_columns(spec, ctx, 0)
    assert kept == () and aliased == (about_axis[spec.joints[0].axis],)
    kept, aliased = link_inertia_columns(spec, ctx, 1)
    assert aliased == (about_axis[spec.joints[1].axis],) and aliased[0] not in kept and len(kept) >= 3
    for j in range(2, 6):
        assert link_inertia_columns(spec, ctx, j)[1] == ()
    assert sorted(c[0].joint for c in link_inertia_candidates(spec, ctx)) == [1, 2, 3, 4, 5]
    # an inertia change of link 3 written into the MJCF moves MuJoCo's torque by its columns
    p10 = np.zeros(10)
    p10[4:10] = [0.004, 0.01, 0.006, 0.001, -0.002, 0.0015]
    changes = {k: np.zeros(6) for k in ("armature", "damping", "frictionloss", "mass")}
    changes.update(first_moment=np.zeros((6, 3)), inertia=np.zeros((6, 3, 3)), payload=None)
    changes["inertia"][2] = inertia_tensor(p10)
    new = load_sim_model(write_corrected(sim, spec, changes, tmp_path / "inertia.xml"), spec)
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.uniform(-2, 2, (20, 6)), rng.normal(0, 1, (20, 6)), rng.normal(0, 3, (20, 6))
    delta = np.zeros(78)
    delta[body_slice(2)] = p10
    expected = regressor_blocks(spec, q, qd, qdd) @ delta
    np.testing.assert_allclose(new.rigid(q, qd, qdd) - sim.rigid(q, qd, qdd), expected, atol=1e-6)
    assert INERTIA_FIELDS == ("A", "B", "C", "D", "E", "F")


def test_write_sim_urdf_writes_links_inertia_and_payload_too(ur5_models, tmp_path):
    """URDF takes every correction but armature: <dynamics>, a link's mass, centre of mass and
    inertia, and a payload as a fixed link on the flange; Pinocchio's torque moves by exactly the
    corrections' columns."""
    from urident.ident.features import payload_columns
    from urident.model import regressor_blocks
    from urident.model.parameters import body_slice, inertia_tensor
    from urident.sim.correct import write_corrected
    from urident.sim.models import load_sim_model

    spec = ur5_models["spec"]
    sim = load_sim_model(ur5_models["urdf"], spec)
    changes = {"armature": np.zeros(6), "damping": np.array([0, 4.0, 0, 0, 0, 0]),
               "frictionloss": np.array([0, 0, 5.0, 0, 0, 0]), "mass": np.array([0, 0, 0.5, 0, 0, 0]),
               "first_moment": np.zeros((6, 3)), "inertia": np.zeros((6, 3, 3)), "payload": (1.5, np.zeros(3))}
    changes["first_moment"][2] = [0.002, 0.001, 0.02]
    p10 = np.zeros(10)
    p10[4:10] = [0.002, 0.003, 0.001, 0.0002, -0.0001, 0.0003]
    changes["inertia"][3] = inertia_tensor(p10)
    out = write_corrected(sim, spec, changes, tmp_path / "corrected.urdf", notes=["a note"])
    assert "a note" in out.read_text() and 'name="payload"' in out.read_text()
    new = load_sim_model(out, spec)
    np.testing.assert_allclose(new.damping, sim.damping + changes["damping"], atol=1e-12)
    np.testing.assert_allclose(new.friction, sim.friction + changes["frictionloss"], atol=1e-12)
    rng = np.random.default_rng(4)
    q, qd, qdd = rng.uniform(-2, 2, (20, 6)), rng.normal(0, 1, (20, 6)), rng.normal(0, 3, (20, 6))
    blocks = regressor_blocks(spec, q, qd, qdd)
    delta = np.zeros(blocks.shape[2])
    delta[body_slice(2)][:4] = [0.5, 0.002, 0.001, 0.02]
    delta[body_slice(3)] = p10
    expected = blocks @ delta + 1.5 * payload_columns(blocks, spec.tool_xyz)[:, :, 0]
    np.testing.assert_allclose(new.rigid(q, qd, qdd) - sim.rigid(q, qd, qdd), expected, atol=1e-4)
    # a correction that leaves no real mass distribution is refused, and named by unrealisable_links
    from urident.sim.correct import unrealisable_links

    bad = dict(changes, inertia=np.zeros((6, 3, 3)))
    bad["inertia"][4] = -np.eye(3)
    assert unrealisable_links(sim, spec, bad) == [4]
