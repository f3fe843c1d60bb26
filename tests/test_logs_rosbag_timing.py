"""Bag timing as UR's ROS 2 driver produces it (tests/bag_timing.py: ros2_control's loop latency
and catch-up, DDS-batched receive times, clock steps), written with rosbags' own Writer: jitter
alone is no gap, a lost message is one (and nothing is differentiated across it), and the driver's
speed scaling topic cuts paused stretches out like a protective stop."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bag_timing import control_loop_stamps, receive_times, write_timed_bag
from urident.cli.main import main
from urident.errors import LogFormatError
from urident.logs import load_log
from urident.logs.gaps import GAP_FACTOR, piece_bounds, recording_gaps

ROOT = Path(__file__).resolve().parent.parent
PERIOD = 0.002     # 500 Hz, UR e-Series


@pytest.fixture(scope="module")
def sample():
    return load_log(ROOT / "logs" / "sample_ident.csv")


def _stamps(sample, model, seed=0):
    n = int((sample.t[-1] - sample.t[0]) / PERIOD) - 50
    return control_loop_stamps(n, PERIOD, np.random.default_rng(seed), model)


def _plain_rule_gaps(t):
    dt = np.diff(t)
    return int(np.sum(dt > GAP_FACTOR * np.median(dt)))


@pytest.mark.parametrize("storage,model", [("mcap", "generic_kernel"), ("sqlite3", "overloaded")])
def test_jitter_alone_is_no_gap(tmp_path, sample, storage, model, capsys):
    stamps = _stamps(sample, model)
    assert _plain_rule_gaps(stamps) > 0          # what refused such bags before
    bag = write_timed_bag(tmp_path / "b", storage, sample, stamps)
    rec = load_log(bag, robot="ur5")
    assert len(rec) == stamps.size and recording_gaps(rec) == []
    assert rec.rate_hz == pytest.approx(500, rel=1e-3)
    assert main(["identify", str(bag), "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]) == 0
    assert "missing (first after" not in capsys.readouterr().err   # no gap note


def test_receive_time_with_dds_batching_is_no_gap(tmp_path, sample):
    rng = np.random.default_rng(1)
    stamps = _stamps(sample, "generic_kernel")
    recv = receive_times(stamps, rng)
    assert _plain_rule_gaps(recv) > stamps.size / 10    # bunched: most intervals ~0, some 5 periods
    rec = load_log(write_timed_bag(tmp_path / "b", "mcap", sample, stamps, receive=recv,
                                   zero_stamps=True), robot="ur5")
    assert rec.metadata["time_source"] == "bag receive time"
    assert recording_gaps(rec) == [] and rec.rate_hz == pytest.approx(500, rel=1e-3)
    from urident.ident.preprocess import sample_rate

    assert sample_rate(rec.t) == pytest.approx(500, rel=1e-3)   # not the bunches' 2 µs spacing
    out = str(tmp_path / "p.yaml")
    assert main(["identify", str(tmp_path / "b"), "--robot", "ur5", "--out", out]) == 0


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_lost_message_is_a_gap_and_nothing_is_differentiated_across_it(tmp_path, sample, storage,
                                                                         capsys):
    import dataclasses

    from urident.ident import prepare
    from urident.model import load_robot

    stamps = _stamps(sample, "generic_kernel")
    lost = 4000
    kept = np.delete(stamps, [lost])
    bag = write_timed_bag(tmp_path / "b", storage, sample, kept)
    rec = load_log(bag, robot="ur5")
    (gap,) = recording_gaps(rec)
    assert gap.missing == 1
    a, b = piece_bounds(rec)[0][1], piece_bounds(rec)[1][0]
    assert a <= lost <= b                       # samples lost-1 and lost sit in different pieces
    argv = ["identify", str(bag), "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "1 gap, 1 period missing" in err and "--allow-gaps" in err
    assert main(argv + ["--allow-gaps"]) == 0
    # what comes after the loss changes nothing before it
    after = np.arange(len(rec))[:, None] >= lost
    changed = dataclasses.replace(rec, qd=np.where(after, 2 * rec.qd, rec.qd),
                                  current=np.where(after, 3 * rec.current, rec.current))
    spec = load_robot("ur5")
    p, q = prepare([rec], spec), prepare([changed], spec)
    first = p.segment == 0
    assert sorted(set(p.segment)) == [0, 1] and p.t[first].max() < rec.t[lost]
    assert np.array_equal(p.qdd[first], q.qdd[first]) and np.array_equal(p.tau[first], q.tau[first])


def test_clock_steps(tmp_path, sample):
    """A forward step of the stamping clock cannot be told from lost messages: a gap (refused
    unless --allow-gaps); a backward step is time going back: one line, or dropped."""
    stamps = _stamps(sample, "rt_kernel")[:3000]
    forward = stamps.copy()
    forward[1500:] += 0.5
    (gap,) = recording_gaps(load_log(write_timed_bag(tmp_path / "f", "mcap", sample, forward),
                                     robot="ur5"))
    assert gap.index == 1500 and gap.missing == 250
    back = stamps.copy()
    back[1500:] -= 0.1
    # the driver's clock steps back, the recorder (another machine) receives in order
    bag = write_timed_bag(tmp_path / "b", "mcap", sample, back, receive=stamps + 1e-4)
    with pytest.raises(LogFormatError) as exc:
        load_log(bag, robot="ur5")
    assert "/joint_states message 1501 (stamp" in str(exc.value) and "goes back" in str(exc.value)
    rec = load_log(bag, robot="ur5", drop_bad=True)
    assert rec.dropped["count"] == int(np.sum(back[1500:] <= back[1499]))
    assert np.all(np.diff(rec.t) > 0)
    # both on one machine: the bag's receive order interleaves the two stretches
    bag = write_timed_bag(tmp_path / "c", "mcap", sample, back)
    with pytest.raises(LogFormatError) as exc:
        load_log(bag, robot="ur5")
    assert "\n" not in str(exc.value) and "/joint_states message" in str(exc.value)


# ------------------------------------------------------------------------------ speed scaling
def _speed(stamps, pause, slow):
    """The broadcaster's 100 Hz messages [percent]: 100, 0 over ``pause`` (s), 40 over ``slow``."""
    at = np.arange(stamps[0] - 0.005, stamps[-1], 0.01)
    value = np.full(at.size, 100.0)
    value[(at >= pause[0]) & (at < pause[1])] = 0.0
    value[(at >= slow[0]) & (at < slow[1])] = 40.0
    return list(zip(at, value))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_speed_scaling_zero_is_excluded_and_the_range_reported(tmp_path, sample, storage, capsys):
    stamps = _stamps(sample, "generic_kernel")
    t0 = stamps[0]
    speed = _speed(stamps, pause=(t0 + 4.0, t0 + 5.0), slow=(t0 + 8.0, t0 + 10.0))
    bag = write_timed_bag(tmp_path / "b", storage, sample, stamps, speed=speed)
    rec = load_log(bag, robot="ur5")
    paused = (stamps >= t0 + 4.0) & (stamps < t0 + 5.0)
    assert len(rec) == stamps.size - paused.sum() and not np.isin(rec.t, stamps[paused]).any()
    (stop,) = rec.metadata["excluded"]
    assert stop["reason"] == "speed scaling 0 (paused)" and stop["messages"] == paused.sum()
    scaling = rec.metadata["speed_scaling"]
    assert scaling["topic"] == "/speed_scaling_state_broadcaster/speed_scaling"
    assert (scaling["min_percent"], scaling["max_percent"]) == (40.0, 100.0)
    assert main(["identify", str(bag), "--robot", "ur5", "--out", str(tmp_path / "p.yaml")]) == 0
    err = capsys.readouterr().err
    assert "speed scaling 0 (paused); excluded" in err and "speed scaling 40–100 %" in err


def test_speed_scaling_as_a_fraction_under_a_namespace(tmp_path, sample):
    """The first ROS 2 driver versions published the factor (0..1); a namespaced driver's topic
    is matched to its joint_states."""
    stamps = _stamps(sample, "rt_kernel")[:3000]
    t0 = stamps[0]
    speed = [(a, v / 100) for a, v in _speed(stamps, (t0 + 2.0, t0 + 2.5), (t0 + 3, t0 + 4))]
    bag = write_timed_bag(tmp_path / "b", "mcap", sample, stamps, speed=speed,
                          topic="/ur/joint_states",
                          speed_topic="/ur/speed_scaling_state_broadcaster/speed_scaling")
    rec = load_log(bag, robot="ur5", topic="/ur/joint_states")
    assert rec.metadata["speed_scaling"]["unit"] == "fraction"
    assert rec.metadata["speed_scaling"]["min_percent"] == pytest.approx(40.0)
    assert len(rec) == 3000 - int(np.sum((stamps >= t0 + 2.0) & (stamps < t0 + 2.5)))


def test_a_bag_without_speed_scaling_loads_as_before(tmp_path, sample):
    stamps = _stamps(sample, "rt_kernel")[:2000]
    rec = load_log(write_timed_bag(tmp_path / "b", "mcap", sample, stamps), robot="ur5")
    assert rec.metadata["speed_scaling"] is None and rec.metadata["excluded"] == []
    assert not any("speed scaling" in n for n in rec.metadata["notes"]) and len(rec) == 2000


def test_every_consumer_reads_a_jittered_bag(tmp_path, sample, capsys):
    valid = load_log(ROOT / "logs" / "sample_valid.csv")
    ident = write_timed_bag(tmp_path / "ident", "mcap", sample, _stamps(sample, "generic_kernel"))
    vbag = write_timed_bag(tmp_path / "valid", "sqlite3", valid, _stamps(valid, "overloaded", 2))
    params, out = str(tmp_path / "p.yaml"), tmp_path
    for argv in (["identify", str(ident), "--robot", "ur5", "--out", params],
                 ["validate", str(vbag), "--robot", "ur5", "--params", params],
                 ["view", str(vbag), "--robot", "ur5", "--params", params,
                  "--save", str(out / "v.rrd")],
                 ["gap", "--robot", "ur5", "--ident", str(ident), "--valid", str(vbag),
                  "--json-out", str(out / "gap.json")]):
        assert main(argv) == 0, argv[0]
    # no tool is mounted in the sample run: payload reads the bag and finds no payload
    capsys.readouterr()
    assert main(["payload", str(vbag), "--robot", "ur5", "--params", params,
                 "--out", str(out / "tool.yaml")]) == 2
    assert "estimated payload mass is" in capsys.readouterr().err
