"""urident export: MJCF and URDF of an identified model, checked in MuJoCo and Pinocchio."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import yaml

from urident.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
LOGS = ROOT / "logs"


@pytest.fixture(scope="module")
def params_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("export")
    paper = out / "paper.yaml"
    assert main(["identify", str(LOGS / "sample_ident.csv"), "--robot", "ur5", "--method", "all",
                 "--out", str(paper)]) == 0
    stribeck = out / "stribeck.yaml"
    assert main(["identify", str(LOGS / "sample_ident.csv"), "--robot", "ur5", "--method", "consistent",
                 "--friction-extra", "stribeck", "--out", str(stribeck)]) == 0
    return {"paper": paper, "ols": out / "paper.ols.yaml", "stribeck": stribeck}


def _prediction(params_path, log):
    from urident.ident import load_params, predict_recordings
    from urident.logs import load_log

    params = load_params(params_path)
    return params, predict_recordings(params, [load_log(log, robot=params.robot)])


def test_mujoco_inverse_dynamics_of_the_exported_mjcf_reproduces_the_prediction(params_files, tmp_path, capsys):
    import mujoco  # the dev extra brings it

    from urident.sim.mujoco_model import inverse_dynamics, load_model

    xml = tmp_path / "ur5.xml"
    assert main(["export", str(params_files["paper"]), "--mjcf", str(xml)]) == 0
    assert "every identified term is expressed" in capsys.readouterr().out
    model = load_model(xml)
    assert model.nv == 6 and model.njnt == 6
    params, pred = _prediction(params_files["paper"], LOGS / "sample_valid.csv")
    d = pred.data
    tau = inverse_dynamics(model, d.q, d.qd, d.qdd)
    measured = np.sqrt(np.mean(d.tau ** 2, axis=0))
    diff = np.sqrt(np.mean((tau - pred.tau_predicted) ** 2, axis=0))
    assert np.all(diff <= 0.02 * measured), diff / measured
    # without frictionloss MuJoCo is the prediction minus the tanh Coulomb term, to rounding
    fc = params.standard[-6:]
    rest = inverse_dynamics(model, d.q, d.qd, d.qdd, frictionloss=False)
    np.testing.assert_allclose(rest, pred.tau_predicted - fc * np.tanh(d.qd / params.model.friction_eps),
                               atol=1e-6 * np.max(np.abs(pred.tau_predicted)))
    # armature and damping are the rotor inertia and the viscous friction
    np.testing.assert_allclose(model.dof_armature, params.standard[-18:-12], rtol=1e-9)
    np.testing.assert_allclose(model.dof_damping, params.standard[-12:-6], rtol=1e-9)
    np.testing.assert_allclose(model.dof_frictionloss + model.tendon_frictionloss, fc, rtol=1e-9)
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tool0") >= 0
    assert model.ngeom == 7   # the robot file's capsules: base and one per link


def test_exported_urdf_reloads_in_pinocchio_with_the_rigid_body_part(params_files, tmp_path):
    import pinocchio as pin

    from urident.ident import load_params
    from urident.logs import load_log
    from urident.model import load_robot, regressor_blocks

    urdf = tmp_path / "ur5.urdf"
    assert main(["export", str(params_files["paper"]), "--urdf", str(urdf)]) == 0
    params = load_params(params_files["paper"])
    spec = load_robot("ur5")
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    rec = load_log(LOGS / "sample_valid.csv", robot="ur5")
    rng = np.random.default_rng(0)
    idx = rng.choice(len(rec.t), 50, replace=False)
    qdd = rng.normal(0, 2, (50, 6))
    rigid = regressor_blocks(spec, rec.q[idx], rec.qd[idx], qdd)[:, :, :60] @ params.standard[:60]
    for k, i in enumerate(idx):
        np.testing.assert_allclose(pin.rnea(model, data, rec.q[i], rec.qd[i], qdd[k]), rigid[k],
                                   rtol=1e-9, atol=1e-9)
    text = urdf.read_text()
    assert text.count("<cylinder") == 7 and "<dynamics damping=" in text
    assert "not expressed: reflected rotor inertia" in text


def test_export_lists_the_terms_the_format_cannot_express_with_their_share(params_files, tmp_path, capsys):
    xml, urdf = tmp_path / "a.xml", tmp_path / "a.urdf"
    assert main(["export", str(params_files["stribeck"]), "--mjcf", str(xml), "--urdf", str(urdf),
                 "--valid", str(LOGS / "sample_valid.csv")]) == 0
    out = capsys.readouterr().out
    mjcf_part, urdf_part = out.split("(URDF)")
    assert "Stribeck" in mjcf_part and "rotor inertia" not in mjcf_part
    assert "Stribeck" in urdf_part and "rotor inertia" in urdf_part
    line = next(l for l in mjcf_part.splitlines() if "Stribeck" in l)
    shares = [float(v.rstrip("%")) for v in line.split(":")[-1].split()]
    assert len(shares) == 6 and max(shares) > 0.5
    # the share is the Stribeck columns' torque over the measured torque
    from urident.ident.design import design_blocks

    params, pred = _prediction(params_files["stribeck"], LOGS / "sample_valid.csv")
    d = pred.data
    cols = [k for k, kind in enumerate(params.kinds) if kind == "stribeck"]
    torque = design_blocks(load_robot_spec(), params.model, d.q, d.qd, d.qdd, d.segment, d.t)[:, :, cols] \
        @ params.values[cols]
    expected = 100 * np.sqrt(np.mean(torque ** 2, 0)) / np.sqrt(np.mean(d.tau ** 2, 0))
    np.testing.assert_allclose(shares, expected, atol=0.051)
    assert "Stribeck" in xml.read_text().split("<compiler")[0]   # in the header comment


def load_robot_spec():
    from urident.model import load_robot

    return load_robot("ur5")


def test_export_refuses_parameters_that_are_not_physically_consistent(params_files, tmp_path, capsys):
    assert main(["export", str(params_files["ols"]), "--mjcf", str(tmp_path / "x.xml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no physically consistent estimate" in err
    data = yaml.safe_load(params_files["paper"].read_text())
    data["standard_parameters"][10]["value"] = -1.0          # body 2's mass
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["export", str(bad), "--urdf", str(tmp_path / "x.urdf")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "body 2 has mass -1 kg" in err and str(bad) in err
    assert not (tmp_path / "x.urdf").exists() and not (tmp_path / "x.xml").exists()


def test_export_outputs_are_checked_before_work(params_files, tmp_path, capsys):
    xml = tmp_path / "m.xml"
    xml.write_text("keep")
    assert main(["export", str(params_files["paper"]), "--mjcf", str(xml)]) == 2
    assert "--mjcf" in capsys.readouterr().err and xml.read_text() == "keep"
    assert main(["export", str(params_files["paper"]), "--mjcf", str(xml), "--overwrite"]) == 0
    assert xml.read_text().startswith("<?xml")
    assert main(["export", str(params_files["paper"])]) == 2


def test_only_urident_sim_mujoco_model_imports_mujoco():
    importers = []
    for path in sorted((ROOT / "urident").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            if any(n == "mujoco" or n.startswith("mujoco.") for n in names):
                importers.append(path.relative_to(ROOT).as_posix())
    assert set(importers) == {"urident/sim/mujoco_model.py"}


def test_mjcf_of_the_real_ur10e_estimate_reproduces_its_prediction_in_mujoco(tmp_path):
    from shared_data import UR10E_DATA

    ident, valid = UR10E_DATA / "ur-20_02_10-30sec_12harm.csv", UR10E_DATA / "ur-20_01_17-ptp_10_points.csv"
    if not (ident.exists() and valid.exists()):
        pytest.skip("UR10e data absent")
    from urident.ident import load_params, predict_recordings
    from urident.logs import load_log
    from urident.sim.mujoco_model import inverse_dynamics, load_model

    params = tmp_path / "ur10e.yaml"
    assert main(["identify", str(ident), "--robot", "ur10e", "--format", "dynamic_calibration", "--rows",
                 "635-3510", "--method", "consistent", "--out", str(params)]) == 0
    xml = tmp_path / "ur10e.xml"
    assert main(["export", str(params), "--mjcf", str(xml)]) == 0
    model = load_model(xml)       # a principal moment at the SDP's boundary is raised, not refused
    p = load_params(params)
    pred = predict_recordings(p, [load_log(valid, robot="ur10e", rows=(700, 4200), format="dynamic_calibration")])
    d = pred.data
    diff = np.sqrt(np.mean((inverse_dynamics(model, d.q, d.qd, d.qdd) - pred.tau_predicted) ** 2, axis=0))
    assert np.all(diff <= 0.02 * np.sqrt(np.mean(d.tau ** 2, axis=0)))


def test_mujoco_inertia_raises_only_what_mujoco_refuses():
    from urident.sim.mjcf import MIN_PRINCIPAL_INERTIA, mujoco_inertia

    good = np.diag([0.1, 0.2, 0.25])
    same, changed = mujoco_inertia(good)
    assert not changed and same is good
    flat = np.diag([0.1, 0.1, 0.0])
    fixed, changed = mujoco_inertia(flat)
    eig = np.linalg.eigvalsh(fixed)
    assert changed and eig.min() >= MIN_PRINCIPAL_INERTIA and np.abs(fixed - flat).max() < 1e-8
    rod = np.diag([0.0, 0.1, 0.1 + 1e-7])       # triangle inequality broken by 1e-7
    fixed, _ = mujoco_inertia(rod)
    a, b, c = np.sort(np.linalg.eigvalsh(fixed))
    assert a + b >= c and np.abs(fixed - rod).max() < 1e-6


def test_export_nominal_writes_the_robot_files_values(tmp_path, capsys):
    from urident.model import load_robot
    from urident.sim.mujoco_model import load_model

    xml = tmp_path / "n.xml"
    assert main(["export", "--nominal", "--robot", "ur10e", "--mjcf", str(xml)]) == 0
    spec = load_robot("ur10e")
    model = load_model(xml)
    np.testing.assert_allclose(model.dof_armature, spec.arrays["rotor_inertia"])
    np.testing.assert_allclose(model.dof_damping, spec.arrays["viscous_friction"])
    np.testing.assert_allclose(model.body_mass[1:7], [j.mass for j in spec.joints])
    assert "nominal values" in xml.read_text().split("<compiler")[0]
    assert main(["export", "--nominal", "--mjcf", str(tmp_path / "m.xml")]) == 2
    assert "--nominal needs --robot" in capsys.readouterr().err


def test_export_payload_is_a_body_on_the_flange_in_mujoco_and_pinocchio(params_files, tmp_path, capsys):
    import mujoco

    from urident.ident import load_params, predict_recordings
    from urident.model.payload import Payload
    from urident.ident.payload_file import save_payload
    from urident.logs import load_log
    from urident.model import load_robot
    from urident.sim.models import load_sim_model
    from urident.sim.mujoco_model import inverse_dynamics, load_model

    a = np.array([[2.0, 0.3, -0.2], [0.3, 3.0, 0.1], [-0.2, 0.1, 4.0]]) * 1e-3
    payload = Payload("ur5", 2.5, [0.01, -0.02, 0.06], a)
    path = tmp_path / "payload.yaml"
    save_payload(payload, path)
    xml, urdf = tmp_path / "ur5.xml", tmp_path / "ur5.urdf"
    assert main(["export", str(params_files["paper"]), "--payload", str(path), "--mjcf", str(xml),
                 "--urdf", str(urdf)]) == 0
    assert "payload" in xml.read_text().split("<compiler")[0]
    model = load_model(xml)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "payload")
    assert b >= 0 and model.body_parentid[b] == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                                                    "wrist_3_link")
    assert model.body_mass[b] == pytest.approx(2.5)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tool0")
    flange_r, flange_p = data.site_xmat[site].reshape(3, 3), data.site_xpos[site]
    np.testing.assert_allclose(data.xipos[b], flange_p + flange_r @ payload.com_m, atol=1e-12)
    r = data.ximat[b].reshape(3, 3)
    in_flange = flange_r.T @ r @ np.diag(model.body_inertia[b]) @ r.T @ flange_r
    np.testing.assert_allclose(in_flange, a, atol=1e-9)
    # MuJoCo's inverse dynamics with the payload is urident's prediction with the payload
    params = load_params(params_files["paper"])
    pred = predict_recordings(params, [load_log(LOGS / "sample_valid.csv", robot="ur5")], payload=payload)
    d = pred.data
    without = predict_recordings(params, [load_log(LOGS / "sample_valid.csv", robot="ur5")])
    tau = inverse_dynamics(model, d.q, d.qd, d.qdd)
    measured = np.sqrt(np.mean(d.tau ** 2, axis=0))
    diff = np.sqrt(np.mean((tau - pred.tau_predicted) ** 2, axis=0))
    assert np.all(diff <= 0.02 * measured), diff / measured
    # ... and the payload is felt: the prediction without it is further off than that on joints 2-3
    off = np.sqrt(np.mean((tau - without.tau_predicted) ** 2, axis=0))
    assert np.all(off[1:3] > 5 * diff[1:3]), (off, diff)
    # the URDF's rigid-body part with the payload link is urident's, to rounding (Pinocchio)
    spec = load_robot("ur5")
    sim = load_sim_model(urdf, spec)
    rigid = sim.rigid(d.q, d.qd, d.qdd)
    from urident.model import regressor_blocks
    from urident.model.parameters import DRIVE, body_slice

    p = params.standard.copy()
    p[body_slice(5)] += payload.body_params(spec)
    p[DRIVE] = 0
    np.testing.assert_allclose(rigid, regressor_blocks(spec, d.q, d.qd, d.qdd) @ p, atol=1e-9 * np.abs(rigid).max())


def test_export_names_each_joints_coulomb_state(params_files, tmp_path, capsys):
    """A model whose joints carry their own Coulomb state (``--preset auto``) is described per joint."""
    from dataclasses import replace

    from urident.ident import load_params, save_params

    params = load_params(params_files["stribeck"])
    states = ("dahl@0.0002", "tanh", "tanh", "dahl@5e-05", "tanh", "tanh")
    mixed = replace(params, model=replace(params.model, joint_coulomb=states))
    save_params(mixed, tmp_path / "mixed.yaml")
    xml = tmp_path / "m.xml"
    assert main(["export", str(tmp_path / "mixed.yaml"), "--mjcf", str(xml)]) == 0
    out = capsys.readouterr().out
    header = xml.read_text().split("<compiler")[0]
    per_joint = "per joint: J1 dahl@0.0002, J2 tanh, J3 tanh, J4 dahl@5e-05, J5 tanh, J6 tanh"
    assert f"Coulomb model {per_joint}" in header and "Coulomb model tanh" not in header
    assert f"Coulomb friction state ({per_joint})" in out
