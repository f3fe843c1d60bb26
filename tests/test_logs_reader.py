"""Loaders: ur_rtde recorder CSV, UR10e dynamic_calibration files, column maps, corrupt input."""

from __future__ import annotations

import argparse
import io
import time
from pathlib import Path

import numpy as np
import pytest

from shared_data import UR10E_DATA
from urident.errors import LogFormatError
from urident.logs import (
    LOG_FIELDS,
    ColumnMapError,
    LogWriter,
    describe_dropped,
    load_log,
    parse_column_map,
    parse_row_range,
    sidecar_path,
)
from urident.cli.log_args import add_log_arguments, load_log_from_args

DATA = UR10E_DATA
HARM = DATA / "ur-20_02_10-30sec_12harm.csv"
PTP = DATA / "ur-20_01_17-ptp_10_points.csv"
BAD = DATA / "ur-19_09_27-11_32_02.csv"
need_data = pytest.mark.skipif(not HARM.exists(), reason="UR10e dataset not present")

RTDE_VARS = ["timestamp", "actual_q", "actual_qd", "actual_current", "target_q", "robot_mode",
             "actual_TCP_pose"]


def rtde_header() -> str:
    cols = []
    for v in RTDE_VARS:
        cols += [v] if v in ("timestamp", "robot_mode") else [f"{v}_{j}" for j in range(6)]
    return ",".join(cols)


def rtde_rows(n: int, duplicate_every: int = 0) -> list[str]:
    rows = []
    for k in range(n):
        t = 12.5 + 0.002 * k
        q = [0.1 * j + 0.3 * np.sin(t) for j in range(6)]
        vals = [t] + q + [0.3 * np.cos(t)] * 6 + [0.5 + j for j in range(6)] + q + [7]
        vals += [0.4, 0.1, 0.6, 0.0, 3.1, 0.0]
        line = ",".join(f"{v:.6f}" for v in vals)
        rows.append(line)
        if duplicate_every and k % duplicate_every == 0:
            rows.append(line)  # the recorder thread sampled the same package twice
    return rows


def write(path: Path, lines: list[str], newline_at_end: bool = True) -> Path:
    path.write_text("\n".join(lines) + ("\n" if newline_at_end else ""))
    return path


# ------------------------------------------------------------------ ur_rtde recorder CSV
def test_ur_rtde_recording_with_duplicates(tmp_path):
    path = write(tmp_path / "rec.csv", [rtde_header()] + rtde_rows(500, duplicate_every=7))
    rec = load_log(path, robot="ur5e")
    assert len(rec) == 500 and rec.metadata["duplicates_removed"] == 72
    assert rec.metadata["log_format"] == "ur_rtde" and rec.status == "unknown"
    assert rec.robot == "ur5e" and rec.rate_hz == pytest.approx(500.0)
    assert np.all(np.diff(rec.t) > 0)
    np.testing.assert_allclose(rec.current[0], [0.5, 1.5, 2.5, 3.5, 4.5, 5.5])
    assert rec.target_q is not None and rec.target_qd is None and rec.robot_mode[0] == 7
    assert rec.metadata["ignored_columns"] == [f"actual_TCP_pose_{j}" for j in range(6)]
    assert rec.metadata["dropped"]["count"] == 0


def test_ur_rtde_needs_a_known_robot(tmp_path):
    path = write(tmp_path / "rec.csv", [rtde_header()] + rtde_rows(10))
    with pytest.raises(LogFormatError, match=r"rec\.csv: robot unknown .*--robot"):
        load_log(path)
    with pytest.raises(LogFormatError, match="unknown robot 'ur99'"):
        load_log(path, robot="ur99", known_robots=["ur5e", "ur10e"])


def test_ur_rtde_missing_column(tmp_path):
    header = rtde_header().replace("actual_qd_3,", "")
    rows = [",".join(r.split(",")[:10] + r.split(",")[11:]) for r in rtde_rows(5)]
    path = write(tmp_path / "rec.csv", [header] + rows)
    with pytest.raises(LogFormatError, match=r"rec\.csv:1: header lacks column actual_qd_3"):
        load_log(path, robot="ur5e")
    path = write(tmp_path / "rec2.csv", ["timestamp,actual_q_0"] + ["0.0,0.0"])
    with pytest.raises(LogFormatError, match=r":1: header lacks column actual_q_1"):
        load_log(path, robot="ur5e")


def test_own_log_sidecar_robot_mismatch_and_unknown(tmp_path):
    path = tmp_path / "own.csv"
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5e"}) as log:
        log.append([0.0] + [0.0] * 18)
    with pytest.raises(LogFormatError, match="recorded on robot 'ur5e'.*'ur10e' given"):
        load_log(path, robot="ur10e")
    side = sidecar_path(path)
    side.write_text(side.read_text().replace("robot: ur5e", "robot: ur42"))
    with pytest.raises(LogFormatError, match=r"unknown robot 'ur42' \(.*own\.yaml: robot"):
        load_log(path, known_robots=["ur5e"])


@pytest.mark.parametrize(
    "text, match",
    [
        ("status: done\n", "own.yaml: status: is 'done'"),
        ("rate_hz: fast\n", "own.yaml: rate_hz: must be int or float"),
        ("rate_hz: -5\n", "rate_hz: must be a positive rate"),
        ("[1, 2]\n", "must be a YAML mapping"),
        ("robot: [unclosed\n", r"own\.yaml:2: malformed YAML"),
        ("gear_ratios: [1, 2]\n", "gear_ratios: must be a list of 6 finite numbers"),
        ("", "sidecar is empty"),
    ],
)
def test_malformed_sidecar(tmp_path, text, match):
    path = tmp_path / "own.csv"
    with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5e"}) as log:
        log.append([0.0] + [0.0] * 18)
    sidecar_path(path).write_text(text)
    with pytest.raises(LogFormatError, match=match):
        load_log(path, robot="ur5e")


# ------------------------------------------------------------------ UR10e dataset
@need_data
def test_ur10e_identification_file_with_preset_and_rows():
    start = time.perf_counter()
    rec = load_log(HARM, robot="ur10e", format="dynamic_calibration", rows=(635, 3510))
    elapsed = time.perf_counter() - start
    print(f"loaded {HARM.name} in {elapsed:.3f} s")
    assert len(rec) == 2876
    assert rec.metadata["first_line"] == 635 and rec.metadata["last_line"] == 3510
    assert np.all(np.abs(rec.q) <= 2 * np.pi) and np.all(np.abs(rec.current) <= 20)
    assert np.all(np.abs(rec.qd) <= np.pi)
    assert rec.target_current.shape == (2876, 6) and rec.target_moment.shape == (2876, 6)
    assert rec.rate_hz == pytest.approx(100, rel=0.05)
    assert np.all(np.diff(rec.t) > 0)
    # the first selected row is file line 635
    first = np.array(HARM.read_text().splitlines()[634].split(","), dtype=float)
    np.testing.assert_array_equal(rec.q[0], first[1:7])
    np.testing.assert_array_equal(rec.target_moment[0], first[25:31])


@need_data
def test_ur10e_validation_file_with_column_map():
    rec = load_log(PTP, robot="ur10e", column_map="t=0,q=1:7,qd=7:13,current=13:19",
                   rows="700-4200")
    assert len(rec) == 3501 and rec.target_moment is None
    assert np.all(np.abs(rec.q) <= 2 * np.pi) and np.all(np.abs(rec.current) <= 20)
    same = load_log(PTP, robot="ur10e", column_map="t,q1..q6,qd1..qd6,i1..i6,i_des1..i_des6,"
                    "tau_des1..tau_des6", rows=(700, 4200))
    np.testing.assert_array_equal(same.q, rec.q)


@need_data
def test_defective_file_rejected_with_file_line_column():
    with pytest.raises(LogFormatError) as err:
        load_log(BAD, robot="ur10e", format="dynamic_calibration_19")
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"{BAD}:2: column q_0 (index 1): value 253 outside the sane range")
    assert "drop_bad" in msg
    with pytest.raises(ColumnMapError, match="19 columns.*expects 31; try --format "
                       "dynamic_calibration_19"):
        load_log(BAD, robot="ur10e", format="dynamic_calibration")


@need_data
def test_defective_file_loads_with_drop_bad():
    rec = load_log(BAD, robot="ur10e", column_map="t,q,qd,i", drop_bad=True)
    dropped = rec.metadata["dropped"]
    assert dropped["count"] == 20 and len(rec) == 1139 - 20
    assert set(dropped["reasons"]) == {"out of range", "joint jump"}
    assert dropped["lines"] == list(range(1, 21))
    assert np.all(np.abs(rec.q) <= 2 * np.pi) and np.all(np.abs(rec.current) <= 20)
    assert np.all(np.abs(np.diff(rec.q, axis=0)) < 0.1)
    line = describe_dropped(rec)
    assert line.startswith(f"{BAD}: dropped 20 bad row(s): ")


@need_data
def test_cli_options(tmp_path):
    parser = argparse.ArgumentParser()
    parser.add_argument("log")
    add_log_arguments(parser)
    args = parser.parse_args([str(BAD), "--columns", "t,q,qd,i", "--drop-bad"])
    out = io.StringIO()
    rec = load_log_from_args(args.log, args, robot="ur10e", report=out)
    assert len(rec) == 1119 and "dropped 20 bad row(s)" in out.getvalue()
    args = parser.parse_args([str(HARM), "--format", "dynamic_calibration", "--rows", "635-3510"])
    assert len(load_log_from_args(args.log, args, robot="ur10e")) == 2876


# ------------------------------------------------------------------ column maps
def test_parse_column_map_forms():
    a = parse_column_map("t=0,q=1:7,qd=7:13,current=13:19")
    b = parse_column_map("t,q,qd,i")
    c = parse_column_map({"t": 0, "q": (1, 7), "qd": (7, 13), "i": "13:19"})
    assert dict(a.columns) == dict(b.columns) == dict(c.columns)
    assert a.ncols is None and b.ncols == 19
    d = parse_column_map("dynamic_calibration")
    assert d.ncols == 31 and d.columns["target_moment"] == tuple(range(25, 31))
    e = parse_column_map("skip*2,time,q0..q5,qd,current,tau")
    assert e.columns["t"] == (2,) and e.columns["tau"] == tuple(range(21, 27))
    assert parse_column_map("t=0,q=1:7,qd=7:13,current=13:19,ncols=40").ncols == 40


@pytest.mark.parametrize(
    "spec, match",
    [
        ("", "empty"),
        ("t=0,q=1:7,qd=7:13", "no column for required field 'current'"),
        ("t=0,q=1:6,qd=7:13,current=13:19", "'q' needs 6 column"),
        ("t=0,q=1:7,qd=6:12,current=13:19", "column 6 used by both"),
        ("t=0,q=a:b,qd=7:13,current=13:19", "expected NAME=INDEX or NAME=START:STOP"),
        ("t=0,q=7:1,qd=7:13,current=13:19", "empty column range"),
        ("t,q,qd,amps", "unknown field 'amps'"),
        ("t=0,q,qd,i", "mixes"),
        ("t,q1..q5,qd,i", "NAME1..NAME6"),
        ("t,,q,qd,i", "empty item"),
        ("t=0,t=1,q=1:7", "given twice"),
        ("t=0,q=1:7,qd=7:13,current=13:19,ncols=10", "uses column 18 but ncols=10"),
    ],
)
def test_parse_column_map_errors(spec, match):
    with pytest.raises(ColumnMapError, match=match):
        parse_column_map(spec)


def test_row_range_parsing():
    assert parse_row_range("635-3510") == (635, 3510) == parse_row_range("635:3510")
    for bad in ("0-5", "9-3", "x", "1-"):
        with pytest.raises(LogFormatError, match="row range"):
            parse_row_range(bad)


# ------------------------------------------------------------------ corrupt foreign input
def foreign_rows(n: int = 30) -> list[list[str]]:
    rows = []
    for k in range(n):
        t = 5.0 + 0.01 * k
        rows.append([f"{t:.3f}"] + [f"{0.2 * np.sin(t + j):.4f}" for j in range(6)]
                    + [f"{0.2 * np.cos(t + j):.4f}" for j in range(6)]
                    + [f"{0.3 * j:.4f}" for j in range(6)])
    return rows


def corrupt(rows, line, col, value):
    rows = [list(r) for r in rows]
    rows[line - 1][col] = value
    return rows


CASES = [
    ("non-numeric", lambda r: corrupt(r, 4, 3, "abc"), r":4: column q_2 \(index 3\): not a number"),
    ("nan", lambda r: corrupt(r, 5, 13, "nan"), r":5: column current_0 \(index 13\): nan is not"),
    ("inf", lambda r: corrupt(r, 6, 1, "-inf"), r":6: column q_0 \(index 1\): -inf is not"),
    ("huge", lambda r: corrupt(r, 7, 8, "1e306"), r":7: column qd_1 \(index 8\): value 1e\+306"),
    ("current", lambda r: corrupt(r, 8, 18, "250"), r":8: column current_5 .*±100 A"),
    ("empty cell", lambda r: corrupt(r, 9, 2, ""), r":9: column q_1 \(index 2\): not a number: ''"),
    ("columns", lambda r: r[:3] + [r[3][:-1]] + r[4:], r":4: 18 columns, expected 19"),
    ("time back", lambda r: corrupt(r, 10, 0, "5.05"), r":10: column t \(index 0\): time 5.05 goes"),
    ("time repeat", lambda r: corrupt(r, 10, 0, "5.080"), r":10: column t .*repeats line 9"),
    ("jump", lambda r: corrupt(r, 12, 4, "2.5"), r":12: column q_3 \(index 4\): joint position"),
]


@pytest.mark.parametrize("name, mutate, match", CASES, ids=[c[0] for c in CASES])
def test_corrupt_foreign_rejected_then_dropped(tmp_path, name, mutate, match):
    rows = mutate(foreign_rows())
    path = write(tmp_path / "f.csv", [",".join(r) for r in rows])
    with pytest.raises(LogFormatError, match=match):
        load_log(path, robot="ur10e", column_map="t,q,qd,i")
    rec = load_log(path, robot="ur10e", column_map="t,q,qd,i", drop_bad=True)
    assert 1 <= rec.metadata["dropped"]["count"] <= 5  # a jump row may take a short run along
    assert len(rec) + rec.metadata["dropped"]["count"] == 30
    assert np.all(np.isfinite(rec.q)) and np.all(np.diff(rec.t) > 0)


def test_identical_duplicate_rows_are_removed(tmp_path):
    rows = foreign_rows()
    rows.insert(5, rows[4])
    path = write(tmp_path / "f.csv", [",".join(r) for r in rows])
    rec = load_log(path, robot="ur10e", column_map="t,q,qd,i")
    assert len(rec) == 30 and rec.metadata["duplicates_removed"] == 1


def test_truncated_last_line(tmp_path):
    lines = [",".join(r) for r in foreign_rows()]
    lines[-1] = lines[-1][:20]
    path = write(tmp_path / "f.csv", lines, newline_at_end=False)
    with pytest.raises(LogFormatError, match=r":30: .*columns, expected 19"):
        load_log(path, robot="ur10e", column_map="t,q,qd,i")
    rec = load_log(path, robot="ur10e", column_map="t,q,qd,i", drop_bad=True)
    assert len(rec) == 29
    # a ur_rtde file cut without a final newline: truncated even if the count happens to fit
    rtde = write(tmp_path / "r.csv", [rtde_header()] + rtde_rows(5), newline_at_end=False)
    with pytest.raises(LogFormatError, match=r"r\.csv:6: truncated last line"):
        load_log(rtde, robot="ur5e")


def test_empty_and_header_only_and_missing(tmp_path):
    empty = tmp_path / "e.csv"
    empty.write_text("")
    with pytest.raises(LogFormatError, match=r"e\.csv: empty file"):
        load_log(empty, robot="ur5e")
    head = write(tmp_path / "h.csv", [rtde_header()])
    with pytest.raises(LogFormatError, match="no data rows"):
        load_log(head, robot="ur5e")
    with pytest.raises(LogFormatError, match="no such log file"):
        load_log(tmp_path / "missing.csv", robot="ur5e")
    noheader = write(tmp_path / "n.csv", [",".join(r) for r in foreign_rows()])
    with pytest.raises(LogFormatError, match=r"n\.csv:1: no header line; give a column map"):
        load_log(noheader, robot="ur5e")


def test_rows_out_of_file(tmp_path):
    path = write(tmp_path / "f.csv", [",".join(r) for r in foreign_rows()])
    with pytest.raises(LogFormatError, match="rows 10-40 asked, the file has 30 data rows"):
        load_log(path, robot="ur10e", column_map="t,q,qd,i", rows=(10, 40))
    rec = load_log(path, robot="ur10e", column_map="t,q,qd,i", rows=(10, 12))
    assert len(rec) == 3 and rec.t[0] == pytest.approx(5.09)


def test_all_rows_bad_is_an_error_even_with_drop_bad(tmp_path):
    rows = [corrupt([r], 1, 1, "nan")[0] for r in foreign_rows(5)]
    path = write(tmp_path / "f.csv", [",".join(r) for r in rows])
    with pytest.raises(LogFormatError, match=r"no valid rows left \(5 dropped: 5 NaN/inf"):
        load_log(path, robot="ur10e", column_map="t,q,qd,i", drop_bad=True)


def test_unknown_format_name(tmp_path):
    path = write(tmp_path / "f.csv", [",".join(r) for r in foreign_rows()])
    with pytest.raises(ColumnMapError, match="unknown log format 'matlab'"):
        load_log(path, robot="ur10e", format="matlab")
