"""Every flag of every subcommand is validated at the command line: a bad value exits 2 with one
line naming the flag, no traceback, and the command itself never starts (hypothesis, bounded)."""

from __future__ import annotations

import argparse
import importlib
import math
import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urident.cli.main import COMMANDS, get_argument_parser, main

# required arguments of each subcommand (never read: the command must not start)
BASE = {
    "demo": [],
    "model": ["--robot", "ur5"],
    "excite": ["--robot", "ur5", "--out", "x.yaml"],
    "check-trajectory": ["t.yaml"],
    "run": ["--robot", "ur5", "--host", "127.0.0.1", "--trajectory", "t.yaml", "--out", "x.csv"],
    "identify": ["x.csv", "--robot", "ur5", "--out", "p.yaml"],
    "validate": ["x.csv", "--params", "p.yaml"],
    "gap": ["--robot", "ur5", "--ident", "a.csv", "--valid", "b.csv"],
    "view": ["x.csv"],
    "convert": ["x.csv", "--bag", "out"],
    "export": ["p.yaml"],
    "simulate": ["--trajectory", "t.yaml", "--out", "x.csv"],
    "sim-controller": [],
    "payload": ["x.csv", "--params", "p.yaml", "--out", "pl.yaml"],
    "drive-gains": ["--robot", "ur5", "--without", "a.csv", "--with", "b.csv", "--payload-mass", "1",
                    "--out", "g.yaml"],
}
# flags holding a path, a robot/preset name, an address or a URL: checked when used, with an
# error naming the file (tests/test_inputs.py, tests/test_outputs.py)
FREE_TEXT = {"--robot", "--out", "--out-root", "--trajectory", "--config", "--params", "--urdf",
             "--report", "--png", "--json-out", "--save", "--host", "--effects", "--ident",
             "--valid", "--rerun", "--bag", "--mjcf", "--name", "--sim", "--write-sim", "--payload",
             "--without", "--with", "--tool-capsule-from", "--check", "--start-near", "--unloaded"}
# text no validator accepts
ALWAYS_BAD = ["nan", "inf", "-inf", "NaN", "abc", "", " ", "1e999", "1,2,3,4,5", "0x1g", "1;2"]


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = get_argument_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _value_flags():
    """(subcommand, flag, action) of every option that takes a value."""
    out = []
    for name, sub in _subparsers().items():
        for action in sub._actions:
            if action.option_strings and action.nargs != 0 and not isinstance(action, argparse._HelpAction):
                out.append((name, action.option_strings[0], action))
    return out


FLAGS = _value_flags()
VALIDATED = [(n, f, a) for n, f, a in FLAGS if f not in FREE_TEXT]


def test_every_value_flag_is_validated_or_declared_free_text():
    for name, flag, action in FLAGS:
        if flag in FREE_TEXT:
            continue
        assert action.type is not None or action.choices is not None, \
            f"urident {name} {flag} has no validator (type= or choices=)"
    assert set(BASE) == set(_subparsers()) and len(COMMANDS) == len(BASE)


def _floats(**kw):
    return st.floats(allow_nan=False, allow_infinity=False, width=64, **kw).map(repr)


def _bad_values(action: argparse.Action) -> st.SearchStrategy[str]:
    always = st.sampled_from(ALWAYS_BAD)
    if action.type is None:  # choices only
        return st.one_of(always, st.text(max_size=12).filter(lambda t: t not in action.choices))
    kind = getattr(action.type, "__name__", "")
    bounds = getattr(action.type, "bounds", None)
    if kind == "integer":
        low, high = bounds
        outside = []
        if low is not None:
            outside.append(st.integers(max_value=low - 1))
        if high is not None:
            outside.append(st.integers(min_value=high + 1))
        fractional = _floats(min_value=-1e6, max_value=1e6).filter(lambda t: float(t) != int(float(t)))
        return st.one_of(always, fractional, *(s.map(str) for s in outside))
    if kind == "number":
        low, high = bounds
        return st.one_of(always, _floats(max_value=low), _floats(min_value=high).filter(lambda t: float(t) > high))
    if kind in ("positive_float", "_dahl_rad"):
        return st.one_of(always, _floats(max_value=0.0))
    if kind == "nonnegative_float":
        return st.one_of(always, _floats(max_value=-1e-12))
    if kind == "fraction":
        return st.one_of(always, _floats(max_value=0.0), _floats(min_value=1.0).filter(lambda t: float(t) > 1))
    if kind == "percentage":
        return st.one_of(always, _floats(max_value=-1e-9), _floats(min_value=100.0).filter(lambda t: float(t) > 100))
    if kind in ("joint_vector", "drive_gains"):
        wrong_size = st.lists(st.floats(-10, 10), max_size=9).filter(lambda v: len(v) != 6)
        with_nan = st.lists(st.floats(0.1, 10), min_size=6, max_size=6).flatmap(
            lambda v: st.integers(0, 5).map(lambda k: v[:k] + [math.nan] + v[k + 1:]))
        cases = [wrong_size, with_nan]
        if kind == "drive_gains":
            cases.append(st.lists(st.floats(0.1, 10), min_size=6, max_size=6).flatmap(
                lambda v: st.integers(0, 5).map(lambda k: v[:k] + [-abs(v[k])] + v[k + 1:])))
        return st.one_of(always, *(c.map(lambda v: ",".join(repr(x) for x in v)) for c in cases))
    if kind == "row_range":
        backwards = st.tuples(st.integers(2, 10**6), st.integers(1, 10**6)).filter(lambda r: r[1] < r[0])
        return st.one_of(always, backwards.map(lambda r: f"{r[0]}-{r[1]}"), st.just("0-5"), st.just("5"))
    if kind == "names":
        return st.one_of(st.sampled_from(["abc", "nan", ",", "x,y"]),
                         st.text(string.ascii_lowercase, min_size=1, max_size=8).map(lambda t: "zz" + t))
    if kind == "payload_com":
        return st.one_of(always, st.sampled_from(["1,2", "1,2,3,4", "1,nan,2"]))
    if kind == "tool_capsule":
        return st.one_of(always, st.sampled_from(["0.05", "0,0.1", "-0.05,0.1", "0.05,-0.1", "0.05,nan"]))
    if kind == "mass_range":
        return st.one_of(always, st.sampled_from(["2,1", "0,1", "-1,2", "1", "1,nan"]))
    if kind == "_parse_version":
        return st.one_of(always, st.sampled_from(["4.1", "5", "6.0.0", "5.-1", "5.1.2.3.4"]))
    if kind == "_parse_fault":
        return st.one_of(always, st.sampled_from(["boom@1", "drop@x", "drop@-1", "stale@1:-2"]))
    if kind == "joint_map":
        return st.one_of(always, st.sampled_from(["a,b,c,d,e,f,g", "a=b,a=c", "a=b,c=b", "=x", "a=", "a,b,c,d,e,e"]))
    if kind == "tf_prefix":
        return st.one_of(always, st.sampled_from(["ur", "_ur_", "1_", "u r_"]))
    if kind == "ros_topic":
        return st.one_of(always, st.sampled_from(["joint_states", "/", "//a", "/a/", "/1a", "/a b"]))
    if kind == "log_list_file":   # a missing file, a directory, an empty list
        return st.sampled_from(["/nonexistent/logs.txt", "/", "/dev/null"])
    if kind in ("finite_float", "seed", "checked", "parse_column_map"):
        return always
    raise AssertionError(f"{action.option_strings[0]}: no bad values known for validator {kind!r}")


@pytest.fixture
def no_command(monkeypatch):
    """Any subcommand that starts is a failure: the bad value must stop at the command line."""
    for name in COMMANDS:
        module = importlib.import_module(f"urident.cli.cmd_{name}")

        def started(args, _name=name):
            raise AssertionError(f"urident {_name} started with a bad flag value")

        monkeypatch.setattr(module, "run", started)


CASES = st.sampled_from(VALIDATED).flatmap(
    lambda case: st.tuples(st.just(case[0]), st.just(case[1]), _bad_values(case[2])))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=CASES)
def test_bad_flag_values_exit_2_with_one_line_naming_the_flag(case, no_command, capsys):
    name, flag, value = case
    code = main([name, *BASE[name], f"{flag}={value}"])
    out, err = capsys.readouterr()
    assert code == 2, (name, flag, value, err)
    assert err.count("\n") == 1 and err.startswith("urident: error: "), err
    assert flag in err and "Traceback" not in err, err


@pytest.mark.parametrize("argv, flag", [
    (["excite", "--robot", "ur5", "--out", "x.yaml", "--harmonics", "1"], "--harmonics"),
    (["excite", "--robot", "ur5", "--out", "x.yaml", "--harmonics", "0"], "--harmonics"),
    (["excite", "--robot", "ur5", "--out", "x.yaml", "--harmonics", "101"], "--harmonics"),
    (["excite", "--robot", "ur5", "--out", "x.yaml", "--duration", "-1"], "--duration"),
    (["excite", "--robot", "ur5", "--out", "x.yaml", "--seed", "-1"], "--seed"),
    (["excite", "--robot", "ur5", "--out", "x.yaml", "--q0", "0,0,0,0,0"], "--q0"),
    (["sim-controller", "--initial-q=nan,0,0,0,0,0"], "--initial-q"),
    (["gap", "--robot", "ur5", "--ident", "a", "--valid", "b", "--drive-gains", "1,2,3,4,5"], "--drive-gains"),
    (["view", "x.csv", "--rows", "9-3"], "--rows"),
    (["demo", "--seed", "x"], "--seed"),
])
def test_the_issue_examples(argv, flag, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"urident: error: argument {flag}: ")


def test_excite_bounds_the_harmonics_by_the_controller_rate(tmp_path, capsys):
    """Valid flags whose combination no trajectory file can carry at the robot's rate."""
    out = tmp_path / "x.yaml"
    assert main(["excite", "--robot", "ur5", "--out", str(out), "--harmonics", "100",
                 "--duration", "4"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--harmonics 100" in err and "125 Hz" in err
    assert not out.exists()


def test_a_file_excite_writes_passes_check_trajectory(tmp_path, capsys):
    """Also with a robot file given by path, which the trajectory file then refers to relatively."""
    robot = tmp_path / "robots" / "my_ur5.yaml"
    robot.parent.mkdir()
    robot.write_text((Path(__file__).resolve().parent.parent / "urident/model/robots/ur5.yaml").read_text())
    out = tmp_path / "traj" / "e.yaml"
    out.parent.mkdir()
    argv = ["excite", "--robot", str(robot), "--out", str(out), "--harmonics", "2", "--duration", "4",
            "--starts", "1", "--iterations", "3", "--quiet"]
    assert main(argv) == 0, capsys.readouterr().err
    assert "robot: ../robots/my_ur5.yaml" in out.read_text()
    assert main(["check-trajectory", str(out)]) == 0
    assert main(argv) == 2 and "--out" in capsys.readouterr().err  # no overwrite without --overwrite
