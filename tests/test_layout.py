"""The one 78-parameter layout (urident.model.parameters), the column kinds an identified model
carries, and the feature columns shared by identification and the gap diagnosis."""

from __future__ import annotations

import numpy as np
import pytest

from urident.ident import ModelConfig, identify, load_params, save_params
from urident.ident.preprocess import Prepared
from urident.ident.synthetic import synthetic_recording
from urident.model import joint_torques, load_robot, regressor_blocks
from urident.model import parameters as P


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


@pytest.fixture(scope="module")
def states(spec):
    rng = np.random.default_rng(7)
    n = 40
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    qd = rng.uniform(-1, 1, (n, 6))
    qdd = rng.uniform(-3, 3, (n, 6))
    return q, qd, qdd


def test_the_layout_tiles_the_vector_and_names_kinds_and_joints_agree():
    names, kinds, joints = P.parameter_names(), P.parameter_kinds(), P.parameter_joints()
    assert len(names) == len(kinds) == len(joints) == P.N_PARAMS == 78
    covered = np.zeros(P.N_PARAMS, int)
    for sl in [P.body_slice(i) for i in range(P.N_JOINTS)] + [P.ROTOR, P.VISCOUS, P.COULOMB]:
        covered[sl] += 1
    assert (covered == 1).all()                      # each entry in exactly one block
    assert P.RIGID_BODY == slice(P.body_slice(0).start, P.body_slice(5).stop) and P.TOOL_BODY == P.body_slice(5)
    for i in range(P.N_JOINTS):
        sl = P.body_slice(i)
        assert names[sl] == [f"{f}{i + 1}" for f in P.BODY_FIELDS]
        assert set(kinds[sl]) == {P.RIGID_BODY_KIND} and (joints[sl] == i).all()
    for sl, prefix, kind in ((P.ROTOR, "IM", P.ROTOR_KIND), (P.VISCOUS, "fv", P.VISCOUS_KIND),
                             (P.COULOMB, "fc", P.COULOMB_KIND)):
        assert names[sl] == [f"{prefix}{j}" for j in range(1, 7)]
        assert set(kinds[sl]) == {kind} and (joints[sl] == np.arange(6)).all()
    assert all(P.column_kind(n) == k for n, k in zip(names, kinds))
    with pytest.raises(KeyError):
        P.column_kind("fz1")
    assert P.column_kind("fz1", "unknown") == "unknown"
    with pytest.raises(IndexError):
        P.body_slice(6)


def test_the_regressor_columns_have_the_meaning_the_layout_gives_them(spec, states):
    """Rotor columns are q̈ of their joint, viscous q̇, Coulomb tanh(q̇/ε); body i acts on joints ≤ i."""
    q, qd, qdd = states
    y = regressor_blocks(spec, q, qd, qdd, 0.01)
    j = np.arange(6)
    np.testing.assert_array_equal(y[:, j, P.ROTOR_OFFSET + j], qdd)
    np.testing.assert_array_equal(y[:, j, P.VISCOUS_OFFSET + j], qd)
    np.testing.assert_allclose(y[:, j, P.COULOMB_OFFSET + j], np.tanh(qd / 0.01))
    for i in range(6):
        assert not np.any(y[:, i + 1:, P.body_slice(i)])
        assert np.any(y[:, i, P.body_slice(i)])
    off_joint = ~np.eye(6, dtype=bool)
    for offset in (P.ROTOR_OFFSET, P.VISCOUS_OFFSET, P.COULOMB_OFFSET):
        assert not np.any(y[:, :, offset:offset + 6][:, off_joint])


def test_the_nominal_vector_is_the_robot_files_links_and_drives(spec):
    p = spec.nominal_params
    assert p.shape == (P.N_PARAMS,)
    for i, joint in enumerate(spec.joints):
        np.testing.assert_array_equal(p[P.body_slice(i)], P.body_params(joint.mass, joint.com, joint.inertia_com))
    np.testing.assert_array_equal(p[P.ROTOR], spec.arrays["rotor_inertia"])
    np.testing.assert_array_equal(p[P.VISCOUS], spec.arrays["viscous_friction"])
    np.testing.assert_array_equal(p[P.COULOMB], spec.arrays["coulomb_friction"])
    with pytest.raises(ValueError, match="78-vector"):
        P.check_standard(np.zeros(77))


def test_a_payload_on_the_tool_body_is_what_the_feature_columns_say(spec, states):
    """Adding a point mass to the last body's ten parameters changes the model's torque by exactly
    features.payload_torque, and features.payload_columns' first column is 1 kg at the tool."""
    from urident.ident import features
    from urident.ident.torque import payload_params, payload_torque

    q, qd, qdd = states
    p10 = payload_params(2.5, [0.01, -0.02, 0.05])
    with_payload = spec.nominal_params + P.tool_body_vector(p10)
    expected = joint_torques(spec, with_payload, q, qd, qdd) - joint_torques(spec, spec.nominal_params, q, qd, qdd)
    blocks = regressor_blocks(spec, q, qd, qdd)
    np.testing.assert_allclose(features.payload_torque(blocks, p10), expected, atol=1e-9)
    np.testing.assert_allclose(payload_torque(spec, q, qd, qdd, p10), expected, atol=1e-9)
    cols = features.payload_columns(blocks, spec.tool_xyz)
    unit = P.body_params(1.0, np.asarray(spec.tool_xyz, float), np.zeros((3, 3)))
    np.testing.assert_allclose(cols[:, :, 0], features.payload_torque(blocks, unit))
    np.testing.assert_array_equal(cols[:, :, 1:], blocks[:, :, P.TOOL_BODY][:, :, 1:4])


@pytest.fixture(scope="module")
def identified(spec):
    rec, qdd, tau = synthetic_recording(spec, duration_s=8.0, rate_hz=125.0, seed=4)
    data = Prepared(rec.t, rec.q, rec.qd, qdd, tau, spec.drive_gains)
    return identify(spec, data, "ols", ModelConfig(extras=("offset", "stribeck", "load", "sqrtvisc"))), data


def test_an_identified_model_carries_its_column_kinds_also_through_a_parameters_file(spec, identified, tmp_path):
    from urident.ident.design import base_for, column_kinds, column_names

    model, _ = identified
    cfg = model.model
    base = base_for(spec, cfg.reduced)
    kinds = P.parameter_kinds()
    assert model.kinds == tuple(column_kinds(spec, cfg))
    assert list(model.kinds[:base.n_base]) == [kinds[k] for k in base.independent]
    assert list(model.kinds[base.n_base:]) == (["offset"] * 6 + ["stribeck"] * 6 + ["load_friction"] * 6
                                              + ["sqrt_viscous"] * 6)
    assert len(column_names(spec, cfg)) == len(model.kinds)
    path = tmp_path / "p.yaml"
    save_params(model, path)
    assert load_params(path).kinds == model.kinds


def test_the_gap_link_torque_leaves_out_exactly_the_friction_kinds(spec, identified):
    """residual.make_context's τ̂_link is the prediction of the columns whose kind is not friction
    (rigid body and rotor inertia), τ̂ − τ̂_link the friction and offset columns'."""
    from urident.gap.data import GapSet
    from urident.gap.residual import make_context
    from urident.ident.design import design_matrix

    model, data = identified
    ctx = make_context(spec, model, GapSet(data, data.t - data.t[0], None, None))
    w = design_matrix(spec, model.model, data.q, data.qd, data.qdd, data.segment)
    friction = P.is_friction(model.kinds)
    assert friction.sum() == 12 + 24                  # viscous, Coulomb and the four extras
    np.testing.assert_allclose(ctx.tau_link, (w[:, ~friction] @ model.values[~friction]).reshape(-1, 6))
    np.testing.assert_allclose(ctx.tau_hat - ctx.tau_link,
                               (w[:, friction] @ model.values[friction]).reshape(-1, 6), atol=1e-9)


def test_identification_and_gap_columns_are_the_shared_features(spec, states):
    """The identification model's Stribeck and load-friction extras and the gap candidates' are the
    same functions of urident.ident.features (the simulator's forward effects are separate)."""
    from urident.gap import candidates as C
    from urident.ident import features
    from urident.ident.design import design_blocks, nominal_link_torque

    q, qd, qdd = states
    cfg = ModelConfig(extras=("stribeck", "load"), stribeck_vs=0.03)
    blocks = design_blocks(spec, cfg, q, qd, qdd)
    raw = regressor_blocks(spec, q, qd, qdd, cfg.friction_eps)
    j = np.arange(6)
    nb = blocks.shape[2] - 12
    np.testing.assert_array_equal(blocks[:, j, nb + j], features.stribeck(qd, 0.01, 0.03))
    np.testing.assert_array_equal(blocks[:, j, nb + 6 + j],
                                  features.load_friction(nominal_link_torque(spec, raw), raw[:, j, P.COULOMB_OFFSET + j]))

    class Ctx:            # the few signals a candidate's columns read
        n = len(q)
        friction_eps = 0.01

        def __init__(self):
            self.q, self.qd, self.qdd = q, qd, qdd
            self.tau_link = np.cos(q) * 3.0

        def sign(self):
            return np.tanh(self.qd / self.friction_eps)

    ctx = Ctx()
    np.testing.assert_array_equal(C.stribeck(2, 0.03).build(ctx)[:, 2, 0], features.stribeck(qd[:, 2], 0.01, 0.03))
    np.testing.assert_array_equal(C.load_friction(4).build(ctx)[:, 4, 0],
                                  features.load_friction(ctx.tau_link[:, 4], ctx.sign()[:, 4]))
    np.testing.assert_array_equal(C.payload_error(spec).build(ctx), features.payload_columns(raw, spec.tool_xyz))
