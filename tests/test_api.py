"""The Python API (`import urident as ur`): the same results as the command line by construction,
frozen results with plain JSON documents, and the CLI's errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import urident as ur
from urident.cli.main import main
from urident.errors import ConfigError

REPO = Path(__file__).resolve().parent.parent
IDENT, VALID = str(REPO / "logs" / "sample_ident.csv"), str(REPO / "logs" / "sample_valid.csv")


@pytest.fixture(scope="module")
def identified():
    return ur.identify([IDENT], robot="ur5", method="all")


def test_importing_urident_loads_no_analysis_code():
    code = "import sys, urident; print(sorted(m for m in ('urident.api', 'numpy', 'pinocchio') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_identify_is_what_the_command_writes(identified, tmp_path, capsys):
    assert main(["identify", IDENT, "--robot", "ur5", "--method", "all", "--out", str(tmp_path / "p.yaml")]) == 0
    printed = capsys.readouterr().out
    written = identified.save(tmp_path / "api.yaml")
    assert [p.name for p in written] == ["api.yaml", "api.ols.yaml", "api.bounded.yaml"]
    for cli_file, api_file in (("p.yaml", "api.yaml"), ("p.ols.yaml", "api.ols.yaml")):
        from urident.ident import load_params

        a, b = load_params(tmp_path / cli_file), load_params(tmp_path / api_file)
        assert a.names == b.names and np.array_equal(a.values, b.values)
    assert identified.report in printed
    assert identified.method == "consistent" and set(identified.models) == {"ols", "bounded", "consistent"}
    params = identified.parameters("ols")
    assert len(params) == len(identified.models["ols"].names) and all(np.isfinite(list(params.values())))
    document = json.loads(identified.to_json())
    assert document["robot"] == "ur5" and set(document["methods"]) == {"ols", "bounded", "consistent"}
    with pytest.raises(AttributeError):
        identified.method = "ols"  # frozen


def test_validate_json_is_the_commands_json(identified, tmp_path):
    params = tmp_path / "p.yaml"
    identified.save(params)
    out = tmp_path / "v.json"
    assert main(["validate", VALID, "--params", str(params), "--json-out", str(out)]) == 0
    check = ur.validate(str(params), [VALID])
    assert json.loads(out.read_text()) == json.loads(check.to_json())
    assert check.tau_measured.shape == check.tau_predicted.shape == (len(check.t), 6)
    assert check.rms_nm.shape == (6,) and 0 < check.e_n < 0.05
    # an Identification validates directly, with the same numbers as its saved file
    direct = ur.validate(identified, VALID)
    assert direct.e_n == pytest.approx(check.e_n, rel=1e-12)


def test_api_errors_are_the_commands_errors(identified):
    with pytest.raises(ConfigError, match="method 'best' unknown"):
        ur.identify([IDENT], robot="ur5", method="best")
    with pytest.raises(ConfigError, match="parameters are for robot 'ur5', validating on 'ur10e'"):
        ur.validate(identified, [VALID], robot="ur10e")
    with pytest.raises(ConfigError) as unknown:
        ur.identify([IDENT], robot="ur99")
    assert unknown.value.exit_code == 2 and "ur99" in str(unknown.value)


def test_errors_carry_what_their_message_names(tmp_path):
    """A notebook gets the file, line, key or violations as fields, not only in the text."""
    import pickle

    from urident.errors import SafetyError, SessionAborted, UnknownRobotError

    with pytest.raises(UnknownRobotError) as unknown:
        ur.identify([IDENT], robot="ur99")
    assert unknown.value.robot == "ur99" and "ur5e" in unknown.value.available
    bad = tmp_path / "params.yaml"
    bad.write_text("format: urident-params\nformat: again\n")
    with pytest.raises(ConfigError) as dup:
        ur.validate(bad, [VALID])
    assert (dup.value.path, dup.value.line, dup.value.key) == (str(bad), 2, "format")
    bad.write_text("[1, 2\n")
    with pytest.raises(ConfigError) as malformed:
        ur.validate(bad, [VALID])
    assert malformed.value.path == str(bad) and malformed.value.line >= 1
    from urident.excitation import load_trajectory

    loaded = load_trajectory(REPO / "experiments" / "ur5_ident.yaml")
    report = ur.check_trajectory(loaded, rate_hz=125.0)
    assert report.ok
    from dataclasses import replace

    fast = replace(loaded, trajectory=replace(loaded.trajectory, a=loaded.trajectory.a * 4, b=loaded.trajectory.b * 4))
    with pytest.raises(SafetyError) as unsafe:
        ur.check_trajectory(fast).raise_if_unsafe("fast.yaml")
    assert unsafe.value.path == "fast.yaml" and unsafe.value.violations and unsafe.value.exit_code == 3
    kept = pickle.loads(pickle.dumps(SessionAborted("run aborted", log_path=tmp_path / "x.csv", n_samples=7)))
    assert kept.log_path == tmp_path / "x.csv" and kept.n_samples == 7   # across the session process


def test_check_trajectory_reports_what_the_command_checks(capsys):
    path = REPO / "experiments" / "ur5_ident.yaml"
    report = ur.check_trajectory(path)
    assert report.ok and not report.violations
    assert main(["check-trajectory", str(path)]) == 0
    capsys.readouterr()
    assert main(["check-trajectory", str(path), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert {k: printed[k] for k in json.loads(report.to_json())} == json.loads(report.to_json())
    with pytest.raises(ConfigError, match="a trajectory for robot 'ur5', not 'ur3'"):
        ur.check_trajectory(path, robot="ur3")


def test_a_run_loads_the_robot_the_caller_named(tmp_path):
    """A robot file outside urident's set reaches the session process as its path, not its name
    (the session loads it again; by name it would be unknown)."""
    import shutil

    from urident.api import _run_robot
    from urident.model import load_robot

    mine = tmp_path / "lab_arm.yaml"
    shutil.copy(load_robot("ur5e").source, mine)
    trajectory = REPO / "experiments" / "ur5e_ident.yaml"
    assert _run_robot(str(mine), trajectory)[1] == str(mine)
    assert load_robot(_run_robot(load_robot(mine), trajectory)[1]).name == load_robot(mine).name
    assert _run_robot("ur5e", trajectory)[1] == "ur5e"
    spec, ref = _run_robot(None, trajectory)
    assert spec.name == "ur5e" and load_robot(ref).name == "ur5e"


def test_a_run_result_reads_as_plain_values(tmp_path):
    """What ``ur.run_trajectory`` returns, as a notebook would store it."""
    from urident.session import RunResult
    from urident.session.preflight import ApproachPlan
    from urident.session.rtde_io import ControllerInfo

    result = RunResult("aborted", tmp_path / "run.csv", 1234, "by the operator", 3,
                       ControllerInfo((5, 21, 0), "5.21.0", 500.0, "UR5e", None),
                       ApproachPlan(np.zeros(6), np.ones(6), 1.0, 2, 0.12), {"p99": 0.0021}, 0.05)
    doc = json.loads(result.to_json())
    assert doc["status"] == "aborted" and doc["n_samples"] == 1234 and doc["log_path"] == str(tmp_path / "run.csv")
    assert doc["controller"]["rate_hz"] == 500.0 and doc["approach"]["joint"] == 3
    assert json.loads(RunResult("checked").to_json())["controller"] is None


@pytest.mark.parametrize("script, expect", [
    ("identify_ur10e.py", "real-robot"),
    ("ros2_bag.py", "validated on the second bag"),
    ("gap_diagnosis.py", "baseline e_N"),
    ("payload.py", "set_target_payload("),
    ("mujoco_model.py", "corrected model, measured by MuJoCo"),
    ("design_excitation.py", "check-trajectory ok: True"),
])
def test_examples_run(script, expect):
    """Each example as a user runs it, from the repository root."""
    from parallel_groups import starts_a_controller

    assert not starts_a_controller(REPO / "examples" / script)  # it runs beside the controller tests
    r = subprocess.run([sys.executable, str(Path("examples") / script)], cwd=REPO, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert expect in r.stdout and "Traceback" not in r.stderr


def test_the_readmes_python_runs_as_written():
    import re

    from readme_helpers import README

    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert blocks
    for block in blocks:
        r = subprocess.run([sys.executable, "-c", block], cwd=REPO, capture_output=True, text=True,
                           timeout=600)
        assert r.returncode == 0, block + r.stderr


def test_design_excitation_is_what_the_command_writes(tmp_path, capsys):
    """One short search through the API and through `urident excite`: the same file (but the
    times), and the API's errors name its arguments where the command names its flags."""
    from urident.errors import OutputError
    from urident.excitation.design import HarmonicRateError, ToolSizeError
    from urident.excitation.files import load_trajectory

    small = dict(harmonics=2, duration_s=6.0, reduced=True, seed=4, starts=1, iterations=3)
    design = ur.design_excitation("ur5", **small)
    assert design.check.ok and design.convergence.reason == "iterations" and not design.converged
    assert design.cond == design.criteria.cond_theta and design.trajectory.a.shape == (6, 2)
    written = design.save(tmp_path / "api.yaml")
    assert main(["excite", "--robot", "ur5", "--out", str(tmp_path / "cli.yaml"), "--harmonics", "2",
                 "--duration", "6", "--reduced", "--seed", "4", "--starts", "1", "--iterations", "3",
                 "--quiet"]) == 0
    assert f"{design.cond:.4g}" in capsys.readouterr().out
    timed = ("wall_s", "cpu_s")
    api, cli = (load_trajectory(p) for p in (written, tmp_path / "cli.yaml"))
    assert np.array_equal(api.trajectory.a, cli.trajectory.a) and api.criteria == cli.criteria
    assert {k: v for k, v in api.optimization.items() if k not in timed} == \
        {k: v for k, v in cli.optimization.items() if k not in timed}
    document = json.loads(design.to_json())
    assert document["robot"] == "ur5" and document["check"]["ok"] is True
    assert document["trajectory"]["a_rad_s"] == cli.trajectory.a.tolist()
    with pytest.raises(OutputError, match="exists"):  # an existing file is not replaced without overwrite
        design.save(written)
    with pytest.raises(HarmonicRateError, match=r"^harmonics 100 with periods 1 over duration 4: .*12.5 Hz") as e:
        ur.design_excitation("ur5", harmonics=100, duration_s=4.0)
    assert e.value.exit_code == 2 and e.value.top_hz == 25.0
    with pytest.raises(ToolSizeError, match="tool capsule"):
        ur.design_excitation("ur5", for_payload=True)
    with pytest.raises(ConfigError, match="excitation settings: .*velocity_fraction"):
        ur.design_excitation("ur5", margins={"velocity_fraction": 1.5})


def test_the_excite_help_states_the_librarys_defaults():
    """The command's help carries the search's, the margins' and --for-payload's defaults as literals
    (its parser is built without numpy); they are the library's, so a changed default changes the help."""
    from urident.cli import cmd_excite
    from urident.excitation import Margins, design
    from urident.excitation.problem import ARM_JOINT_FRACTION, PAPER_Q0, ExcitationSettings

    for name in ("PAYLOAD_PERIODS", "PAYLOAD_DURATION_S", "PAYLOAD_VELOCITY_FRACTION"):
        assert getattr(cmd_excite, name) == getattr(design, name)
    assert cmd_excite.PAYLOAD_VELOCITY_CAP_RAD_S == round(design.payload_velocity_cap(), 2)
    assert cmd_excite.ARM_JOINT_FRACTION == ARM_JOINT_FRACTION
    settings, margins = ExcitationSettings(), Margins()
    assert cmd_excite.SEARCH == {name: getattr(settings, name) for name in cmd_excite.SEARCH}
    assert cmd_excite.MARGINS == {name: getattr(margins, name) for name in cmd_excite.MARGINS}
    assert set(cmd_excite.MARGINS) == set(vars(margins))
    assert PAPER_Q0 == (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)  # the --q0 help's "0,-pi/2,0,0,0,0"
    r = subprocess.run([sys.executable, "-m", "urident", "excite", "--help"], capture_output=True, text=True,
                       cwd=REPO, check=True)
    text = " ".join(r.stdout.split())
    assert f"within {design.payload_velocity_cap():.2f} rad/s" in text
    assert (f"(default {settings.starts}: each runs {settings.screen_iterations} BFGS iterations, the best "
            f"{settings.finalists} continue until converged, then up to {settings.hop_rounds} rounds of "
            f"{settings.hops} perturbed restarts") in text
    assert f"at most {settings.polish_iterations})" in text and f"(default {settings.iterations};" in text
    assert f"less than {100 * settings.tolerance / 2:g} % over its last {settings.window} iterations" in text
    assert f"(default {margins.torque_fraction:g})" in text and f"(default {margins.clearance_m:g})" in text


def test_max_velocity_bounds_every_joint_and_is_recorded(tmp_path, capsys):
    """--max-velocity caps |q̇| of every joint below the velocity fraction's bound (the shipped files
    of fast-wristed arms use it for servoJ's lag), and the file records it; a bad value is one line."""
    from urident.excitation import load_trajectory

    out = tmp_path / "capped.yaml"
    args = ["excite", "--robot", "ur3e", "--out", str(out), "--harmonics", "2", "--duration", "6", "--reduced",
            "--seed", "4", "--starts", "1", "--iterations", "3", "--quiet"]
    assert main(args + ["--max-velocity", "0.4"]) == 0
    f = load_trajectory(out)
    _, qd, _ = f.trajectory.evaluate(np.linspace(0.0, f.trajectory.duration, 4001))
    assert np.abs(qd).max() <= 0.4 * (1 + 1e-5)  # enforced on a sample grid: between samples a hair above
    assert f.optimization["max_velocity_rad_s"] == 0.4
    free = tmp_path / "free.yaml"
    assert main(args[:4] + [str(free)] + args[5:]) == 0
    _, qd_free, _ = load_trajectory(free).trajectory.evaluate(np.linspace(0.0, 6.0, 4001))
    assert np.abs(qd_free).max() > 0.4 and "max_velocity_rad_s" not in load_trajectory(free).optimization
    capsys.readouterr()
    assert main(args + ["--max-velocity", "-1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--max-velocity" in err and len(err.splitlines()) == 1
