"""Gaps in logs: found in one place (own and foreign logs), refused by every log consumer unless
--allow-gaps / --allow-aborted, and never differentiated or filtered across."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urident.cli.main import main
from urident.logs import load_log, read_sidecar, sidecar_path
from urident.logs.gaps import find_gaps, missing_periods, recording_gaps, split_at_gaps
from urident.logs.sidecar import write_sidecar

SAMPLES = Path(__file__).resolve().parents[1] / "logs"


def test_find_gaps_counts_missing_periods_and_ignores_jitter():
    period = 0.002
    t = np.arange(1000) * period
    t[300:] += 0.2                    # a 0.2 s latency spike: 100 periods missing
    t[100] += 0.4 * period            # jitter: not a gap
    t[700:] += 3 * period             # 3 more missing
    gaps = find_gaps(t, period)
    assert [(g.index, g.missing) for g in gaps] == [(300, 100), (700, 3)]
    assert gaps[0].t_before == pytest.approx(299 * period)
    assert missing_periods(1.49 * period, period) == 0 and missing_periods(1.6 * period, period) == 1


def test_jitter_that_averages_out_is_no_gap_and_a_loss_in_it_is_left_out_of_pieces():
    """A late stamp followed by a short interval, and a stall the control loop catches up (cycles
    run at once), keep the timing level: no gap. A message lost inside such a stall is one, and
    the stretch it may lie in is in no piece."""
    from urident.logs.gaps import find_gaps

    period = 0.002
    slots = np.arange(2000) * period
    t = slots.copy()
    t[300] += 0.9 * period                              # 1.9 then 0.1 periods
    t[800:805] = slots[800] + 4.2 * period + 1e-5 * np.arange(5)   # 4 ms stall, then caught up
    assert np.diff(t).max() > 4 * period and find_gaps(t, period) == []
    lost = np.delete(t, 803)                            # the broadcaster skipped one cycle in it
    (gap,) = find_gaps(lost, period)
    assert gap.missing == 1 and gap.index <= 803 <= gap.resume
    assert find_gaps(np.delete(slots, [500, 520, 521]), period)[1].missing == 2


def copy_log(src: Path, dst: Path, drop: slice | None = None, status: str | None = None,
             reason: str | None = None) -> Path:
    """A copy of an urident log with data rows ``drop`` removed and/or another status."""
    lines = src.read_text().splitlines(keepends=True)
    header, rows = lines[0], lines[1:]
    if drop is not None:
        del rows[drop]
    dst.write_text(header + "".join(rows))
    meta = read_sidecar(sidecar_path(src))
    meta["n_samples"] = len(rows)
    if status:
        meta["status"], meta["abort_reason"] = status, reason
    write_sidecar(sidecar_path(dst), meta)
    return dst


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("gaps")
    ident, valid = SAMPLES / "sample_ident.csv", SAMPLES / "sample_valid.csv"
    return {
        "ident": ident, "valid": valid, "dir": d,
        "gapped": copy_log(ident, d / "gapped.csv", drop=slice(1200, 1300)),
        "aborted": copy_log(ident, d / "aborted.csv", status="aborted",
                            reason="at t = 9.000 s: controller samples late: no sample for 0.20 s"),
        "params": d / "params.yaml",
    }


def one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    lines = [l for l in err if l.startswith("urident: error:")]
    assert len(lines) == 1 and "Traceback" not in "\n".join(err), err
    return lines[0]


def consumers(logs, log):
    return {
        "identify": ["identify", str(log), "--robot", "ur5", "--out", str(logs["dir"] / f"p_{log.stem}.yaml")],
        "validate": ["validate", str(log), "--params", str(logs["params"])],
        "gap": ["gap", "--robot", "ur5", "--ident", str(logs["ident"]), "--valid", str(log)],
    }


@pytest.fixture(scope="module")
def params(logs):
    assert main(["identify", str(logs["ident"]), "--robot", "ur5", "--out", str(logs["params"])]) == 0
    return logs["params"]


@pytest.mark.parametrize("command", ["identify", "validate", "gap"])
def test_consumers_refuse_gapped_and_aborted_logs(logs, params, capsys, command):
    argv = consumers(logs, logs["gapped"])[command]
    assert main(argv) == 2
    line = one_line(capsys)
    assert "gapped.csv: 1 gap, 100 periods missing" in line and "--allow-gaps" in line
    argv = consumers(logs, logs["aborted"])[command]
    assert main(argv) == 2
    line = one_line(capsys)
    assert "aborted.csv: the run was aborted (at t = 9.000 s: controller samples late" in line
    assert "--allow-aborted" in line


@pytest.mark.parametrize("command", ["identify", "validate"])
def test_allowed_logs_are_used(logs, params, command):
    assert main(consumers(logs, logs["gapped"])[command] + ["--allow-gaps"]) == 0
    assert main(consumers(logs, logs["aborted"])[command] + ["--allow-aborted"]) == 0


def test_nothing_is_differentiated_across_a_gap(logs):
    """Each gap-free piece is preprocessed on its own: what comes after a gap does not change a
    single acceleration or torque before it (a zero-phase filter across the gap would)."""
    import dataclasses

    from urident.ident import prepare
    from urident.model import load_robot

    spec = load_robot("ur5")
    rec = load_log(logs["gapped"])
    assert [len(p) for p in split_at_gaps(rec)] == [1200, len(rec) - 1200]
    changed = dataclasses.replace(rec, qd=np.where(np.arange(len(rec))[:, None] >= 1200, 2 * rec.qd, rec.qd),
                                  current=np.where(np.arange(len(rec))[:, None] >= 1200, 3 * rec.current,
                                                   rec.current))
    a, b = prepare([rec], spec), prepare([changed], spec)
    assert sorted(set(a.segment)) == [0, 1]
    before = a.segment == 0
    assert a.t[before].max() < rec.t[1200]
    assert np.array_equal(a.qdd[before], b.qdd[before]) and np.array_equal(a.tau[before], b.tau[before])
    assert not np.allclose(a.qdd[~before], b.qdd[~before])


def test_foreign_log_gaps_from_timestamps(tmp_path):
    """A bare ur_rtde recorder CSV (no sidecar) gets its gaps from its timestamps."""
    rec = load_log(SAMPLES / "sample_ident.csv")
    names = (["timestamp"] + [f"actual_q_{j}" for j in range(6)] + [f"actual_qd_{j}" for j in range(6)]
             + [f"actual_current_{j}" for j in range(6)])
    keep = np.r_[0:500, 530:len(rec)]
    rows = np.column_stack([rec.t, rec.q, rec.qd, rec.current])[keep]
    path = tmp_path / "rtde_record.csv"
    path.write_text(",".join(names) + "\n" + "".join(",".join(f"{v:.6f}" for v in r) + "\n" for r in rows))
    foreign = load_log(path, robot="ur5")
    gaps = recording_gaps(foreign)
    assert [(g.index, g.missing) for g in gaps] == [(500, 30)]
    assert main(["identify", str(path), "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]) == 2


def test_a_log_whose_writer_died_counts_as_aborted(logs, capsys):
    running = copy_log(logs["ident"], logs["dir"] / "running.csv", status="running")
    argv = ["identify", str(running), "--robot", "ur5", "--out", str(logs["dir"] / "p_run.yaml")]
    assert main(argv) == 2
    assert "its writer never closed it (status: running)" in one_line(capsys)
    assert main(argv + ["--allow-aborted"]) == 0
