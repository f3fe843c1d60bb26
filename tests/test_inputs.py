"""Inputs: every file format is read by one strict YAML reader (duplicate keys rejected, one
error format ``FILE: key.path: message``); unreadable, directory, non-UTF-8 and empty inputs exit 2
with one line naming the file; physically impossible robot files are rejected naming the key."""

from __future__ import annotations

import re
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from urident.cli.main import main
from urident.errors import ConfigError, LogFormatError, UridentError
from urident.excitation import load_trajectory
from urident.ident import load_params
from urident.logs import LOG_FIELDS, LogWriter, load_log
from urident.model import load_robot
from urident.session import load_experiment_config
from urident.simcontroller.effects import parse_effects
from urident.ident.prediction import load_prediction_params
from urident.yamlio import parse_yaml

ROOT = Path(__file__).resolve().parent.parent
UR5 = ROOT / "urident" / "model" / "robots" / "ur5.yaml"
TRAJECTORY = ROOT / "experiments" / "ur5_ident.yaml"
SAMPLE = ROOT / "logs" / "sample_valid.csv"


def _one_line_error(capsys, code: int, *needles: str) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("urident: error: ") and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def _duplicate_line(text: str, pattern: str) -> tuple[str, int]:
    """``text`` with the first line matching ``pattern`` written twice; the second's line number."""
    lines = text.splitlines(keepends=True)
    k = next(i for i, line in enumerate(lines) if re.match(pattern, line))
    return "".join(lines[:k + 1] + [lines[k].replace(lines[k].split(":", 1)[1], " 15000.0\n")] + lines[k + 1:]), k + 2


# -- duplicate keys, in every format ------------------------------------------------------------

def test_duplicate_key_in_a_robot_file_is_rejected_with_line_and_key(tmp_path, capsys):
    text, line = _duplicate_line(UR5.read_text(), r"\s+torque_limit:")
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=rf"^{re.escape(str(bad))}:{line}: joints\[0\]\.torque_limit: duplicate key$"):
        load_robot(bad)
    for argv in (["model", "--robot", str(bad)],
                 ["excite", "--robot", str(bad), "--out", str(tmp_path / "t.yaml")],
                 ["run", "--robot", str(bad), "--host", "127.0.0.1", "--trajectory", str(TRAJECTORY),
                  "--check-only"]):
        _one_line_error(capsys, main(argv), f"{bad}:{line}: joints[0].torque_limit: duplicate key")


def test_duplicate_keys_in_the_other_formats(tmp_path):
    cases = [
        ("traj.yaml", TRAJECTORY.read_text().replace("  harmonics: 5\n", "  harmonics: 5\n  harmonics: 6\n", 1),
         load_trajectory, ConfigError, "trajectory.harmonics"),
        ("c.yaml", "servo:\n  gain: 300\n  gain: 2000\n", load_experiment_config, ConfigError, "servo.gain"),
        ("fx.yaml", "effects:\n  - name: stribeck\n    joints: [1]\n    joints: [2]\n", parse_effects,
         ConfigError, "effects[0].joints"),
        ("p.yaml", "format: urident-params\nrobot: ur5\nrobot: ur10e\n", load_params, ConfigError, "robot"),
        ("v.yaml", "params: [1, 2]\nparams: [3]\n", partial(load_prediction_params, spec=load_robot("ur5")), ConfigError,
         "params"),
    ]
    for name, text, loader, error, key in cases:
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(error, match=rf"^{re.escape(str(path))}:\d+: {re.escape(key)}: duplicate key$"):
            loader(path)


def test_duplicate_key_in_a_sidecar(tmp_path):
    path = tmp_path / "o.csv"
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"}) as log:
        log.append([0.0] + [0.0] * 18)
    side = path.with_suffix(".yaml")
    side.write_text(side.read_text() + "robot: ur10e\n")
    n = side.read_text().count("\n")
    with pytest.raises(LogFormatError, match=rf"o\.yaml:{n}: robot: duplicate key$"):
        load_log(path)


def test_strict_reader_details():
    with pytest.raises(ConfigError, match=r"^F:4: a\[1\]\.x: duplicate key$"):
        parse_yaml("a:\n  - {x: 1}\n  - {x: 2,\n     x: 3}\n", "F")
    assert parse_yaml("base: &b {x: 1}\nother:\n  <<: *b\n  x: 2\n", "F")["other"] == {"x": 2}  # merge keys override
    assert parse_yaml("a: &a [1]\nb: *a\n", "F") == {"a": [1], "b": [1]}
    with pytest.raises(ConfigError, match=r"^F:1: malformed YAML \(could not determine a constructor"):
        parse_yaml("!!python/object/apply:os.system [true]\n", "F")
    with pytest.raises(ConfigError, match=r"^F:2: malformed YAML"):
        parse_yaml("a: [\n", "F")


# -- unreadable, directory, non-UTF-8, empty ----------------------------------------------------

@pytest.fixture
def bad_inputs(tmp_path):
    d = tmp_path / "dir.yaml"
    d.mkdir()
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"robot: \xff\xfe\x00\n")
    empty = tmp_path / "empty.yaml"
    empty.write_bytes(b"")
    return {"directory": d, "binary": binary, "empty": empty, "missing": tmp_path / "missing.yaml"}


@pytest.mark.parametrize("kind", ["directory", "binary", "missing"])
def test_unreadable_inputs_exit_2_naming_the_file(bad_inputs, kind, tmp_path, capsys):
    bad = str(bad_inputs[kind])
    argvs = [
        ["model", "--robot", bad],
        ["check-trajectory", bad],
        ["validate", str(SAMPLE), "--params", bad],
        ["view", str(SAMPLE), "--params", bad, "--save", str(tmp_path / "v.rrd")],
        ["run", "--robot", "ur5", "--host", "127.0.0.1", "--trajectory", str(TRAJECTORY), "--config", bad,
         "--check-only"],
        ["run", "--robot", "ur5", "--host", "127.0.0.1", "--trajectory", bad, "--check-only"],
        ["simulate", "--trajectory", bad, "--out", str(tmp_path / "s.csv")],
        ["simulate", "--trajectory", str(TRAJECTORY), "--out", str(tmp_path / "s.csv"), "--effects", bad],
    ]
    for argv in argvs:
        _one_line_error(capsys, main(argv), bad)


def test_unreadable_logs_and_sidecars(bad_inputs, tmp_path, capsys):
    rrd = str(tmp_path / "v.rrd")
    for bad in (bad_inputs["directory"], bad_inputs["missing"]):
        _one_line_error(capsys, main(["view", str(bad), "--robot", "ur5", "--save", rrd]), str(bad))
    path = tmp_path / "o.csv"
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"}) as log:
        log.append([0.0] + [0.0] * 18)
    path.with_suffix(".yaml").write_bytes(b"robot: ur5\nnote: \xff\n")
    _one_line_error(capsys, main(["view", str(path), "--save", rrd]), "o.yaml: sidecar is not UTF-8")


def test_empty_parameter_files_name_the_file(bad_inputs, tmp_path, capsys):
    empty = str(bad_inputs["empty"])
    _one_line_error(capsys, main(["validate", str(SAMPLE), "--params", empty]),
                    f"{empty}: parameters file is empty")
    _one_line_error(capsys, main(["view", str(SAMPLE), "--params", empty, "--save", str(tmp_path / "v.rrd")]),
                    f"{empty}: parameter file is empty")
    with pytest.raises(ConfigError, match="robot file is not UTF-8"):
        load_robot(bad_inputs["binary"])


# -- physically impossible robot files ----------------------------------------------------------

def _robot_with(tmp_path, old: str, new: str) -> Path:
    text = UR5.read_text()
    assert old in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(old, new, 1))
    return bad


def _first_inertia_line() -> str:
    return next(line for line in UR5.read_text().splitlines() if "inertia_com:" in line)


@pytest.mark.parametrize("values, message", [
    ([0.01, 0.01, 0.05, 0, 0, 0], "violates the triangle inequality"),   # Izz > Ixx + Iyy
    ([0.01, 0.01, 0.01, 0.02, 0, 0], "is not positive definite"),         # a negative principal moment
    ([0.0, 0.0, 0.0, 0, 0, 0], "is not positive definite"),               # zero inertia
])
def test_impossible_inertia_is_rejected_naming_the_key(tmp_path, capsys, values, message):
    line = _first_inertia_line()
    key, _ = line.split(":", 1)
    bad = _robot_with(tmp_path, line, f"{key}: [{', '.join(map(str, values))}]")
    with pytest.raises(ConfigError, match=rf"bad\.yaml: joints\[0\]\.link\.inertia_com: {message}"):
        load_robot(bad)
    _one_line_error(capsys, main(["model", "--robot", str(bad)]), "joints[0].link.inertia_com", message)


@pytest.mark.parametrize("mass", ["0.0", "-3.7"])
def test_non_positive_mass_is_rejected(tmp_path, mass):
    bad = _robot_with(tmp_path, "mass: 3.7", f"mass: {mass}")
    with pytest.raises(ConfigError, match=r"joints\[0\]\.link\.mass: must be positive"):
        load_robot(bad)


def test_shipped_robots_are_physically_possible():
    from urident.model.robot import available_robots, inertia_problem

    for name in available_robots():
        for joint in load_robot(name).joints:
            assert joint.mass > 0 and inertia_problem(joint.inertia_com) is None
    # the triangle inequality holds with equality for a thin rod: accepted
    assert inertia_problem(np.diag([1.0, 1.0, 2.0])) is None


def test_errors_are_uridenterrors_with_exit_code_2():
    assert issubclass(ConfigError, UridentError) and ConfigError.exit_code == 2
