"""rosbag2 input: bags written with rosbags' own Writer (MCAP and SQLite storage) load like the
CSV they came from, every log consumer accepts them, and each real-world defect is one line
naming the topic and stamp, or dropped and counted under --drop-bad."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from urident.cli.main import main
from urident.errors import LogFormatError
from urident.logs import is_bag, load_log
from urident.model import load_robot

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "logs" / "sample_ident.csv"
UR = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
      "wrist_2_joint", "wrist_3_joint"]
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
SAFETY = "ur_dashboard_msgs/msg/SafetyMode"


def _store():
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg("uint8 mode\n", SAFETY))
    return store


@pytest.fixture(scope="module")
def sample():
    return load_log(SAMPLE)


def _qos(depth: int) -> Qos:
    zero = QosTime(0, 0)
    return Qos(QosHistory.KEEP_LAST, depth, QosReliability.RELIABLE, QosDurability.VOLATILE,
               zero, zero, QosLiveliness.AUTOMATIC, zero, False)


def write_bag(path: Path, storage: str, messages, *, topic="/joint_states", publishers=1,
              safety=()):
    """A bag of JointState ``messages`` = [(stamp_ns, names, q, qd, effort[, receive_ns]), ...] (receive time
    = stamp, or 1 ms steps when no message has a stamp), ``publishers`` connections on the topic (each its
    own QoS) taking messages in turn, and SafetyMode messages ``safety`` = [(t_ns, mode), ...]."""
    store = _store()
    js = store.types["sensor_msgs/msg/JointState"]
    header, time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    with Writer(path, version=9, storage_plugin=STORAGES[storage]) as w:
        conns = [w.add_connection(topic, "sensor_msgs/msg/JointState", typestore=store,
                                  offered_qos_profiles=[_qos(10 + k)])
                 for k in range(publishers)]
        stamped = any(m[0] for m in messages)
        for k, (ns, names, q, qd, eff, *recv) in enumerate(messages):
            msg = js(header=header(stamp=time(sec=int(ns // 10**9), nanosec=int(ns % 10**9)),
                                   frame_id=""),
                     name=list(names), position=np.asarray(q, float),
                     velocity=np.asarray(qd, float), effort=np.asarray(eff, float))
            recv = recv[0] if recv else int(ns) if stamped else 10**9 + k * 10**6
            w.write(conns[k % len(conns)], recv, store.serialize_cdr(msg, msg.__msgtype__))
        if safety:
            c = w.add_connection("/io_and_status_controller/safety_mode", SAFETY, typestore=store)
            for ns, mode in safety:
                w.write(c, int(ns), store.serialize_cdr(store.types[SAFETY](mode=mode), SAFETY))
    return path


def messages_of(rec, n=None, names=UR, effort=None):
    """One message per sample of a Recording (stamp = its time)."""
    n = len(rec) if n is None else n
    eff = rec.current if effort is None else effort
    return [[int(round(rec.t[k] * 1e9)), list(names), rec.q[k], rec.qd[k], eff[k]]
            for k in range(n)]


def _params(path: Path) -> np.ndarray:
    data = yaml.safe_load(path.read_text())
    found = []

    def walk(node):
        if isinstance(node, dict):
            for key, value in node.items():
                if key == "value" and isinstance(value, float):
                    found.append(value)
                else:
                    walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)

    walk(data)
    return np.array(found)


# ------------------------------------------------------------------------------ reading
@pytest.mark.parametrize("storage", list(STORAGES))
def test_identify_from_bag_equals_identify_from_csv(tmp_path, sample, storage, capsys):
    bag = write_bag(tmp_path / "bag", storage, messages_of(sample))
    assert is_bag(bag) and not is_bag(SAMPLE)
    assert main(["identify", str(SAMPLE), "--robot", "ur5", "--out", str(tmp_path / "c.yaml")]) == 0
    assert main(["identify", str(bag), "--robot", "ur5", "--out", str(tmp_path / "b.yaml")]) == 0
    pc, pb = _params(tmp_path / "c.yaml"), _params(tmp_path / "b.yaml")
    assert pc.size > 30 and pc.shape == pb.shape
    np.testing.assert_allclose(pb, pc, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("storage", list(STORAGES))
def test_single_storage_file_tf_prefix_and_joint_order(tmp_path, sample, storage):
    msgs = messages_of(sample, 400, names=[f"ur_{n}" for n in UR])
    perm = [3, 0, 5, 1, 4, 2]
    for m in msgs[200:]:  # the driver reorders: values follow their names
        m[1] = [m[1][i] for i in perm]
        m[2], m[3], m[4] = (np.asarray(x)[perm] for x in m[2:5])
    bag = write_bag(tmp_path / "b", storage, msgs)
    storage_file = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    for path in (bag, storage_file):
        rec = load_log(path, robot="ur5")
        np.testing.assert_array_equal(rec.q, sample.q[:400])
        np.testing.assert_array_equal(rec.current, sample.current[:400])
        assert rec.metadata["joint_names"][0] == "ur_shoulder_pan_joint"
        assert rec.metadata["time_source"] == "header.stamp"
        assert any("joint order changes" in n and "message 201" in n for n in rec.metadata["notes"])


def test_receive_time_fallback_and_effort_torque(tmp_path, sample):
    gains = load_robot("ur5").drive_gains
    msgs = messages_of(sample, 200, effort=sample.current * gains)
    for m in msgs:
        m[0] = 0
    rec = load_log(write_bag(tmp_path / "b", "mcap", msgs), robot="ur5", effort="torque")
    assert rec.metadata["time_source"] == "bag receive time"
    np.testing.assert_allclose(np.diff(rec.t), 1e-3)
    np.testing.assert_allclose(rec.tau, sample.current[:200] * gains)
    np.testing.assert_allclose(rec.current, sample.current[:200], rtol=1e-12)


def test_protective_stop_is_excluded_and_reported(tmp_path, sample, capsys):
    msgs = messages_of(sample, 600)
    t_ns = [m[0] for m in msgs]
    safety = [(t_ns[0], 1), (t_ns[250], 3), (t_ns[300], 1)]
    bag = write_bag(tmp_path / "b", "sqlite3", msgs, safety=safety)
    rec = load_log(bag, robot="ur5")
    assert len(rec) == 550
    assert not np.isin(rec.t, sample.t[250:300]).any()
    (stop,) = rec.metadata["excluded"]
    assert stop["reason"] == "protective stop" and stop["messages"] == 50
    assert rec.safety_status_bits is not None and set(rec.safety_status_bits) == {1}
    assert main(["view", str(bag), "--robot", "ur5", "--save", str(tmp_path / "v.rrd")]) == 0
    err = capsys.readouterr().err
    assert "protective stop; excluded 50 message(s)" in err and "message 251" in err


# ------------------------------------------------------------------------------ defects
def _defect(kind: str, sample):
    msgs = messages_of(sample, 300)
    if kind == "out of order":  # received in order, stamped out of order
        for m in msgs:
            m.append(m[0])
        msgs[100][0], msgs[101][0] = msgs[101][0], msgs[100][0]
    elif kind == "repeated stamp":
        msgs[100][0] = msgs[99][0]
    elif kind == "missing joint":
        m = msgs[100]
        m[1], m[2], m[3], m[4] = m[1][:5], m[2][:5], m[3][:5], m[4][:5]
    elif kind == "NaN effort":
        msgs[100][4] = np.array(msgs[100][4])
        msgs[100][4][2] = np.nan
    elif kind == "rate change":  # the second half at a quarter of the rate
        t0 = msgs[150][0]
        for k, m in enumerate(msgs[150:]):
            m[0] = t0 + 4 * k * 8_000_000
    elif kind == "empty velocity":
        msgs[100][3] = []
    return msgs


DEFECTS = {  # kind: (text of the one-line error, messages dropped under --drop-bad)
    "out of order": ("goes back", 1),
    "repeated stamp": ("repeats message", 1),
    "missing joint": ("joint wrist_3_joint missing", 1),
    "NaN effort": ("effort[2]: nan is not a finite number", 1),
    "rate change": ("rate changes from 125 Hz to 31.25 Hz", 149),  # message 151 ends both rates
    "empty velocity": ("velocity array is empty", 1),
}


@pytest.mark.parametrize("storage", list(STORAGES))
@pytest.mark.parametrize("kind", list(DEFECTS))
def test_defect_is_one_line_or_dropped_and_counted(tmp_path, sample, storage, kind):
    text, n_dropped = DEFECTS[kind]
    bag = write_bag(tmp_path / "b", storage, _defect(kind, sample))
    with pytest.raises(LogFormatError) as exc:
        load_log(bag, robot="ur5")
    msg = str(exc.value)
    assert "\n" not in msg and "/joint_states message" in msg and "stamp" in msg and text in msg
    rec = load_log(bag, robot="ur5", drop_bad=True)
    assert rec.dropped["count"] == n_dropped and len(rec) == 300 - n_dropped
    assert np.all(np.diff(rec.t) > 0) and np.all(np.isfinite(rec.current))


@pytest.mark.parametrize("storage", list(STORAGES))
def test_repeated_message_is_a_duplicate(tmp_path, sample, storage):
    msgs = messages_of(sample, 300)
    msgs.insert(101, list(msgs[100]))
    rec = load_log(write_bag(tmp_path / "b", storage, msgs), robot="ur5")
    assert len(rec) == 300 and rec.metadata["duplicates_removed"] == 1


@pytest.mark.parametrize("storage", list(STORAGES))
def test_several_publishers(tmp_path, sample, storage):
    msgs = messages_of(sample, 300)
    bag = write_bag(tmp_path / "b", storage, msgs, publishers=2)
    with pytest.raises(LogFormatError, match=r"/joint_states has several publishers \(2 connections\)"):
        load_log(bag, robot="ur5")
    rec = load_log(bag, robot="ur5", drop_bad=True)
    assert len(rec) == 150 and rec.dropped["count"] == 150
    assert rec.dropped["reasons"] == {"other publisher": 150}


def test_several_publishers_on_one_connection(tmp_path, sample):
    """rosbag2 lists one offered QoS profile per publisher of a recorded topic."""
    store = _store()
    msgs = messages_of(sample, 200)
    js = store.types["sensor_msgs/msg/JointState"]
    header, time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    bag = tmp_path / "b"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store,
                             offered_qos_profiles=[_qos(10), _qos(1)])
        for ns, names, q, qd, eff in msgs:
            msg = js(header=header(stamp=time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""),
                     name=names, position=q, velocity=qd, effort=eff)
            w.write(c, ns, store.serialize_cdr(msg, msg.__msgtype__))
    with pytest.raises(LogFormatError, match=r"several publishers \(2 publishers\)"):
        load_log(bag, robot="ur5")
    rec = load_log(bag, robot="ur5", drop_bad=True)  # checked message by message
    assert len(rec) == 200 and any("2 publishers" in n for n in rec.metadata["notes"])


def test_gap_is_named(tmp_path, sample):
    msgs = messages_of(sample, 300)
    del msgs[100:140]
    rec = load_log(write_bag(tmp_path / "b", "mcap", msgs), robot="ur5")
    assert any("1 gap, 40 periods missing" in n and "message 100 " in n for n in rec.metadata["notes"])


def test_bad_inputs_are_one_line(tmp_path, sample, capsys):
    bag = write_bag(tmp_path / "b", "mcap", messages_of(sample, 50))
    cases = [
        (["view", str(bag), "--robot", "ur5", "--topic", "/ur/joint_states"],
         "no topic /ur/joint_states; JointState topics: /joint_states"),
        (["view", str(bag), "--robot", "ur5", "--topic", "joint_states"], "--topic"),
        (["view", str(bag)], "robot unknown"),
        (["view", str(SAMPLE), "--effort", "torque"], "rosbag2 bags only"),
        (["view", str(tmp_path / "none.mcap"), "--robot", "ur5"], "none.mcap"),
    ]
    for argv, text in cases:
        assert main(argv + ["--save", str(tmp_path / "x.rrd")]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("urident: error:") and len(err.splitlines()) == 1 and text in err, err


# ------------------------------------------------------------------------------ export
@pytest.mark.parametrize("storage", list(STORAGES))
def test_convert_round_trip_identifies_the_same_parameters(tmp_path, storage, capsys):
    bag = tmp_path / "ident_bag"
    assert main(["convert", str(SAMPLE), "--bag", str(bag), "--storage", storage,
                 "--tf-prefix", "ur_"]) == 0
    assert is_bag(bag) and (bag / "metadata.yaml").is_file()
    for path, out in ((SAMPLE, "c.yaml"), (bag, "b.yaml")):
        assert main(["identify", str(path), "--robot", "ur5", "--method", "all",
                     "--out", str(tmp_path / out)]) == 0
    pc, pb = _params(tmp_path / "c.yaml"), _params(tmp_path / "b.yaml")
    assert pc.size > 60 and pc.shape == pb.shape
    np.testing.assert_allclose(pb, pc, rtol=1e-9, atol=1e-12)


def test_convert_refuses_outputs_and_keeps_the_old_bag_on_failure(tmp_path, capsys):
    bag = tmp_path / "bag"
    assert main(["convert", str(SAMPLE), "--bag", str(bag)]) == 0
    before = sorted(p.name for p in bag.iterdir())
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir").mkdir()
    (tmp_path / "link").symlink_to(bag)
    cases = [(bag, [], "exists; pass --overwrite"), (tmp_path / "file", ["--overwrite"], "not a rosbag2"),
             (tmp_path / "dir", ["--overwrite"], "not a rosbag2"), (tmp_path / "link", [], "symbolic link"),
             (tmp_path / "no" / "bag", [], "does not exist")]
    capsys.readouterr()
    for out, extra, text in cases:
        assert main(["convert", str(SAMPLE), "--bag", str(out), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and text in err, err
    # an input error after the output check: the existing bag is untouched, no temporary left
    assert main(["convert", str(tmp_path / "missing.csv"), "--bag", str(bag), "--overwrite"]) == 2
    assert sorted(p.name for p in bag.iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag", "dir", "file", "link"]
    assert main(["convert", str(SAMPLE), "--bag", str(bag), "--overwrite", "--storage", "sqlite3"]) == 0
    assert sorted(p.name for p in bag.iterdir()) == ["bag.db3", "metadata.yaml"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag", "dir", "file", "link"]
