"""Many logs at once (directories, globs, --logs-from lists) and the progress line."""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import pytest

from urident.cli.main import main
from urident.errors import ConfigError
from urident.cli.log_args import expand_log_paths, logs_from_args
from urident.progress import Progress, progress_iter

REPO = Path(__file__).resolve().parent.parent
SAMPLE = REPO / "logs" / "sample_ident.csv"


def _copy_log(dst: Path) -> Path:
    shutil.copy(SAMPLE, dst.with_suffix(".csv"))
    shutil.copy(SAMPLE.with_suffix(".yaml"), dst.with_suffix(".yaml"))
    return dst.with_suffix(".csv")


def test_expand_directory_glob_and_bag(tmp_path):
    d = tmp_path / "runs"
    d.mkdir()
    b = _copy_log(d / "b")
    a = _copy_log(d / "a")
    bag = d / "c_bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (d / "notes.txt").write_text("x")
    assert expand_log_paths([str(d)]) == [str(a), str(b), str(bag)]   # name order; a bag is one log
    assert expand_log_paths([str(d / "*.csv")]) == [str(a), str(b)]
    assert expand_log_paths([str(bag)]) == [str(bag)]
    with pytest.raises(ConfigError, match="no log matches"):
        expand_log_paths([str(d / "*.nope")])
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ConfigError, match="holds no log"):
        expand_log_paths([str(empty)])
    with pytest.raises(ConfigError, match="no LOG given"):
        logs_from_args([], [])


def test_identify_from_directory_and_list_reports_every_log(tmp_path, capsys):
    d = tmp_path / "runs"
    d.mkdir()
    logs = [_copy_log(d / n) for n in ("r1", "r2")]
    listing = tmp_path / "list.txt"
    listing.write_text("# two runs\nruns/r1.csv\n\nruns/r2.csv  # second\n")
    out1, out2 = tmp_path / "p1.yaml", tmp_path / "p2.yaml"
    assert main(["identify", str(d), "--robot", "ur5", "--out", str(out1)]) == 0
    text1 = capsys.readouterr().out
    assert main(["identify", "--logs-from", str(listing), "--robot", "ur5", "--out", str(out2)]) == 0
    text2 = capsys.readouterr().out
    assert "logs used (2):" in text1 and "logs used (2):" in text2
    for log in logs:
        assert str(log) in text1
    assert text1.count("sha256 ") == 2
    # the same two logs, so the same parameters (the seam between runs is never differentiated)
    assert out1.read_text().split("provenance")[0] == out2.read_text().split("provenance")[0]


def test_logs_from_errors(tmp_path, capsys):
    missing = tmp_path / "nope.txt"
    assert _exit(["identify", "--logs-from", str(missing), "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]) == 2
    assert "--logs-from" in capsys.readouterr().err
    blank = tmp_path / "blank.txt"
    blank.write_text("# nothing\n\n")
    assert _exit(["identify", "--logs-from", str(blank), "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]) == 2
    assert "lists no log" in capsys.readouterr().err
    assert main(["identify", "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]) == 2
    assert "no LOG given" in capsys.readouterr().err


def _exit(argv) -> int:
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code)


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_only_on_a_terminal():
    pipe = io.StringIO()
    assert list(progress_iter(range(5), "loading", stream=pipe, delay=0, interval=0)) == list(range(5))
    assert pipe.getvalue() == ""
    tty = _Tty()
    with Progress("loading logs", total=4, stream=tty, delay=0, interval=0) as p:
        for _ in range(4):
            p.advance()
    text = tty.getvalue()
    assert "\rloading logs: 1/4 (25 %)" in text and "4/4 (100 %)" in text
    assert text.endswith("\r")   # the line is cleared at the end
    quiet = _Tty()
    with Progress("short", total=2, stream=quiet, delay=60) as p:   # work shorter than the delay
        p.advance(2)
    assert quiet.getvalue() == ""


def test_view_sends_a_decimated_series_and_keeps_full_metrics(tmp_path):
    import numpy as np

    from urident.ident.metrics import error_metrics
    from urident.logs.recording import Recording
    from urident.model import load_robot
    from urident.viz import close_recording, open_recording, read_rrd
    from urident.viz.replay import MAX_DISPLAY_SAMPLES, display_stride, log_recording_comparison

    spec = load_robot("ur5e")
    n = 2 * MAX_DISPLAY_SAMPLES + 7
    t = np.arange(n) * 0.002
    rng = np.random.default_rng(0)
    q = rng.normal(0, 0.1, (n, 6))
    tau_m = rng.normal(size=(n, 6))
    tau_p = tau_m + 0.1 * rng.normal(size=(n, 6))
    recording = Recording(t=t, q=q, qd=np.zeros((n, 6)), current=np.zeros((n, 6)), target_q=q + 1e-3)
    out = tmp_path / "big.rrd"
    rec = open_recording("urident_test", save=out)
    metrics = log_recording_comparison(rec, spec, recording, t, q, tau_m, tau_p, robot_path=None)
    close_recording(rec)
    contents = read_rrd(out)
    k = display_stride(n)
    assert k == 3
    times, values = contents.scalars(f"torque/{spec.joint_names[0]}/residual")
    assert len(values) == len(range(0, n, k)) <= MAX_DISPLAY_SAMPLES
    np.testing.assert_allclose(values, (tau_m - tau_p)[::k, 0])
    _, tracking = contents.scalars(f"tracking/{spec.joint_names[0]}")
    assert len(tracking) == len(values)
    e_n, rms = error_metrics(tau_p - tau_m)   # metrics from every sample, not the drawn ones
    assert metrics["e_N"] == pytest.approx(e_n)
    assert metrics[f"rms/{spec.joint_names[0]}"] == pytest.approx(rms[0])


def test_gap_takes_a_directory_and_a_list_and_lists_every_log(tmp_path, capsys):
    ident_dir = tmp_path / "ident"
    ident_dir.mkdir()
    ident = _copy_log(ident_dir / "run1")
    shutil.copy(REPO / "logs" / "sample_valid.csv", tmp_path / "valid.csv")
    shutil.copy(REPO / "logs" / "sample_valid.yaml", tmp_path / "valid.yaml")
    listing = tmp_path / "valid.txt"
    listing.write_text("valid.csv\n")
    assert main(["gap", "--robot", "ur5", "--ident", str(ident_dir), "--valid-from", str(listing),
                 "--max-effects", "1"]) == 0
    out = capsys.readouterr().out
    assert "identification logs used (1):" in out and str(ident) in out
    assert "validation logs used (1):" in out and str(tmp_path / "valid.csv") in out
    assert main(["gap", "--robot", "ur5", "--ident", str(ident_dir)]) == 2
    assert "no --valid given" in capsys.readouterr().err


def test_working_line_only_on_a_terminal():
    import time

    from urident.progress import Working

    tty, pipe = _Tty(), io.StringIO()
    for stream in (tty, pipe):
        with Working("diagnosis", stream=stream, delay=0, interval=0.05):
            time.sleep(0.3)
    assert "\rdiagnosis: 0 s" in tty.getvalue() and tty.getvalue().endswith("\r")
    assert pipe.getvalue() == ""
