"""Hypothesis, bounded (issue 32): option values and file contents of the newer commands —
``payload``, ``drive-gains``, ``export``, ``gap --sim`` / ``--check`` and the bag reader — keep the
bad-input promise: exit 0 with a finite result in the physical range, or exit 2 with one line;
never 70 (an internal error); no third-party output; no existing file changed.

Commands run in-process (``urident.cli.main.main``) on short UR5 simulations; few examples each."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urident.cli.main import main
from urident.model import load_robot

from fuzz_helpers import assert_promise, file_states, key_paths

ROOT = Path(__file__).resolve().parent.parent
MASS, COM = 2.0, [0.01, -0.02, 0.06]
ROWS = ["--rows", "1-1200"]
FUZZ = settings(max_examples=6, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

#: Numbers as a user might type them: plausible (most: they reach the computation), on the edges,
#: absurd, not numbers.
NUMBERS = st.one_of(st.sampled_from([0.0, -1.0, 1e-12, 1e300, -1e300, 1e6, math.nan, math.inf]),
                    st.sampled_from([0.05, 0.5, 2.0, 0.002, -0.03, 0.2, 1.0]), st.floats(-1, 1, allow_nan=False))
MASSES = st.sampled_from([0.3, 1.0, 1.9, 2.0, 2.1, 4.0, 5.0, 6.0, 1e3, 1e-6])


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("cmdfuzz")
    (d / "eff.yaml").write_text(yaml.safe_dump({"effects": [{"name": "payload_error", "mass_kg": MASS,
                                                             "offset_m": COM}]}))
    for name, traj, extra in (("arm", "ur5_ident", []), ("valid", "ur5_valid", []),
                              ("load", "ur5_ident", ["--effects", str(d / "eff.yaml")])):
        assert main(["simulate", "--trajectory", str(ROOT / "experiments" / f"{traj}.yaml"),
                     "--out", str(d / f"{name}.csv"), "--seed", "3", *extra]) == 0
    assert main(["identify", str(d / "arm.csv"), "--robot", "ur5", "--out", str(d / "arm_params.yaml")]) == 0
    assert main(["export", "--nominal", "--robot", "ur5", "--mjcf", str(d / "ur5.xml"),
                 "--urdf", str(d / "ur5.urdf")]) == 0
    assert main(["convert", str(d / "valid.csv"), "--bag", str(d / "bag"), "--rows", "1-300"]) == 0
    return d


def _run(capfd, argv, where: Path) -> tuple[int, str, str]:
    before = file_states(where)
    capfd.readouterr()
    code = main([str(a) for a in argv])
    out, err = capfd.readouterr()
    assert_promise(code, out, err, before, {p: s for p, s in file_states(where).items() if p in before})
    return code, out, err


def _fresh(where: Path, name: str) -> Path:
    """An output path that does not exist yet (removed if a previous example wrote it)."""
    path = where / "out" / name
    path.parent.mkdir(exist_ok=True)
    if path.is_dir():
        shutil.rmtree(path)
    path.unlink(missing_ok=True)
    return path


def _text(v: float) -> str:
    return repr(float(v))


@FUZZ
@given(mass_range=st.one_of(st.sampled_from([(0.1, 1.0), (5.0, 10.0), (1.0, 3.0), (1.9, 2.1), (0.5, 20.0)]),
                            st.tuples(MASSES, MASSES)), tare=st.sampled_from([None, "arm", "load", "copy"]),
       tare_rows=st.sampled_from([None, "1-1", "1-1200", "5-900"]))
def test_payload_options(data, capfd, mass_range, tare, tare_rows):
    if tare == "copy" and not (data / "copy.csv").exists():
        shutil.copy(data / "load.csv", data / "copy.csv")
        shutil.copy(data / "load.yaml", data / "copy.yaml")
    out = _fresh(data, "payload.yaml")
    argv = ["payload", data / "load.csv", "--params", data / "arm_params.yaml", *ROWS, "--out", out,
            "--mass-range=" + ",".join(_text(v) for v in mass_range)]
    if tare:
        argv += ["--unloaded", data / f"{tare}.csv"]
    if tare_rows:
        argv += ["--unloaded-rows", tare_rows]
    code, stdout, _ = _run(capfd, argv, data)
    if tare in ("load", "copy"):
        assert code == 2            # the loaded log as its own tare
    if code == 0:
        from urident.ident.payload_file import load_payload

        spec = load_robot("ur5")
        load_payload(out, spec)           # what the command wrote, every reader reads
        doc = yaml.safe_load(out.read_text())
        assert 0 < doc["mass_kg"] <= spec.payload_kg and np.all(np.isfinite(doc["com_m"]))
        low, high = sorted(mass_range)
        if min(abs(doc["mass_kg"] - low), abs(doc["mass_kg"] - high)) < 5e-4 * doc["mass_kg"]:
            assert "m" not in doc["identifiable"] and doc["urscript"] is None
            assert "set_target_payload(" not in stdout and "--mass-range bound" in stdout


@settings(FUZZ, max_examples=4)
@given(mass=MASSES, com=st.one_of(st.just(tuple(COM)), st.tuples(NUMBERS, NUMBERS, NUMBERS)),
       order=st.sampled_from(["right", "swapped", "right", "same"]))
def test_drive_gains_options(data, capfd, mass, com, order):
    out = _fresh(data, "gains.yaml")
    without, with_ = {"right": ("arm", "load"), "swapped": ("load", "arm"), "same": ("arm", "arm")}[order]
    code, _, _ = _run(capfd, ["drive-gains", "--robot", "ur5", "--without", data / f"{without}.csv",
                                "--with", data / f"{with_}.csv", *ROWS, f"--payload-mass={_text(mass)}",
                              "--payload-com=" + ",".join(_text(v) for v in com), "--out", out], data)
    if order != "right":
        assert code == 2
    if code == 0:
        from urident.ident.gains_file import load_gains
        from urident.ident.torque import gain_problem

        gains = load_gains(out)[1]
        assert gain_problem(gains, load_robot("ur5").drive_gains) is None


PAYLOAD_KEYS = st.sampled_from([("mass_kg",), ("com_m", 0), ("com_m", 2), ("inertia_kg_m2", 0, 0),
                                ("inertia_kg_m2", 2, 2), ("inertia_kg_m2", 0, 1)])


@FUZZ
@given(key=PAYLOAD_KEYS, value=NUMBERS, command=st.sampled_from(["export", "validate"]))
def test_payload_file_contents(data, capfd, key, value, command):
    doc = {"format": "urident-payload", "version": 1, "robot": "ur5", "mass_kg": 1.5, "com_m": [0.0, 0.0, 0.05],
           "inertia_kg_m2": [[0.004, 0.0, 0.0], [0.0, 0.004, 0.0], [0.0, 0.0, 0.002]]}
    node = doc
    for k in key[:-1]:
        node = node[k]
    node[key[-1]] = value
    if key[0] == "inertia_kg_m2" and key[1] != key[2]:
        doc["inertia_kg_m2"][key[2]][key[1]] = value       # kept symmetric: the value's range is fuzzed
    payload = data / "fuzz_payload.yaml"
    payload.write_text(yaml.safe_dump(doc))
    if command == "export":
        out = _fresh(data, "model.xml")
        code, _, _ = _run(capfd, ["export", "--nominal", "--robot", "ur5", "--mjcf", out, "--payload", payload], data)
        if code == 0:
            assert out.exists()
    else:
        code, stdout, _ = _run(capfd, ["validate", "--params", data / "arm_params.yaml", data / "valid.csv", *ROWS,
                                       "--payload", payload], data)
        if code == 0:
            assert "inf" not in stdout and "nan" not in stdout
    if not (math.isfinite(value) and abs(value) < 1e5) or (key == ("mass_kg",) and value <= 0):
        assert code == 2


MJCF_ATTRS = st.sampled_from(["mass", "fullinertia", "pos"])


@FUZZ
@given(fmt=st.sampled_from(["xml", "urdf"]), attr=MJCF_ATTRS, value=NUMBERS, body=st.integers(0, 5))
def test_gap_sim_model_contents(data, capfd, monkeypatch, fmt, attr, value, body):
    """A simulator model with one inertial value replaced: MuJoCo's log file and urdfdom's lines never
    appear; the torques at rest must be the arm's."""
    text = (data / f"ur5.{fmt}").read_text()
    if fmt == "xml":
        pattern = {"mass": r'mass="[^"]*"', "fullinertia": r'diaginertia="[^" ]*',   # MuJoCo writes it so
                   "pos": r'<inertial pos="[^" ]*'}[attr]
        repl = {"mass": f'mass="{value!r}"', "fullinertia": f'diaginertia="{value!r}',
                "pos": f'<inertial pos="{value!r}'}[attr]
    else:
        pattern = {"mass": r'<mass value="[^"]*"', "fullinertia": r'ixx="[^"]*"', "pos": r'damping="[^"]*"'}[attr]
        repl = {"mass": f'<mass value="{value!r}"', "fullinertia": f'ixx="{value!r}"',
                "pos": f'damping="{value!r}"'}[attr]
    matches = list(re.finditer(pattern, text))
    m = matches[body % len(matches)]
    model = data / f"fuzz_model.{fmt}"
    model.write_text(text[:m.start()] + repl + text[m.end():])
    work = data / "cwd"
    work.mkdir(exist_ok=True)
    monkeypatch.chdir(work)
    _run(capfd, ["gap", "--robot", "ur5", "--sim", model, "--valid", data / "valid.csv", "--rows", "1-400",
                 "--max-effects", "1", "--effects", "current_offset"], data)
    assert list(work.iterdir()) == []          # no MUJOCO_LOG.TXT


@FUZZ
@given(source=st.sampled_from(["valid", "arm", "load"]), rows=st.sampled_from([None, "1-400", "2-401", "1-1"]),
       copy=st.booleans())
def test_gap_check_logs(data, capfd, source, rows, copy):
    """A held-out check log: the same data as a validation or identification log (under another
    name, same rows) is refused; anything else runs or fails in one line."""
    check = data / f"{source}.csv"
    if copy:
        check = data / f"copy_{source}.csv"
        if not check.exists():
            shutil.copy(data / f"{source}.csv", check)
            shutil.copy(data / f"{source}.yaml", check.with_suffix(".yaml"))
    argv = ["gap", "--robot", "ur5", "--ident", data / "arm.csv", "--valid", data / "valid.csv", "--rows", "1-400",
            "--check", check, "--max-effects", "1", "--effects", "current_offset"]
    if rows:
        argv += ["--check-rows", rows]
    code, _, err = _run(capfd, argv, data)
    if source in ("valid", "arm") and rows in (None, "1-400"):
        assert code == 2 and "held out" in err


JUNK = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(width=64), st.text(max_size=6),
                 st.just([]), st.just({}))


@FUZZ
@given(pick=st.integers(0, 10**6), value=JUNK, garbage=st.one_of(st.none(), st.binary(max_size=40)))
def test_bag_metadata_contents(data, capfd, pick, value, garbage):
    bag = data / "fuzz_bag"
    if bag.exists():
        shutil.rmtree(bag)
    shutil.copytree(data / "bag", bag)
    meta = bag / "metadata.yaml"
    if garbage is not None:
        meta.write_bytes(garbage)
    else:
        doc = yaml.safe_load(meta.read_text())
        paths = [p for p in key_paths(doc, max_items=3) if p]
        path = paths[pick % len(paths)]
        node = doc
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
        meta.write_text(yaml.safe_dump(doc))
    _run(capfd, ["validate", "--params", data / "arm_params.yaml", bag], data)


# -- the cases, one each ------------------------------------------------------------------

def _one_line(capfd, argv, *needles) -> str:
    capfd.readouterr()
    assert main([str(a) for a in argv]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("urident: error: "), err
    for needle in needles:
        assert needle in err, err
    return err


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_two_outputs_to_one_path_are_refused_before_any_work(data, capfd, overwrite):
    out = _fresh(data, "same.out")
    _one_line(capfd, ["export", "--nominal", "--robot", "ur5", "--mjcf", out, "--urdf", out, *overwrite],
              "--urdf", "also the --mjcf output")
    assert not out.exists()
    params = data / "arm_params.yaml"
    before = params.read_bytes()
    _one_line(capfd, ["export", params, "--urdf", params, "--overwrite"], "is also the input")
    assert params.read_bytes() == before


def test_gap_ident_from_and_check_rows(data, capfd):
    listing = data / "ident.txt"
    listing.write_text("arm.csv\n")
    capfd.readouterr()
    assert main(["gap", "--robot", "ur5", "--ident-from", str(listing), "--valid", str(data / "valid.csv"),
                 "--rows", "1-400", "--max-effects", "1", "--effects", "current_offset"]) == 0
    _one_line(capfd, ["gap", "--robot", "ur5", "--ident", data / "arm.csv", "--valid", data / "valid.csv",
                      "--check-rows", "1-100"], "--check-rows needs --check")
    _one_line(capfd, ["gap", "--robot", "ur5", "--sim", data / "ur5.xml", "--valid", data / "valid.csv",
                      "--check", data / "arm.csv"], "--check is not available with --sim")


def test_simulator_models_libraries_cannot_read(data, capfd, monkeypatch):
    """urdfdom's lines and MuJoCo's MUJOCO_LOG.TXT never reach the terminal or the directory."""
    monkeypatch.chdir(data / "cwd" if (data / "cwd").is_dir() else data)
    urdf = data / "nan.urdf"
    urdf.write_text(re.sub(r'damping="[^"]*"', 'damping="nan"', (data / "ur5.urdf").read_text(), count=1))
    _one_line(capfd, ["gap", "--robot", "ur5", "--sim", urdf, "--valid", data / "valid.csv"],
              "<joint name=", "<dynamics damping='nan'>")
    mjcf = data / "nan.xml"
    mjcf.write_text(re.sub(r'mass="[^"]*"', 'mass="nan"', (data / "ur5.xml").read_text(), count=1))
    work = data / "mjcwd"
    work.mkdir(exist_ok=True)
    monkeypatch.chdir(work)
    _one_line(capfd, ["gap", "--robot", "ur5", "--sim", mjcf, "--valid", data / "valid.csv"], "shoulder_pan_link")
    assert list(work.iterdir()) == []


def test_messages_name_the_culprit(data, capfd):
    _one_line(capfd, ["payload", data / "load.csv", "--params", data / "arm_params.yaml", "--unloaded",
                      data / "arm.csv", "--unloaded-rows", "1-1", "--out", _fresh(data, "p.yaml")],
              f"--unloaded {data / 'arm.csv'} (--unloaded-rows 1-1)")
    _one_line(capfd, ["excite", "--robot", "ur5", "--tool-capsule", "10,10", "--out", _fresh(data, "t.yaml")],
              "tool capsule: radius 10 m")
    bag = data / "garbage_bag"
    if bag.exists():
        shutil.rmtree(bag)
    shutil.copytree(data / "bag", bag)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: [1, 2\n: :\n")
    _one_line(capfd, ["validate", "--params", data / "arm_params.yaml", bag], "metadata.yaml:3:")
