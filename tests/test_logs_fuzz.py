"""Property: malformed logs and sidecars either load as valid data or raise LogFormatError."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from urident.errors import LogFormatError
from urident.logs import LOG_FIELDS, LogWriter, Recording, load_log, parse_column_map, sidecar_path
from urident.logs.schema import FIELDS_BY_ATTR

SPECIAL = ["nan", "NaN", "inf", "-inf", "1e306", "-1e306", "1e400", "", " ", "abc", "0x10",
           "1,2", "\x00", "253.0000", "1e-320", "--1", "1_0", "Infinity", "\ufffd", "\r"]

N_ROWS = 12


def base_rows(kind: str) -> tuple[bytes, bytes | None]:
    """A valid log of ``kind`` as (csv bytes, sidecar bytes or None)."""
    lines = []
    for k in range(N_ROWS):
        t = 3.0 + 0.002 * k
        q = [0.1 * j + 0.001 * k for j in range(6)]
        vals = [t] + q + [0.5] * 6 + [1.0 + j for j in range(6)]
        lines.append(",".join(f"{v:.6f}" for v in vals))
    names = [c for f in LOG_FIELDS[:4] for c in f.columns]
    if kind == "foreign":
        return ("\n".join(lines) + "\n").encode(), None
    csv = ("\n".join([",".join(names)] + lines) + "\n").encode()
    if kind == "rtde":
        return csv, None
    sidecar = yaml.safe_dump(
        {"format": "urident-log", "format_version": 1, "robot": "ur5e", "rate_hz": 500.0,
         "status": "completed", "abort_reason": None, "n_samples": N_ROWS, "late_cycles": 0,
         "columns": names, "start_time": "2024-01-01T00:00:00Z", "extra": {"a": 1}},
        sort_keys=False,
    ).encode()
    return csv, sidecar


@st.composite
def mutation(draw):
    kind = draw(st.sampled_from(["truncate", "cell", "bytes", "swap", "shuffle", "dup", "del"]))
    return (kind, draw(st.integers(0, 10**6)), draw(st.integers(0, 10**6)),
            draw(st.one_of(st.sampled_from(SPECIAL), st.text(max_size=8),
                           st.floats(allow_nan=True, allow_infinity=True).map(repr))),
            draw(st.binary(min_size=1, max_size=6)))


def mutate(data: bytes, mut) -> bytes:
    kind, a, b, text, raw = mut
    if kind == "truncate":
        return data[: a % (len(data) + 1)]
    if kind == "bytes":
        pos = a % (len(data) + 1)
        return data[:pos] + raw + data[pos:]
    if kind == "del":
        if not data:
            return data
        pos = a % len(data)
        return data[:pos] + data[pos + 1 :]
    lines = data.split(b"\n")
    if len(lines) < 2:
        return data
    i, j = a % len(lines), b % len(lines)
    if kind == "cell":
        cells = lines[i].split(b",")
        cells[b % len(cells)] = text.encode("utf-8", "surrogatepass")
        lines[i] = b",".join(cells)
    elif kind == "swap":
        lines[i], lines[j] = lines[j], lines[i]
    elif kind == "shuffle":
        body = lines[1:-1]
        np.random.default_rng(a).shuffle(body)
        lines = lines[:1] + body + lines[-1:]
    elif kind == "dup":
        lines.insert(i, lines[j])
    return b"\n".join(lines)


yaml_values = st.one_of(
    st.none(), st.booleans(), st.integers(-10, 10**6), st.floats(), st.text(max_size=10),
    st.lists(st.one_of(st.integers(-5, 5), st.floats(), st.text(max_size=3)), max_size=7),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


@st.composite
def sidecar_mutation(draw):
    kind = draw(st.sampled_from(["keep", "keep", "text", "bytes", "value", "delete", "cut"]))
    key = draw(st.sampled_from(["format", "robot", "rate_hz", "status", "n_samples", "columns",
                                "gear_ratios", "torque_constants", "extra", "start_time", 7]))
    return (kind, draw(st.text(max_size=40)), draw(st.binary(max_size=40)), key,
            draw(yaml_values), draw(st.integers(0, 10**4)))


def apply_sidecar(path: Path, original: bytes, mut) -> None:
    kind, text, raw, key, value, cut = mut
    if kind == "delete":
        return
    if kind == "text":
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
    elif kind == "bytes":
        path.write_bytes(raw)
    elif kind == "cut":
        path.write_bytes(original[: cut % (len(original) + 1)])
    elif kind == "value":
        data = yaml.safe_load(original)
        data[key] = value
        path.write_text(yaml.safe_dump(data))
    else:
        path.write_bytes(original)


def assert_valid(rec: Recording) -> None:
    n = len(rec)
    assert n >= 1
    assert rec.t.shape == (n,) and np.all(np.isfinite(rec.t))
    assert np.all(np.diff(rec.t) > 0)
    for attr in ("q", "qd", "current"):
        arr = getattr(rec, attr)
        assert arr.shape == (n, 6) and arr.dtype == np.float64
        assert np.all(np.isfinite(arr))
        assert np.all(np.abs(arr) <= FIELDS_BY_ATTR[attr].bound)
    assert rec.robot is not None


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(["own", "rtde", "foreign"]),
    mutations=st.lists(mutation(), min_size=0, max_size=4),
    side_mut=sidecar_mutation(),
    drop_bad=st.booleans(),
    rows=st.one_of(st.none(), st.none(), st.tuples(st.integers(1, 6), st.integers(6, 12)),
                   st.tuples(st.integers(-1, 15), st.integers(-1, 15))),
)
def test_malformed_logs_load_or_raise_logformaterror(kind, mutations, side_mut, drop_bad, rows):
    csv, sidecar = base_rows(kind)
    for mut in mutations:
        csv = mutate(csv, mut)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "log.csv"
        path.write_bytes(csv)
        if sidecar is not None:
            apply_sidecar(sidecar_path(path), sidecar, side_mut)
        kwargs = {"robot": "ur5e", "drop_bad": drop_bad, "rows": rows,
                  "known_robots": ["ur5e", "ur10e"]}
        if kind == "foreign":
            kwargs["column_map"] = "t,q,qd,i"
        try:
            rec = load_log(path, **kwargs)
        except LogFormatError as exc:
            assert "\n" not in str(exc) and str(exc)
            event(f"rejected: {str(exc).split(': ', 1)[-1].split(' ')[0]}")
            return
        assert_valid(rec)
        event(f"loaded ({'some dropped' if rec.metadata['dropped']['count'] else 'none dropped'})")
        if not mutations and side_mut[0] == "keep" and rows is None:
            assert len(rec) == N_ROWS


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=60))
def test_column_map_parser_never_crashes(spec):
    try:
        cmap = parse_column_map(spec)
    except LogFormatError as exc:
        assert "\n" not in str(exc)
        return
    assert {"t", "q", "qd", "current"} <= set(cmap.columns)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=30), st.booleans())
def test_writer_round_trips_arbitrary_rows(values, with_dup):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "w.csv"
        with LogWriter(path, fields=LOG_FIELDS[:4], metadata={"robot": "ur5e"}) as log:
            for k, v in enumerate(values):
                row = [10.0 + 0.002 * k] + [0.0] * 6 + [0.0] * 6 + [v / 10] * 6
                log.append(row)
                if with_dup:
                    log.append(row)
        rec = load_log(path, known_robots=["ur5e"])
        assert len(rec) == len(values)
        np.testing.assert_allclose(rec.current[:, 0], np.array(values) / 10, rtol=1e-8,
                                   atol=1e-300)
