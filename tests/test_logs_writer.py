"""LogWriter: round trip, abort on exception, crash safety (kill -9), de-duplication."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import yaml

from urident.errors import LogFormatError, OutputError
from urident.logs import LOG_FIELDS, LogWriter, field_columns, load_log, sidecar_path

META = {
    "robot": "ur10e",
    "controller_version": "5.11.1.108318",
    "rate_hz": 500,
    "gear_ratios": [101] * 6,
    "torque_constants": [0.125, 0.125, 0.125, 0.092, 0.092, 0.092],
    "operator": "test",  # free-form: lands in extra
}


def make_samples(n: int, t0: float = 1234.5, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = t0 + 0.002 * np.arange(n)
    phase = rng.uniform(0, 2 * np.pi, 6)
    q = 1.5 * np.sin(2 * np.pi * 0.2 * t[:, None] + phase)
    qd = 1.5 * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t[:, None] + phase)
    return {
        "timestamp": t,
        "actual_q": q,
        "actual_qd": qd,
        "actual_current": rng.normal(0, 3, (n, 6)),
        "target_q": q + 1e-4,
        "target_qd": qd,
        "target_qdd": rng.normal(0, 2, (n, 6)),
        "target_current": rng.normal(0, 3, (n, 6)),
        "target_moment": rng.normal(0, 50, (n, 6)),
        "joint_temperatures": 30 + rng.random((n, 6)),
        "robot_mode": np.full(n, 7),
        "safety_status_bits": np.full(n, 1),
        "runtime_state": np.full(n, 2),
    }


def rows_of(samples: dict[str, np.ndarray]) -> np.ndarray:
    cols = [np.asarray(samples[f.name], dtype=np.float64).reshape(len(samples["timestamp"]), -1)
            for f in LOG_FIELDS]
    return np.hstack(cols)


def test_round_trip(tmp_path):
    path = tmp_path / "run.csv"
    s = make_samples(1200)
    flat = rows_of(s)
    with LogWriter(path, metadata=META) as log:
        for k in range(600):  # by keyword, half with attribute names
            log.append_sample(
                s["timestamp"][k],
                q=s["actual_q"][k],
                qd=s["actual_qd"][k],
                current=s["actual_current"][k],
                **{f.name: s[f.name][k] for f in LOG_FIELDS[4:]},
            )
        for k in range(600, 1200):  # flat rows
            log.append(flat[k])
        log.mark_late_cycle(3)
    rec = load_log(path)
    assert len(rec) == 1200 and rec.robot == "ur10e" and rec.rate_hz == 500.0
    assert rec.status == "completed"
    np.testing.assert_allclose(rec.t, s["timestamp"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(rec.q, s["actual_q"], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(rec.qd, s["actual_qd"], rtol=1e-8)
    np.testing.assert_allclose(rec.current, s["actual_current"], rtol=1e-8)
    np.testing.assert_allclose(rec.target_moment, s["target_moment"], rtol=1e-8)
    np.testing.assert_allclose(rec.temperature, s["joint_temperatures"], rtol=1e-8)
    assert rec.robot_mode.dtype == np.int64 and set(rec.robot_mode) == {7}
    assert rec.q.shape == (1200, 6) and rec.q.dtype == np.float64
    assert not rec.q.flags.writeable
    side = yaml.safe_load(sidecar_path(path).read_text())
    assert side["status"] == "completed" and side["abort_reason"] is None
    assert side["n_samples"] == 1200 and side["late_cycles"] == 3
    assert side["extra"] == {"operator": "test"}
    assert side["columns"] == field_columns(LOG_FIELDS)
    assert side["start_time"].endswith("Z") and side["gear_ratios"] == [101.0] * 6
    header = path.read_text().splitlines()[0]
    assert header.startswith("timestamp,actual_q_0,actual_q_1,")


def test_trajectory_hash_and_subset_fields(tmp_path):
    traj = tmp_path / "traj.yaml"
    traj.write_text("period_s: 10\n")
    path = tmp_path / "sim.csv"
    fields = ["timestamp", "actual_q", "actual_qd", "actual_current"]
    with LogWriter(path, fields=fields, metadata={"robot": "ur5e", "trajectory_file": traj}) as log:
        log.append([0.0] + [0.0] * 18)
        log.append([0.002] + [0.001] * 18)
    rec = load_log(path)
    assert rec.target_q is None and rec.robot_mode is None and len(rec) == 2
    import hashlib

    assert rec.metadata["trajectory_sha256"] == hashlib.sha256(traj.read_bytes()).hexdigest()


def test_duplicate_timestamps_skipped(tmp_path):
    path = tmp_path / "dup.csv"
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5e"}) as log:
        assert log.append([1.0] + [0.1] * 18)
        assert not log.append([1.0] + [0.2] * 18)
        assert log.append([1.002] + [0.1] * 18)
    rec = load_log(path)
    assert len(rec) == 2 and rec.metadata["duplicates_skipped"] == 1


def test_exception_marks_aborted_and_keeps_samples(tmp_path):
    path = tmp_path / "abort.csv"
    flat = rows_of(make_samples(777))
    with pytest.raises(RuntimeError, match="protective stop"):
        with LogWriter(path, metadata=META, flush_interval_s=3600) as log:
            for row in flat:
                log.append(row)
            raise RuntimeError("protective stop\nat joint 2")
    rec = load_log(path)
    assert len(rec) == 777 and rec.status == "aborted"
    assert rec.metadata["abort_reason"] == "RuntimeError: protective stop at joint 2"


def test_completed_log_cut_afterwards_is_detected(tmp_path):
    path = tmp_path / "cut.csv"
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5e"}) as log:
        for k in range(10):
            log.append([k * 0.002] + [0.0] * 18)
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-3]))
    with pytest.raises(LogFormatError, match=r"cut\.csv: 7 data rows, but cut\.yaml says "
                       "n_samples: 10"):
        load_log(path)
    rec = load_log(path, drop_bad=True)
    assert len(rec) == 7 and "n_samples: 10" in rec.metadata["dropped"]["sample_count_mismatch"]


def test_close_with_status_and_extra(tmp_path):
    path = tmp_path / "c.csv"
    log = LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"})
    assert yaml.safe_load(sidecar_path(path).read_text())["status"] == "running"
    log.append([0.0] + [0.0] * 18)
    log.close("aborted", "operator stop", extra={"note": "x"})
    log.close()  # idempotent
    rec = load_log(path)
    assert rec.status == "aborted" and rec.metadata["extra"] == {"note": "x"}
    with pytest.raises(ValueError, match="closed"):
        log.append([1.0] + [0.0] * 18)


def test_refuses_to_overwrite_and_bad_rows(tmp_path):
    path = tmp_path / "o.csv"
    LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"}).close()
    with pytest.raises(OutputError, match="o.yaml: exists"):
        LogWriter(path, fields=LOG_FIELDS[:4])
    with pytest.raises(OutputError, match="o.csv: exists"):  # the CSV alone is enough to refuse
        path.with_suffix(".yaml").unlink()
        LogWriter(path, fields=LOG_FIELDS[:4])
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"}, overwrite=True) as log:
        with pytest.raises(ValueError, match="19 columns"):
            log.append([0.0] * 5)
        with pytest.raises(ValueError, match="lacks"):
            log.append_sample(0.0, q=[0] * 6, qd=[0] * 6)
        with pytest.raises(ValueError, match="not a field"):
            log.append_sample(0.0, q=[0] * 6, qd=[0] * 6, current=[0] * 6, bogus=1)
    with pytest.raises(ValueError, match="unknown log field"):
        LogWriter(tmp_path / "f.csv", fields=["timestamp", "nope"])


def test_flushes_before_close(tmp_path):
    path = tmp_path / "f.csv"
    log = LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5"}, flush_interval_s=0)
    for k in range(5):
        log.append([k * 0.01] + [0.0] * 18)
    assert len(path.read_text().splitlines()) == 6  # header + 5, all on disk before close
    rec = load_log(path)
    assert rec.status == "running" and len(rec) == 5
    log.close()


CHILD = textwrap.dedent(
    """
    import sys, time
    from urident.logs import LogWriter, LOG_FIELDS
    log = LogWriter(sys.argv[1], fields=LOG_FIELDS[:4], metadata={"robot": "ur10e"},
                    flush_interval_s=0.2)
    k = 0
    def sample():
        global k
        log.append([100.0 + 0.002 * k] + [0.0001 * k] * 6 + [0.0] * 12)
        k += 1
    for _ in range(600):
        sample()
    time.sleep(0.3)       # longer than flush_interval_s: the next append flushes
    sample()              # 601 samples flushed
    for _ in range(10):   # buffered, not flushed: may be lost
        sample()
    print("ready", flush=True)
    time.sleep(60)
    """
)


def test_kill_9_leaves_readable_log(tmp_path):
    path = tmp_path / "crash.csv"
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout.readline().strip() == "ready"
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stdout.close()
    assert proc.returncode == -signal.SIGKILL
    rec = load_log(path)
    assert rec.status == "running"
    assert 601 <= len(rec) <= 611
    np.testing.assert_allclose(rec.t[:601], 100.0 + 0.002 * np.arange(601), atol=1e-6)


def test_crashed_log_with_truncated_last_line(tmp_path):
    path = tmp_path / "cut.csv"
    log = LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur10e"}, flush_interval_s=0)
    for k in range(20):
        log.append([k * 0.002] + [0.5] * 18)
    with open(path, "a") as fh:  # what a kill during write can leave
        fh.write("0.040000,0.5,0.5,0.")
    rec = load_log(path)  # sidecar says running: the cut line is dropped and reported
    assert len(rec) == 20 and rec.status == "running"
    assert rec.metadata["dropped"]["count"] == 1
    assert rec.metadata["dropped"]["reasons"] == {"truncated": 1}
    assert rec.metadata["dropped"]["lines"] == [22]
    log.close()
