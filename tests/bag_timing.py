"""Stamp streams of real UR ROS 2 bags, for the bag timing tests and benchmarks/bag_jitter.py.

UR's driver runs in ros2_control_node, whose loop wakes at absolute slots (``next += period;
sleep_until(next)``), reads the latest RTDE package (non_blocking_read, the default) and the
joint_state_broadcaster stamps the message with that cycle's time. So header.stamp = slot + the
wake-up latency, and a cycle that starts late or overruns is followed by cycles that run at once
until the schedule is caught up. A message the broadcaster's realtime publisher could not take,
or the recorder dropped, is a true loss. The recorder's receive time adds transport delay and DDS
batching (several messages delivered together)."""

from __future__ import annotations

import numpy as np

#: wake-up latency models [s]: (base, exponential mean, spike probability, spike range)
LATENCY = {
    "rt_kernel": (5e-6, 10e-6, 0.0, (0.0, 0.0)),
    "generic_kernel": (20e-6, 60e-6, 2e-3, (0.5e-3, 8e-3)),   # ms stalls, as ros2_control#808
    "overloaded": (20e-6, 150e-6, 1e-2, (0.5e-3, 20e-3)),
}


def control_loop_stamps(n: int, period: float, rng: np.random.Generator, model: str,
                        t0: float = 1.0, cycle_s: float = 60e-6) -> np.ndarray:
    """(n,) header stamps [s] of the loop (module doc) under latency ``model``."""
    base, mean, p_spike, (lo, hi) = LATENCY[model]
    lat = base + rng.exponential(mean, n)
    spike = rng.random(n) < p_spike
    lat[spike] += rng.uniform(lo, hi, int(spike.sum()))
    t = np.empty(n)
    busy_until = -np.inf
    for k in range(n):
        slot = t0 + k * period
        t[k] = slot + lat[k] if slot > busy_until else busy_until   # behind: no sleep
        busy_until = t[k] + cycle_s
    return t


def receive_times(stamps: np.ndarray, rng: np.random.Generator, batch_s: float = 0.01,
                  delay_s: float = 150e-6) -> np.ndarray:
    """Receive times of ``stamps`` at a recorder that is handed messages in batches every
    ``batch_s`` (DDS batching), 2 µs apart within a batch."""
    arrive = stamps + delay_s + rng.exponential(50e-6, stamps.size)
    arrive = np.maximum.accumulate(arrive)
    deliver = np.ceil(arrive / batch_s) * batch_s
    _, first, counts = np.unique(deliver, return_index=True, return_counts=True)
    within = np.arange(stamps.size) - np.repeat(first, counts)
    return deliver + 2e-6 * within


def sampled_at(rec, t: np.ndarray):
    """q, qd, current of recording ``rec`` at times ``t`` (from its start), linearly interpolated."""
    tt = np.asarray(rec.t) - rec.t[0]
    x = t - t[0]
    cols = [np.column_stack([np.interp(x, tt, a[:, j]) for j in range(a.shape[1])])
            for a in (rec.q, rec.qd, rec.current)]
    return cols


def write_timed_bag(path, storage: str, rec, stamps: np.ndarray, *, receive=None, speed=(),
                    speed_topic: str = "/speed_scaling_state_broadcaster/speed_scaling",
                    topic: str = "/joint_states", zero_stamps: bool = False):
    """A bag with rosbags' own Writer: one JointState per time in ``stamps`` [s] (values of
    ``rec`` there, UR's joint names), received at ``receive`` (default: the stamp; with
    ``zero_stamps`` the headers carry no stamp), and ``speed`` = [(receive_s, value), ...] on
    ``speed_topic`` as the driver's std_msgs/Float64."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    store = get_typestore(Stores.ROS2_HUMBLE)
    js, f64 = store.types["sensor_msgs/msg/JointState"], store.types["std_msgs/msg/Float64"]
    header, time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    q, qd, cur = sampled_at(rec, stamps)
    ns = np.round(np.asarray(stamps) * 1e9).astype(np.int64)
    recv = ns if receive is None else np.round(np.asarray(receive) * 1e9).astype(np.int64)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        c = w.add_connection(topic, "sensor_msgs/msg/JointState", typestore=store)
        s = (w.add_connection(speed_topic, "std_msgs/msg/Float64", typestore=store)
             if len(speed) else None)
        for k in range(ns.size):
            st = 0 if zero_stamps else int(ns[k])
            msg = js(header=header(stamp=time(sec=st // 10**9, nanosec=st % 10**9), frame_id=""),
                     name=names, position=q[k], velocity=qd[k], effort=cur[k])
            w.write(c, int(recv[k]), store.serialize_cdr(msg, msg.__msgtype__))
        for at, value in speed:
            raw = store.serialize_cdr(f64(data=float(value)), f64.__msgtype__)
            w.write(s, int(round(at * 1e9)), raw)
    return path
