"""Real UR10e data (shared development set): the paper's method reproduces the reference figures
measured on exactly these windows, and urident's best configuration (preset ``real-robot``, i.e.
``auto``: each joint's friction terms, the torque's lead and the acceleration corner chosen on the
identification run) beats both references on every joint with mean RMS <= 1.12 N·m; the fixed set ``real-robot`` meant before
(``ur10e-2020``) still gives its documented row.

Identification: ur-20_02_10-30sec_12harm.csv rows 635-3510; validation: ur-20_01_17-ptp_10_points.csv
rows 700-4200; torques = robot file drive gains x raw current. References on that window:
paper method (plain OLS, tanh friction, eps = 0.01 rad/s): RMS [2.19, 3.57, 1.59, 0.44, 1.00, 1.27]
N·m (mean 1.68), e_N 0.0809; the source project's published parameters: RMS [2.34, 4.08, 1.78,
0.53, 0.58, 1.39] (mean 1.78), e_N 0.0892. Every choice of the presets was made by blocked CV inside
the identification file (urident/ident/presets.py, friction_select.py); the validation file only
scores it here.
"""

from __future__ import annotations


import numpy as np
import pytest

from shared_data import UR10E_DATA
from urident.ident import (PRESETS, ModelConfig, PreprocessConfig, identify_all, load_params, prediction_config,
                           prepare, resolve_preset, save_params, validate)
from urident.logs import load_log
from urident.model import load_robot

DATA = UR10E_DATA
ID_FILE = DATA / "ur-20_02_10-30sec_12harm.csv"
VAL_FILE = DATA / "ur-20_01_17-ptp_10_points.csv"
PAPER_RMS = np.array([2.19, 3.57, 1.59, 0.44, 1.00, 1.27])
PAPER_EN = 0.0809
PUBLISHED_RMS = np.array([2.34, 4.08, 1.78, 0.53, 0.58, 1.39])
PUBLISHED_EN = 0.0892
# measured with the real-robot preset (auto; OLS and consistent agree to 0.01 N·m): the README's rows
BEST_RMS = np.array([1.66, 2.36, 1.15, 0.28, 0.42, 0.68])
BEST_EN = 0.0545
BEST_CV = 1.272        # mean held-out RMS of the chosen terms, before the lead
LEAD_CV = 1.229        # ... with the chosen lead
CORNER_CV = 1.148      # ... and the chosen acceleration corner
# the fixed set (preset ur10e-2020) at the distance its CV chose on this run, OLS
FIXED_RMS = np.array([1.86, 2.63, 1.35, 0.31, 0.44, 0.52])
FIXED_EN = 0.0605

pytestmark = [pytest.mark.skipif(not (ID_FILE.exists() and VAL_FILE.exists()), reason="UR10e data absent"),
              # one worker, so the module's fixtures (auto's selection: seconds) are built once under xdist
              pytest.mark.xdist_group("ident_ur10e")]


@pytest.fixture(scope="module")
def ur10e():
    spec = load_robot("ur10e")
    ident = load_log(ID_FILE, robot="ur10e", rows=(635, 3510), format="dynamic_calibration")
    valid = load_log(VAL_FILE, robot="ur10e", rows=(700, 4200), format="dynamic_calibration")
    data = prepare([ident], spec, PreprocessConfig())
    vdata = prepare([valid], spec, PreprocessConfig(trim_rest=False))
    return spec, data, vdata, valid


def test_paper_method_reproduces_reference(ur10e):
    spec, data, vdata, _ = ur10e
    model = identify_all(spec, data, ("ols",), ModelConfig())["ols"]
    res = validate(model, spec, vdata)
    assert res.n_samples == 3501
    np.testing.assert_allclose(res.rms_nm, PAPER_RMS, atol=0.05)
    assert res.mean_rms_nm == pytest.approx(PAPER_RMS.mean(), abs=0.02)
    assert res.e_n == pytest.approx(PAPER_EN, abs=0.0015)


@pytest.fixture(scope="module")
def best(ur10e):
    spec, data, _, _ = ur10e
    choice = resolve_preset(spec, data, "real-robot")
    fitted = data if choice.data is None else choice.data
    models = identify_all(spec, fitted, ("ols", "consistent"), choice.model, weighting=choice.weighting,
                          preprocess_config=choice.preprocess_config(PreprocessConfig()))
    return choice, models


def test_best_configuration_selected_by_cv_inside_identification_file(best):
    choice, _ = best
    assert choice.preset == "auto" and choice.weighting == "joint" and choice.selection is not None
    m = choice.model
    # every joint on a Dahl presliding state driven by the integrated velocity
    assert m.reduced and m.dahl_source == "velocity" and all(c.startswith("dahl@") for c in m.joint_coulomb)
    # the load-dependent Coulomb friction of the harmonic drives carrying gravity: CV finds it
    # where the gap diagnosis does (joints 2 and 3) and the fixed set has it on every joint
    assert [any(t.split("@")[0] == "load" for t in terms) for terms in m.joint_extras] == \
        [False, True, True, False, False, False]
    assert choice.selection.mean_rms_nm == pytest.approx(BEST_CV, abs=0.01)
    # the measured torque leads the motion (the drives' current loop), by a few milliseconds
    assert 0.002 <= choice.torque_lead_s <= 0.010
    lead_cv = [s.mean_rms_nm for s in choice.lead_scores]
    assert min(lead_cv) == pytest.approx(LEAD_CV, abs=0.01)
    assert min(lead_cv) <= 0.995 * choice.selection.mean_rms_nm   # the lead is kept when it pays 0.5 %
    # the torque follows the arm's motion above the paper's 10 Hz: CV takes the highest corner below
    # 0.45 × the log's 100 Hz
    assert choice.corner_grid == (10.0, 15.0, 20.0, 30.0, 45.0) and choice.filter_hz == 45.0
    corner_cv = [s.mean_rms_nm for s in choice.corner_scores]
    assert corner_cv[0] == pytest.approx(min(lead_cv), abs=1e-9) and min(corner_cv) == pytest.approx(CORNER_CV, abs=0.01)


def test_best_configuration_meets_target(best, ur10e, tmp_path):
    spec, _, _, valid = ur10e
    choice, models = best
    # validated as `urident validate` does: the lead and corner the parameters record are applied
    vdata = prepare([valid], spec, prediction_config(models["ols"]))
    assert models["ols"].preprocess.torque_lead_s == choice.torque_lead_s > 0
    assert models["ols"].preprocess.filter_hz == choice.filter_hz
    for name, model in models.items():
        res = validate(model, spec, vdata)
        np.testing.assert_allclose(res.rms_nm, BEST_RMS, atol=0.03, err_msg=name)
        assert res.e_n == pytest.approx(BEST_EN, abs=0.001), name
        assert np.all(res.rms_nm < PAPER_RMS) and np.all(res.rms_nm < PUBLISHED_RMS), (name, res.rms_nm)
        assert res.mean_rms_nm <= 1.12, name
        assert res.e_n < min(PAPER_EN, PUBLISHED_EN)
    # the parameters file keeps the per-joint terms and the lead: a reloaded model predicts the same
    save_params(models["ols"], tmp_path / "best.yaml")
    back = load_params(tmp_path / "best.yaml")
    assert back.model == models["ols"].model and back.preprocess == models["ols"].preprocess
    np.testing.assert_allclose(validate(back, spec, vdata).rms_nm, validate(models["ols"], spec, vdata).rms_nm)


def test_the_fixed_set_real_robot_meant_before_gives_its_row(ur10e):
    """``ur10e-2020`` at the distance its blocked CV chose on this run (2e-4 rad, which the preset's
    model carries): the README's ur10e-2020 row, without the 7 fits of the distance's CV."""
    spec, data, vdata, _ = ur10e
    preset = PRESETS["ur10e-2020"]
    assert preset.select_dahl_rad and preset.model.dahl_rad == 2e-4
    model = identify_all(spec, data, ("ols",), preset.model, weighting=preset.weighting)["ols"]
    res = validate(model, spec, vdata)
    np.testing.assert_allclose(res.rms_nm, FIXED_RMS, atol=0.01)
    assert res.e_n == pytest.approx(FIXED_EN, abs=5e-4)
