"""The simulator-model API (``ur.diagnose_sim``, ``ur.export_model``) and the commands that are
thin shells over it: the same report, the same JSON."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import urident as ur
from urident.cli.main import main

pytest.importorskip("mujoco")
VALID = Path(__file__).resolve().parents[1] / "logs" / "sample_valid.csv"


def test_gap_sim_json_out_is_the_apis_to_json(tmp_path, capsys):
    model = tmp_path / "ur5.xml"
    done = ur.export_model(None, model, robot="ur5")
    assert done.fmt == "mjcf" and done.terms is None and model.is_file()
    js, written = tmp_path / "gap.json", tmp_path / "cli.xml"
    args = ["--rows", "1-800"]
    assert main(["gap", "--robot", "ur5", "--sim", str(model), "--valid", str(VALID), *args, "--max-effects", "2",
                 "--write-sim", str(written), "--json-out", str(js)]) == 0
    out = capsys.readouterr().out
    report = ur.diagnose_sim(model, [VALID], "ur5", max_effects=2, write_sim=tmp_path / "api.xml",
                             log_options={"rows": (1, 800)})
    doc = json.loads(report.to_json())
    cli = json.loads(js.read_text())
    assert doc["sim_corrected"].pop("path").endswith("api.xml") and cli["sim_corrected"].pop("path").endswith("cli.xml")
    assert doc == cli
    text = "\n".join(report.lines())
    assert text.replace(str(tmp_path / "api.xml"), str(written)) in out
    assert report.corrected is not None and report.corrected.shrink_pct.shape == (6,)
    assert doc["sim_predicted"]["e_n"] == pytest.approx(report.predicted_e_n)
    # a finding the format expresses has a written value, and the dataclasses read by name
    assert all(f.written_magnitude for f in report.findings if f.expressible)
    assert report.corrected.after["damping"].shape == (6,)


def test_export_model_is_what_export_writes_and_prints(tmp_path, capsys):
    from urident.ident.payload import Payload
    from urident.ident.payload_file import save_payload

    params = tmp_path / "p.yaml"
    ident = ur.identify([VALID.with_name("sample_ident.csv")], "ur5", method="consistent")
    ident.save(params)
    payload = tmp_path / "payload.yaml"
    save_payload(Payload("ur5", 1.5, [0.0, 0.0, 0.05], np.eye(3) * 1e-3), payload)
    xml = tmp_path / "cli.urdf"
    assert main(["export", str(params), "--urdf", str(xml), "--valid", str(VALID), "--payload", str(payload)]) == 0
    out = capsys.readouterr().out
    done = ur.export_model(str(params), tmp_path / "api.urdf", valid_logs=[VALID], payload=str(payload))
    assert "\n".join(done.lines()).replace(str(tmp_path / "api.urdf"), str(xml)) in out
    assert (tmp_path / "api.urdf").read_text().replace("api.urdf", "cli.urdf") == xml.read_text().replace(
        "api.urdf", "cli.urdf")
    doc = json.loads(done.to_json())
    assert doc["format"] == "urdf" and doc["robot"] == "ur5" and doc["not_expressed"][0]["share_pct"]
    assert any("payload" in n for n in doc["notes"])
    from urident.errors import ConfigError

    with pytest.raises(ConfigError, match="--nominal has none"):
        ur.export_model(None, tmp_path / "n.xml", robot="ur5", valid_logs=[VALID])
    with pytest.raises(ConfigError, match="must be MJCF"):
        ur.export_model(str(params), tmp_path / "x.txt")
