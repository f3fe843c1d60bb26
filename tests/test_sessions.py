"""Several sessions: shared parameters with per-session offsets and friction scales kept by CV
(``identify --sessions``), and the share of a new session's error such a shift explains
(``validate --session-shift``)."""

from __future__ import annotations

import numpy as np
import pytest

from urident.ident import ModelConfig, Prepared, identify
from urident.ident.design import base_for, design_blocks
from urident.ident.identify import predict_prepared
from urident.ident.preprocess import Provenance, concatenate
from urident.ident.sessions import fit_sessions, session_shift
from urident.ident.synthetic import synthetic_recording
from urident.model import load_robot
from urident.model.parameters import FRICTION

SHIFTS = [(0.0, 1.0), (0.8, 1.3), (-0.5, 0.8)]   # (offset on joint 2 [N·m], friction scale) per session


@pytest.fixture(scope="module")
def sessions():
    spec = load_robot("ur5")
    b = base_for(spec, False)
    parts = []
    for s, (off, scale) in enumerate(SHIFTS):
        rec, qdd, _ = synthetic_recording(spec, duration_s=4.0, rate_hz=125.0, seed=30 + s)
        p = spec.nominal_params.copy()
        p[FRICTION] *= scale
        tau = design_blocks(spec, ModelConfig(), rec.q, rec.qd, qdd) @ (b.combination @ p)
        tau[:, 1] += off
        tau += np.random.default_rng(s).normal(0, 0.1, tau.shape)
        parts.append(Prepared(rec.t, rec.q, rec.qd, qdd, tau, spec.drive_gains,
                              (Provenance(f"day{s}.csv", None, None, (0, len(rec))),)))
    return spec, parts, b.combination @ spec.nominal_params


def test_sessions_keep_the_shifts_that_exist_and_recover_the_shared_model(sessions):
    spec, parts, theta = sessions
    data = concatenate(parts)
    fixed, terms = fit_sessions(spec, data, ModelConfig(), "joint")
    kept = {(j, kind) for j, kind, _, _ in terms.chosen}
    assert (1, "offset") in kept and not any(kind == "offset" and j != 1 for j, kind in kept)
    assert {(j, "friction_scale") for j in (0, 1, 2)} <= kept
    np.testing.assert_allclose(terms.values[(1, "offset")], [0.8, -0.5], atol=0.15)   # 4 s runs: offset and gravity overlap
    np.testing.assert_allclose(terms.values[(0, "friction_scale")], [1.3, 0.8], atol=0.03)
    shared = identify(spec, fixed, "ols", ModelConfig(), "joint").values
    plain = identify(spec, data, "ols", ModelConfig(), "joint").values
    assert np.abs(shared - theta)[-12:].max() < 0.2 * np.abs(plain - theta)[-12:].max()
    assert "J2 offset" in terms.text() and terms.sessions[0] == "day0.csv"


def test_session_shift_says_how_much_of_a_new_sessions_error_it_explains(sessions):
    spec, parts, _ = sessions
    m = identify(spec, parts[0], "ols", ModelConfig(), "none")
    shift = session_shift(m, spec, parts[1], predict_prepared(m, spec, parts[1]))
    assert shift.offset_nm[1] == pytest.approx(0.8, abs=0.05)
    np.testing.assert_allclose(shift.friction_scale[:3], 1.3, atol=0.03)
    assert shift.explained_mean_pct > 90 and np.all(shift.rms_after <= shift.rms_before)
    same = session_shift(m, spec, parts[0], predict_prepared(m, spec, parts[0]))
    assert same.explained_mean_pct < 2       # the identification session itself has no shift


def test_sessions_need_two_logs(sessions):
    from urident.errors import ConfigError

    spec, parts, _ = sessions
    with pytest.raises(ConfigError, match="two sessions"):
        fit_sessions(spec, parts[0], ModelConfig())
