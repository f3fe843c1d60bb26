"""The acceleration filter's corner, chosen by ``--preset auto`` and applied by validate."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import urident as ur
from urident.errors import ConfigError
from urident.ident import load_params, prepare, resolve_preset, save_params
from urident.ident.presets import corner_grid
from urident.ident.synthetic import random_multisine, synthetic_recording
from urident.model import load_robot

VIBRATION_HZ = 20.0
AMPLITUDE = 6e-5   # [rad] per joint: about 1 rad/s² at 20 Hz, far above the current noise on the big joints


@pytest.fixture(scope="module")
def spec():
    return load_robot("ur5")


def run(spec, seed: int, vibration: str | None):
    """A 10 s, 125 Hz multi-sine run with a 20 Hz vibration of every joint in its logged motion:
    ``'torque'``: the arm really moves so (its torques carry the vibration's inertia); ``'sensor'``:
    only the logged motion does (the torques follow the smooth motion); None: no vibration."""
    rng = np.random.default_rng(seed + 100)
    base = random_multisine(spec, np.random.default_rng(seed))
    phase = rng.uniform(0, 2 * np.pi, 6)
    w = 2 * np.pi * VIBRATION_HZ

    def shaken(t):
        q, qd, qdd = base(t)
        arg = w * np.asarray(t)[:, None] + phase
        return (q + AMPLITUDE * np.sin(arg), qd + AMPLITUDE * w * np.cos(arg), qdd - AMPLITUDE * w ** 2 * np.sin(arg))

    rec, _, _ = synthetic_recording(spec, 10.0, 125.0, current_noise_a=0.02, seed=seed,
                                    trajectory=shaken if vibration == "torque" else base)
    if vibration != "sensor":
        return rec
    q, qd, _ = shaken(rec.t)
    return replace(rec, q=q, qd=qd)


def test_the_grid_stays_below_nyquist_and_holds_the_base():
    t = np.arange(1000) / 100.0
    from urident.ident import Prepared

    z = np.zeros((1000, 6))
    grid = corner_grid(Prepared(t, z, z, z, z, np.ones(6)), 12.0)
    assert 12.0 in grid and max(grid) <= 45.0 and grid == tuple(sorted(grid))


def test_auto_keeps_the_corner_unless_the_torque_follows_faster_motion(spec, tmp_path):
    plain = resolve_preset(spec, prepare([run(spec, 5, None)], spec), "auto")
    assert plain.filter_hz == 10.0 and plain.data is None
    assert "acceleration filter corner chosen by 5-fold blocked CV of the chosen model: 10 Hz (the data's own" \
        in plain.text()
    # vibration in the logged motion only (a sensor's): a higher corner adds torque that is not there
    assert resolve_preset(spec, prepare([run(spec, 5, "sensor")], spec), "auto").filter_hz == 10.0

    ident = ur.identify([run(spec, 5, "torque")], "ur5", "ols", preset="auto")
    corner = ident.model.preprocess.filter_hz
    assert corner > VIBRATION_HZ
    assert f"acceleration filter corner chosen by 5-fold blocked CV of the chosen model: {corner:g} Hz (" \
        in ident.report
    path = tmp_path / "p.yaml"
    save_params(ident.model, path)
    loaded = load_params(path)
    assert loaded.preprocess.filter_hz == corner
    other = run(spec, 6, "torque")   # another run of the same arm: validate filters it as identified
    at_corner = ur.validate(loaded, [other]).rms_nm
    at_ten = ur.validate(loaded, [other], filter_hz=10.0).rms_nm
    assert np.mean(at_corner) < 0.7 * np.mean(at_ten)
    # a log too slow for the recorded corner is refused, in one line that says where the corner came from
    slow = replace(other.select(np.arange(0, len(other.t), 3)), rate_hz=other.rate_hz / 3)
    with pytest.raises(ConfigError, match="must be below the Nyquist frequency .*a parameters file records the corner"):
        ur.validate(loaded, [slow])
    assert np.all(np.isfinite(ur.validate(loaded, [slow], filter_hz=10.0).rms_nm))


def test_a_corner_given_is_kept(spec, tmp_path, capsys):
    from urident.cli.main import main
    from urident.logs import LogWriter

    rec = run(spec, 5, "torque")
    with LogWriter(tmp_path / "id.csv", fields=["timestamp", "actual_q", "actual_qd", "actual_current"],
                   metadata={"robot": rec.robot, "rate_hz": rec.rate_hz}) as w:
        for k in range(len(rec)):
            w.append_sample(float(rec.t[k]), q=rec.q[k], qd=rec.qd[k], current=rec.current[k])
    out = tmp_path / "p.yaml"
    assert main(["identify", str(tmp_path / "id.csv"), "--robot", "ur5", "--out", str(out), "--preset", "auto",
                 "--filter-hz", "10"]) == 0
    assert "acceleration filter corner chosen" not in capsys.readouterr().out
    assert load_params(out).preprocess.filter_hz == 10.0
