"""`urident demo`, exactly as the README's first line runs it: the newcomer's path, end to end
(simulated controller, the identification and validation runs of experiments/ back to back,
identification, validation, gap diagnosis, Rerun files). The shortened mode is covered on a CB3
arm in tests/test_demo_family.py."""

import json
import shutil
import subprocess
from pathlib import Path

from urident.cli.main import main
from urident.logs import load_log

REPO = Path(__file__).resolve().parent.parent


def test_the_readme_demo_runs_the_whole_pipeline():
    before = set((REPO / "logs").glob("demo-*"))
    r = subprocess.run(["urident", "demo"], cwd=REPO, capture_output=True, text=True, timeout=900,
                       stdin=subprocess.DEVNULL)
    made = sorted(set((REPO / "logs").glob("demo-*")) - before)
    try:
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr
        (run_dir,) = made
        for name in ("ident.csv", "ident.yaml", "valid.csv", "params.yaml", "validation.json",
                     "gap.json", "gap.rrd", "validation.rrd", "ident_live.rrd", "valid_live.rrd"):
            assert (run_dir / name).is_file(), name
        for log in ("ident.csv", "valid.csv"):
            rec = load_log(run_dir / log)
            assert rec.status == "completed" and rec.robot == "ur5e" and len(rec.t) > 20 * 500
            # the first run's stop check touched nothing of the second run's (and vice versa)
            notes = rec.metadata["extra"]["stop_problems"]
            assert not [n for n in notes if "after the session exited" in n], notes
        validation = json.loads((run_dir / "validation.json").read_text())
        assert {"e_n", "rms_nm", "rre_pct", "n_samples", "method"} <= set(validation["results"][0])
        gap = json.loads((run_dir / "gap.json").read_text())
        assert gap["final"]["e_n"] <= gap["baseline"]["e_n"]
        assert "urident demo finished" in r.stdout and "gap diagnosis: e_N" in r.stdout
        assert "Traceback" not in r.stderr
    finally:
        for path in made:
            shutil.rmtree(path, ignore_errors=True)


def test_second_demo_does_not_clash(tmp_path):
    """A second run gets a new directory (even in the same second) and a controller address
    whose ports are free (a leftover controller keeps its own)."""
    import socket

    from urident.cli.demo import PORTS, free_loopback_address, new_run_directory

    first, second = new_run_directory(tmp_path), new_run_directory(tmp_path)
    assert first != second and first.is_dir() and second.is_dir()
    host = free_loopback_address()
    busy = socket.socket()
    busy.bind((host, PORTS[0]))
    busy.listen()
    try:
        for _ in range(5):
            assert free_loopback_address() != host
    finally:
        busy.close()


def test_readme_post_hoc_examples_on_the_sample_logs(tmp_path, capsys):
    """The README's post-hoc commands, as written, on logs/sample_*.csv."""
    from pathlib import Path

    logs = Path(__file__).resolve().parent.parent / "logs"
    ident, valid = str(logs / "sample_ident.csv"), str(logs / "sample_valid.csv")
    params = str(tmp_path / "params.yaml")
    assert main(["identify", ident, "--robot", "ur5", "--method", "all", "--out", params]) == 0
    assert main(["validate", valid, "--params", params, "--json-out", str(tmp_path / "v.json")]) == 0
    assert json.loads((tmp_path / "v.json").read_text())["e_n"] < 0.05
    assert main(["view", valid, "--params", params, "--save", str(tmp_path / "s.rrd")]) == 0
    assert main(["gap", "--robot", "ur5", "--ident", ident, "--valid", valid,
                 "--json-out", str(tmp_path / "gap.json")]) == 0
    gap = json.loads((tmp_path / "gap.json").read_text())
    assert len(gap["baseline"]["rms_nm"]) == 6


def test_summary_sets_the_injected_effects_beside_the_findings():
    """Named, missed and invented are read off the effects the simulated controller ran and the
    diagnosis' findings, with magnitudes on both sides."""
    from pathlib import Path

    from urident.cli.demo import DemoResult, compare_effects, summary

    injected = ({"name": "stribeck", "joints": [1, 2], "static_friction_ratio": [1.3, 1.3]},
                {"name": "current_offset", "joints": [4], "offset_a": [0.03]})
    findings = [{"effect": "stribeck", "joint": 2, "shrink_pct": 12.5, "rms_before_nm": 1.0,
                 "rms_after_nm": 0.875, "magnitude": {"static_friction_nm": 0.8}},
                {"effect": "load_friction", "joint": 3, "shrink_pct": 4.0, "rms_before_nm": 1.0,
                 "rms_after_nm": 0.96, "magnitude": {"coefficient": 0.02}}]
    rows, invented = compare_effects(injected, findings)
    assert [(r["effect"], r["named"], r["missed"]) for r in rows] == [("stribeck", [2], [1]),
                                                                     ("current_offset", [], [4])]
    assert [f["effect"] for f in invented] == ["load_friction"]
    gap = {"baseline": {"e_n": 0.1}, "final": {"e_n": 0.09}, "findings": findings}
    text = summary(DemoResult(Path("x"), {"method": "ols", "e_n": 0.1, "rms_nm": [0.0] * 6}, gap, 1.0,
                              "UR5e", injected))
    assert "1 of 3 injected (effect, joint) named, 1 invented" in text
    assert "static_friction_ratio [1.3, 1.3]" in text and "static_friction_nm 0.8" in text
    assert "missed: 1" in text and "invented: load_friction on joint 3" in text

    # a finding the diagnosis reports as confounded with the injected effect is not invented
    alike = [{**findings[1], "effect": "asymmetric_coulomb", "joint": 4, "confounded_with": ["current_offset on joint 4"]}]
    rows, invented = compare_effects(injected, findings[:1] + alike)
    assert rows[1]["confounded"] == [4] and rows[1]["missed"] == [] and invented == []
    text = summary(DemoResult(Path("x"), {"method": "ols", "e_n": 0.1, "rms_nm": [0.0] * 6},
                              {**gap, "findings": findings[:1] + alike}, 1.0, "UR5e", injected))
    assert "1 of 3 injected (effect, joint) named, 1 confounded with a finding, 0 invented" in text
    assert "confounded with current_offset on joint 4" in text and "confounded with a finding: 4" in text
