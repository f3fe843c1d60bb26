"""`urident identify` and `urident validate` send their results to a Rerun recording (--save),
read back through Rerun's own API."""

import numpy as np
import pytest

from urident.cli.main import main
from urident.excitation import FourierTrajectory
from urident.excitation.fourier import base_frequency
from urident.model import load_robot
from urident.simcontroller.offline import simulate
from urident.viz.readback import read_rrd


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("vizres")
    spec = load_robot("ur5")
    q0 = np.array([0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0])
    paths = []
    for seed in (1, 2):
        free = np.random.default_rng(seed).normal(scale=0.2, size=(6, 8))
        traj = FourierTrajectory.from_free(free, base_frequency(8.0), q0, 8.0)
        out = d / f"run{seed}.csv"
        simulate(spec, traj, 125.0, None, seed=seed, out=out)
        paths.append(out)
    return d, paths


def test_identify_and_validate_save_rrd(logs):
    d, (ident, valid) = logs
    params = d / "p.yaml"
    assert main(["identify", str(ident), "--robot", "ur5", "--method", "all", "--out", str(params),
                 "--save", str(d / "ident.rrd")]) == 0
    assert main(["validate", str(valid), "--params", str(params), "--save", str(d / "valid.rrd")]) == 0
    joints = load_robot("ur5").joint_names
    for rrd, prefix, labels in ((d / "ident.rrd", "identify", ("ols", "bounded", "consistent")),
                                (d / "valid.rrd", "validate", ("p",))):
        contents = read_rrd(rrd)
        assert f"{prefix}/summary" in contents.entities
        for label in labels:
            counts = set()
            for joint in joints:
                for series in ("measured", "predicted", "residual"):
                    t, values = contents.scalars(f"{prefix}/{label}/torque/{joint}/{series}")
                    counts.add(len(t))
                    assert np.all(np.isfinite(np.asarray(values, dtype=float)))
            assert len(counts) == 1 and counts.pop() > 500
            (row,) = contents.rows(f"{prefix}/{label}/metrics/e_N", "Scalars:scalars")  # static
            assert row[0] is None and 0 < float(row[1][0]) < 1
