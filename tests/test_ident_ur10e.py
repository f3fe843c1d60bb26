"""Real UR10e data (shared development set): the paper's method reproduces the reference figures
measured on exactly these windows, and urident's best configuration (preset ``real-robot``) beats
both references on every joint with mean RMS <= 1.25 N·m.

Identification: ur-20_02_10-30sec_12harm.csv rows 635-3510; validation: ur-20_01_17-ptp_10_points.csv
rows 700-4200; torques = robot file drive gains x raw current. References on that window:
paper method (plain OLS, tanh friction, eps = 0.01 rad/s): RMS [2.19, 3.57, 1.59, 0.44, 1.00, 1.27]
N·m (mean 1.68), e_N 0.0809; the source project's published parameters: RMS [2.34, 4.08, 1.78,
0.53, 0.58, 1.39] (mean 1.78), e_N 0.0892. Every choice of the preset was made by blocked CV inside
the identification file (urident/ident/presets.py); the validation file only scores it here.
"""

from __future__ import annotations


import numpy as np
import pytest

from shared_data import UR10E_DATA
from urident.ident import (ModelConfig, PreprocessConfig, identify_all, load_params, prepare,
                           resolve_preset, save_params, validate)
from urident.logs import load_log
from urident.model import load_robot

DATA = UR10E_DATA
ID_FILE = DATA / "ur-20_02_10-30sec_12harm.csv"
VAL_FILE = DATA / "ur-20_01_17-ptp_10_points.csv"
PAPER_RMS = np.array([2.19, 3.57, 1.59, 0.44, 1.00, 1.27])
PAPER_EN = 0.0809
PUBLISHED_RMS = np.array([2.34, 4.08, 1.78, 0.53, 0.58, 1.39])
PUBLISHED_EN = 0.0892
# measured with the real-robot preset (OLS and consistent agree to 0.01 N·m)
BEST_RMS = np.array([1.86, 2.63, 1.35, 0.31, 0.44, 0.52])
BEST_EN = 0.0605
BEST_CV = 1.271

pytestmark = pytest.mark.skipif(not (ID_FILE.exists() and VAL_FILE.exists()), reason="UR10e data absent")


@pytest.fixture(scope="module")
def ur10e():
    spec = load_robot("ur10e")
    ident = load_log(ID_FILE, robot="ur10e", rows=(635, 3510), format="dynamic_calibration")
    valid = load_log(VAL_FILE, robot="ur10e", rows=(700, 4200), format="dynamic_calibration")
    data = prepare([ident], spec, PreprocessConfig())
    vdata = prepare([valid], spec, PreprocessConfig(trim_rest=False))
    return spec, data, vdata


def test_paper_method_reproduces_reference(ur10e):
    spec, data, vdata = ur10e
    model = identify_all(spec, data, ("ols",), ModelConfig())["ols"]
    res = validate(model, spec, vdata)
    assert res.n_samples == 3501
    np.testing.assert_allclose(res.rms_nm, PAPER_RMS, atol=0.05)
    assert res.mean_rms_nm == pytest.approx(PAPER_RMS.mean(), abs=0.02)
    assert res.e_n == pytest.approx(PAPER_EN, abs=0.0015)


@pytest.fixture(scope="module")
def best(ur10e):
    spec, data, _ = ur10e
    choice = resolve_preset(spec, data, "real-robot")
    models = identify_all(spec, data, ("ols", "consistent"), choice.model, weighting=choice.weighting)
    return choice, models


def test_best_configuration_selected_by_cv_inside_identification_file(best):
    choice, _ = best
    assert choice.weighting == "joint"
    m = choice.model
    assert m.reduced and m.coulomb == "dahl" and m.dahl_source == "velocity"
    assert set(m.extras) == {"load", "sqrtvisc", "stribeck"}
    grid = [s.model.dahl_rad for s in choice.cv_scores]
    cv = [s.mean_rms_nm for s in choice.cv_scores]
    assert m.dahl_rad == grid[int(np.argmin(cv))] == pytest.approx(2e-4)
    assert min(cv) == pytest.approx(BEST_CV, abs=0.01)


def test_best_configuration_meets_target(best, ur10e, tmp_path):
    spec, _, vdata = ur10e
    _, models = best
    for name, model in models.items():
        res = validate(model, spec, vdata)
        np.testing.assert_allclose(res.rms_nm, BEST_RMS, atol=0.03, err_msg=name)
        assert res.e_n == pytest.approx(BEST_EN, abs=0.001), name
        assert np.all(res.rms_nm < PAPER_RMS) and np.all(res.rms_nm < PUBLISHED_RMS), (name, res.rms_nm)
        assert res.mean_rms_nm <= 1.25, name
        assert res.e_n < min(PAPER_EN, PUBLISHED_EN)
    # the parameters file keeps the velocity-driven state: a reloaded model predicts the same
    save_params(models["ols"], tmp_path / "best.yaml")
    back = load_params(tmp_path / "best.yaml")
    assert back.model == models["ols"].model
    np.testing.assert_allclose(validate(back, spec, vdata).rms_nm, validate(models["ols"], spec, vdata).rms_nm)
