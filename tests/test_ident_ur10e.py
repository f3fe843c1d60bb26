"""Real UR10e data (shared development set): the paper's method reproduces the reference figures
measured on exactly these windows, and urident's best configuration beats it.

Identification: ur-20_02_10-30sec_12harm.csv rows 635-3510; validation: ur-20_01_17-ptp_10_points.csv
rows 700-4200; torques = robot file drive gains x raw current. Reference (paper method, plain OLS,
tanh friction, eps = 0.01 rad/s): RMS [2.19, 3.57, 1.59, 0.44, 1.00, 1.27] N·m (mean 1.68), e_N 0.0809.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urident.ident import ModelConfig, PreprocessConfig, identify_all, prepare, validate
from urident.logs import load_log
from urident.model import load_robot

DATA = Path("/work/shared/data/ur10e-dynamic-calibration")
ID_FILE = DATA / "ur-20_02_10-30sec_12harm.csv"
VAL_FILE = DATA / "ur-20_01_17-ptp_10_points.csv"
PAPER_RMS = np.array([2.19, 3.57, 1.59, 0.44, 1.00, 1.27])
PAPER_EN = 0.0809

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


def test_best_configuration_beats_paper_method(ur10e):
    """Reduced base set + per-joint weighting (chosen by blocked CV inside the identification file)
    and the history-driven 'hold' Coulomb state (a-priori physics, v_h = 5x the identification file's
    standstill velocity noise)."""
    spec, data, vdata = ur10e
    best = ModelConfig(reduced=True, coulomb="hold", hold_velocity=3e-4)
    models = identify_all(spec, data, ("ols", "consistent"), best, weighting="joint")
    for name, model in models.items():
        res = validate(model, spec, vdata)
        assert res.mean_rms_nm < PAPER_RMS.mean() - 0.1, (name, res.rms_nm)
        assert res.e_n < PAPER_EN
