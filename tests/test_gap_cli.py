"""``urident gap``: arguments, console report, JSON file, one-line errors."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest

from urident.cli.main import main
from urident.gap.schema import errors, report_schema
from urident.logs import LOG_FIELDS, LogWriter


def _write_log(path, rec):
    n = len(rec.t)
    zeros = np.zeros(6)
    with LogWriter(path, LOG_FIELDS, {"robot": "ur10e", "rate_hz": 100.0}, overwrite=True) as w:
        for k in range(n):
            w.append({"t": rec.t[k], "q": rec.q[k], "qd": rec.qd[k], "current": rec.current[k],
                      "target_q": rec.q[k], "target_qd": rec.qd[k], "target_qdd": zeros,
                      "target_current": zeros, "target_moment": zeros,
                      "temperature": np.full(6, 30.0), "robot_mode": 7, "safety_status_bits": 1,
                      "runtime_state": 2})


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    from test_gap_diagnose import simulate, sines
    from urident.model import load_robot

    spec = load_robot("ur10e")
    d = tmp_path_factory.mktemp("gap")
    eff = "effects:\n  - name: current_offset\n    joints: [4]\n    offset_a: 0.1\n"
    paths = []
    for seed, name in ((61, "ident.csv"), (62, "valid.csv")):
        rec = simulate(spec, sines(seed, duration=16.0), eff, seed=seed)
        _write_log(d / name, rec)
        paths.append(d / name)
    return paths


def test_cli_reports_and_writes_json(logs, tmp_path, capsys):
    out = tmp_path / "gap.json"
    rc = main(["gap", "--robot", "ur10e", "--ident", str(logs[0]), "--valid", str(logs[1]),
               "--json-out", str(out), "--max-effects", "1"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "Where" in text and "Which" in text and "How far" in text
    assert "current_offset on joint 4" in text
    doc = json.loads(out.read_text())
    assert errors(doc) == []                 # the shipped schema: no NaN, None, infinity
    jsonschema.validate(doc, report_schema())  # and the reference validator agrees
    assert doc["findings"][0]["effect"] == "current_offset" and doc["findings"][0]["joint"] == 4
    assert len(doc["baseline"]["rms_nm"]) == 6 and len(doc["final"]["rms_nm"]) == 6
    assert doc["final"]["rms_nm"][3] < doc["baseline"]["rms_nm"][3]


def test_cli_rows_per_set_and_effect_subset(logs, capsys):
    rc = main(["gap", "--robot", "ur10e", "--ident", str(logs[0]), "--valid", str(logs[1]),
               "--ident-rows", "1-1400", "--valid-rows", "200-1500", "--effects", "stribeck,load_friction"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "current_offset" not in text.split("Which")[1]


def test_cli_errors_are_one_line(logs, capsys):
    rc = main(["gap", "--robot", "ur10e", "--ident", str(logs[0]), "--valid", str(logs[1]),
               "--effects", "gremlins"])
    err = capsys.readouterr().err
    assert rc != 0 and err.startswith("urident: error: ") and "gremlins" in err
    assert err.count("\n") == 1
    rc = main(["gap", "--robot", "ur10e", "--ident", str(logs[0]) + ".missing", "--valid", str(logs[1])])
    err = capsys.readouterr().err
    assert rc != 0 and err.startswith("urident: error: ") and err.count("\n") == 1


@pytest.fixture(scope="module")
def check_logs(tmp_path_factory):
    """Two held-out logs: one with the same 0.1 A offset on joint 4, one where it is gone."""
    from test_gap_diagnose import simulate, sines
    from urident.model import load_robot

    spec = load_robot("ur10e")
    d = tmp_path_factory.mktemp("gapcheck")
    eff = "effects:\n  - name: current_offset\n    joints: [4]\n    offset_a: 0.1\n"
    _write_log(d / "same.csv", simulate(spec, sines(63, duration=16.0), eff, seed=63))
    _write_log(d / "gone.csv", simulate(spec, sines(64, duration=16.0), None, seed=64))
    return d / "same.csv", d / "gone.csv"


def test_check_scores_each_finding_on_held_out_logs(logs, check_logs, tmp_path, capsys):
    """An offset present on the check log holds there (checked shrink interval above 0); on a log
    where it is gone the same finding no longer shrinks joint 4 and is marked as not holding."""
    out = tmp_path / "gap.json"
    base = ["gap", "--robot", "ur10e", "--ident", str(logs[0]), "--valid", str(logs[1]), "--max-effects", "1"]
    assert main(base + ["--check", str(check_logs[0]), "--json-out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Check (held-out logs" in text and "holds" in text and "DOES NOT HOLD" not in text
    doc = json.loads(out.read_text())
    assert errors(doc) == []
    jsonschema.validate(doc, report_schema())
    row = doc["check"]["findings"][0]
    assert (row["effect"], row["joint"], row["holds"]) == ("current_offset", 4, True)
    lo, hi = row["checked_shrink_ci95_pct"]
    assert 0 < lo <= row["checked_shrink_pct"] <= hi
    assert row["predicted_shrink_ci95_pct"][0] > 0
    # the prediction for the check log's motion (the offset is there too) lies in the checked interval
    assert lo <= row["extrapolated_shrink_pct"] <= hi
    assert main(base + ["--check", str(check_logs[1]), "--json-out", str(out), "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert "DOES NOT HOLD on the check logs" in text
    row = json.loads(out.read_text())["check"]["findings"][0]
    assert row["holds"] is False and row["checked_shrink_ci95_pct"][0] <= 0
    # from the motion alone the offset would still help: only the check logs' torque shows it gone
    assert row["extrapolated_shrink_pct"] > 0


def test_check_log_reused_for_selection_is_refused(logs, capsys):
    rc = main(["gap", "--robot", "ur10e", "--ident", str(logs[0]), "--valid", str(logs[1]),
               "--check", str(logs[1])])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("urident: error: --check ") and err.count("\n") == 1
