"""`urident demo --robot R`: the pipeline on another arm than the default UR5e (a CB3 UR3 at
125 Hz here, in the shortened mode), and a clear error for a robot urident does not know."""

import json

from urident.cli.main import main
from urident.logs import load_log


def test_quick_demo_on_a_cb3_ur3(tmp_path, capsys):
    assert main(["demo", "--quick", "--robot", "ur3", "--out-root", str(tmp_path)]) == 0
    (run_dir,) = [p for p in tmp_path.iterdir() if p.name.startswith("demo-")]
    for log in ("ident.csv", "valid.csv"):
        rec = load_log(run_dir / log)
        assert rec.status == "completed" and rec.robot == "ur3" and rec.rate_hz == 125.0
        assert len(rec.t) > 8 * 125
    params = (run_dir / "params.yaml").read_text()
    assert "robot: ur3" in params
    gap = json.loads((run_dir / "gap.json").read_text())
    assert gap["final"]["e_n"] <= gap["baseline"]["e_n"]
    out = capsys.readouterr().out
    assert "simulated UR3 controller" in out and "at 125 Hz" in out
    assert "validation on the second trajectory (UR3," in out
    assert "robot file 'ur3': nominal values" in out


def test_demo_with_an_unknown_robot_exits_2(tmp_path, capsys):
    assert main(["demo", "--robot", "ur99", "--out-root", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown robot 'ur99'" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())
