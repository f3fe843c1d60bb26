"""`urident model --check` on hand-written robot files and `urident model --list`."""

import pytest

from urident.cli.main import main
from urident.model import available_robots, load_robot
from urident.model.check import check_robot


@pytest.mark.parametrize("name", available_robots())
def test_shipped_robot_files_pass_the_check(name):
    assert check_robot(load_robot(name)) == []


def _variant(tmp_path, old, new, count=1):
    text = load_robot("ur5e").source.read_text()
    assert old in text
    path = tmp_path / "my_arm.yaml"
    path.write_text(text.replace(old, new, count))
    return path


@pytest.mark.parametrize("old, new, key, words", [
    # a UR5e with a custom tool flange 2 cm longer, but the DH table not updated
    ("tool:\n  xyz: [0.0, 0.0996, 0.0]", "tool:\n  xyz: [0.0, 0.1196, 0.0]", "tool.xyz", "20.000 mm"),
    ("    xyz: [0.0, 0.0, 0.3922]", "    xyz: [0.0, 0.0, 0.4122]", "joints[3].xyz", "off the declared DH axis"),
    ("    rpy: [0.0, 1.5707963267948966, 0.0]\n    axis: y\n    position_limits: [-6.283185, 6.283185]\n"
     "    velocity_limit: 3.141593\n    acceleration_limit: 25.0",
     "    rpy: [0.0, 0.0, 0.0]\n    axis: y\n    position_limits: [-6.283185, 6.283185]\n"
     "    velocity_limit: 3.141593\n    acceleration_limit: 25.0", "joints[4].rpy", "and joints[3].rpy"),
    ("      mass: 8.058", "      mass: 8058.0", "joints[1].torque_limit", "gravity torque"),
    ("      com: [0.0, 0.0195, 0.2422]", "      com: [0.0, 19.5, 242.2]", "joints[2].link.com", "in mm"),
    ("    velocity_limit: 3.141593", "    velocity_limit: 180.0", "joints[0].velocity_limit", "rad/s"),
    ("position_limits: [-6.283185, 6.283185]", "position_limits: [-360.0, 360.0]",
     "joints[0].position_limits", "beyond ±2π"),
    ("controller_rate_hz: 500", "controller_rate_hz: 125", "controller_rate_hz", "500 Hz"),
    ('controller_version: "5.11.0"', 'controller_version: "3.15.8"', "controller_version", "5.x"),
    ("- {a: [0.0, 0.0, 0.06], b: [0.0, 0.0, 0.425], radius: 0.06}",
     "- {a: [0.0, 0.0, 0.06], b: [0.0, 0.0, 0.425], radius: 0.2}", "allowed_contacts", "overlap"),
    ("model: UR5e\n", "", "model", "missing"),
])
def test_check_names_the_key(tmp_path, capsys, old, new, key, words):
    path = _variant(tmp_path, old, new)
    problems = check_robot(load_robot(path))
    assert problems, "the check found nothing"
    assert any(f"my_arm.yaml: {key}:" in p and words in p for p in problems), problems
    assert all("\n" not in p for p in problems)
    assert main(["model", "--robot", str(path), "--check"]) == 2
    captured = capsys.readouterr()
    assert f": {key}: " in captured.err
    assert "urident: error:" in captured.err and "problem" in captured.err


def test_check_accepts_a_consistent_custom_flange(tmp_path, capsys):
    # Longer flange: the tool offset and DH d6 change together, as the README describes.
    text = load_robot("ur5e").source.read_text()
    text = text.replace("tool:\n  xyz: [0.0, 0.0996, 0.0]", "tool:\n  xyz: [0.0, 0.1196, 0.0]")
    text = text.replace("d: [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996]", "d: [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.1196]")
    text = text.replace("name: ur5e", "name: ur5e_long_flange")
    path = tmp_path / "flange.yaml"
    path.write_text(text)
    assert main(["model", "--robot", str(path), "--check"]) == 0
    out = capsys.readouterr().out
    assert "flange.yaml: ok" in out and "nominal values" in out
    assert load_robot(path).dashboard_model == "UR5"


def test_check_reports_load_errors_as_one_line(tmp_path, capsys):
    path = _variant(tmp_path, "torque_limit: 150.0", "torque_limit: -150.0")
    assert main(["model", "--robot", str(path), "--check"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "joints[0].torque_limit" in err[0]


def test_model_list_prints_every_robot(capsys):
    import json

    assert main(["model", "--list"]) == 0
    out = capsys.readouterr().out
    for name in available_robots():
        spec = load_robot(name)
        line = next(line for line in out.splitlines() if line.split()[:1] == [name])
        assert spec.generation in line and f"{spec.controller_rate_hz:g} Hz" in line
        assert f"{spec.reach_m:.2f} m" in line and f"{spec.payload_kg:g} kg" in line
    assert main(["model", "--list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {r["robot"] for r in rows} == set(available_robots())
    assert {r["rate_hz"] for r in rows if r["generation"] == "cb3"} == {125.0}
    assert main(["model"]) == 2
    assert "--robot" in capsys.readouterr().err


def test_nominal_marks_are_loaded_and_reported(tmp_path, capsys):
    from pathlib import Path

    from urident.errors import ConfigError

    ur20, ur10e = load_robot("ur20"), load_robot("ur10e")
    assert "inertia_com" not in ur20.nominal and "torque_constant" in ur20.nominal  # UR publishes UR20 inertias
    assert "torque_constant" not in ur10e.nominal                                   # measured drive gains
    assert ur20.nominal_note(("inertia_com",)) is None
    assert "torque constants" in ur20.nominal_note()
    bad = _variant(tmp_path, "nominal: [", "nominal: [inertias, ")
    with pytest.raises(ConfigError, match="my_arm.yaml: nominal: must be a list"):
        load_robot(bad)
    logs = Path(__file__).resolve().parent.parent / "logs"
    params = tmp_path / "p.yaml"
    assert main(["identify", str(logs / "sample_ident.csv"), "--robot", "ur5", "--method", "ols",
                 "--out", str(params)]) == 0
    out = capsys.readouterr().out
    assert "robot file 'ur5': nominal values, not manufacturer data: link inertias" in out
    assert "torque constants" not in out.splitlines()[-1]   # the UR5's are not marked nominal
