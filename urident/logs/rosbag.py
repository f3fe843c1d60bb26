"""rosbag2 logs (MCAP or SQLite storage) in and out: the only module that imports ``rosbags``.

Input: ``sensor_msgs/msg/JointState`` on one topic (``/joint_states``, UR's
joint_state_broadcaster), joints matched by name to the robot file's order (UR's
``shoulder_pan_joint`` … ``wrist_3_joint``, with or without a ``tf_prefix``), time from
``header.stamp`` (the bag's receive time when no message carries a stamp), ``effort`` read as the
motor current [A] (UR's default) or as joint torque [N·m]. The driver's
``…/safety_mode`` and ``…/robot_mode`` topics (io_and_status_controller), when recorded, mark
stopped stretches (protective stop, e-stop, robot not running): their samples are excluded. So does
speed scaling 0 on ``/speed_scaling_state_broadcaster/speed_scaling`` (std_msgs/Float64, percent;
the program paused, the pendant's slider at 0 or a safeguard reduction to standstill); its range
over the samples kept is reported.

Defects are issues as in CSV logs (``urident.logs.validate``), numbered by message (1-based, in
bag order) and named by topic and stamp: one line by default, dropped and counted with
``drop_bad``.

Output: :func:`write_bag` writes a Recording as a rosbag2 (MCAP by default) with the same
JointState layout, so a urident or simulated run can be replayed in ROS tools and read back.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Collection

import numpy as np

from urident.errors import LogFormatError

from .gaps import describe_gaps, find_gaps, nominal_period
from .recording import Recording
from .schema import FIELDS_BY_ATTR, N_JOINTS
from .validate import DropReport, Issue, check_jumps, check_time, check_values

DEFAULT_TOPIC = "/joint_states"
#: What JointState effort holds (docs/signals.md): motor currents [A] (UR's released drivers'
#: default), full joint torques [N·m], or UR's gravity-compensated torques [N·m]
#: (actual_current_as_torque: the driver with use_currents_as_efforts false).
EFFORTS = ("current", "torque", "compensated")
#: The effort check (:func:`effort_meaning`). Unit, from the motion: on joints whose nominal
#: inertial + friction torque d has an RMS of at least DYNAMIC_NM, the effort regressed on
#: (d, gravity G) gives d's coefficient a: a x drive gain in UNIT_BAND → amperes, a in UNIT_BAND →
#: newton-metres (the two are a drive gain, ~10, apart). Gravity, at standstill (every |q̇| below
#: STANDSTILL_RAD_S, at least MIN_STANDSTILL messages) on joints 2-3 whose nominal gravity torque
#: is at least GRAVITY_SHARE of the one with the arm stretched horizontal: the effort's scale s
#: against G. A current has s x gain in UNIT_BAND; a newton-metre effort with s in FOLLOWS_GRAVITY
#: is a full torque, with |s| below COMPENSATED_SCALE a gravity-compensated one.
MOVING_RAD_S = 0.05
MIN_MOVING = 50
DYNAMIC_NM = 0.5
UNIT_BAND = (0.5, 2.0)
STANDSTILL_RAD_S = 0.005
MIN_STANDSTILL = 10
GRAVITY_SHARE = 0.2
FOLLOWS_GRAVITY = (0.5, 2.0)
COMPENSATED_SCALE = 0.3
FORMAT_ROSBAG2 = "rosbag2"
STORAGES = ("mcap", "sqlite3")

_JOINT_STATE = "sensor_msgs/msg/JointState"
_SAFETY_MODE = "ur_dashboard_msgs/msg/SafetyMode"
_ROBOT_MODE = "ur_dashboard_msgs/msg/RobotMode"
_FLOAT64 = "std_msgs/msg/Float64"
_SPEED = "speed scaling"
_SUFFIXES = (".mcap", ".db3")
_INSTALL_HINT = "reading and writing rosbag2 needs the rosbags package: pip install rosbags==0.11.9"
_DROP_HINT = "pass --drop-bad to drop such messages"

#: UR safety modes (ur_dashboard_msgs/SafetyMode) in which the arm is held or braking.
SAFETY_STOPPED = {3: "protective stop", 4: "recovery", 5: "safeguard stop",
                  6: "system emergency stop", 7: "robot emergency stop", 8: "violation",
                  9: "fault", 12: "safeguard stop", 13: "three-position enabling stop"}
ROBOT_MODE_RUNNING = 7
#: RTDE safety_status_bits bit of a UR safety mode (modes 1..7 are bits 0..6; 8, 9 are bits 8, 9).
_SAFETY_BIT = {1: 0, 2: 1, 3: 2, 4: 3, 5: 4, 6: 5, 7: 6, 8: 8, 9: 9}
#: Two stretches of at least this many messages whose periods differ by more than
#: RATE_CHANGE_RATIO are a rate change (a single long interval is a gap, left to the gap rule).
RATE_WINDOW = 25
RATE_CHANGE_RATIO = 1.5

#: Speed scaling at or below this fraction is a standstill the controller holds (the driver
#: publishes exactly 0 while the program is paused or resuming).
SPEED_SCALING_PAUSED = 1e-6

# A tiny definition of UR's status messages, so tests and write_bag need no ROS installation.
SAFETY_MODE_MSG = "uint8 mode\n"
ROBOT_MODE_MSG = "int8 mode\n"


def is_bag(path: str | Path) -> bool:
    """True for a rosbag2 bag: a directory holding ``metadata.yaml``, or one ``.mcap`` or
    ``.db3`` storage file."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in _SUFFIXES


def ur_joint_names(robot_joint_names: Collection[str]) -> tuple[str, ...]:
    """UR's ROS joint names for the robot file's joints: ``shoulder_pan`` → ``shoulder_pan_joint``."""
    return tuple(n if n.endswith("_joint") else f"{n}_joint" for n in robot_joint_names)


def _rosbags():
    try:
        import rosbags.rosbag2 as rosbag2
        import rosbags.typesys as typesys
    except ImportError:
        raise LogFormatError(_INSTALL_HINT) from None
    return rosbag2, typesys


def _typestore(typesys):
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    types = {}
    types.update(typesys.get_types_from_msg(SAFETY_MODE_MSG, _SAFETY_MODE))
    types.update(typesys.get_types_from_msg(ROBOT_MODE_MSG, _ROBOT_MODE))
    store.register(types)
    return store


def _robot_joints(robot: str) -> tuple[str, ...]:
    from urident.model import load_robot

    return load_robot(robot).joint_names


# ---------------------------------------------------------------------------------------- input
@dataclass
class _Messages:
    """The joint-state messages of one topic, in bag order, mapped to the robot's joints."""

    stamp: np.ndarray      # (M,) s, header.stamp (or receive time)
    values: np.ndarray     # (M, 18) q, qd, effort in the robot's joint order (NaN: missing)
    number: np.ndarray     # (M,) 1-based message number on the topic


def load_bag(
    path: str | Path,
    robot: str | None = None,
    topic: str | None = None,
    effort: str | None = None,
    rows: tuple[int, int] | None = None,
    drop_bad: bool = False,
    known_robots: Collection[str] | None = None,
) -> Recording:
    """Load the JointState messages of ``topic`` of a rosbag2 into a :class:`Recording`.

    ``effort``: ``current`` (motor currents [A], UR's released drivers), ``torque`` (full joint
    torques [N·m]) or ``compensated`` (UR's gravity-compensated torques [N·m]); for either torque
    ``Recording.tau`` holds them (``metadata["torque_kind"]`` full / compensated) and ``current``
    is the full torque divided by the robot file's drive gains
    (``metadata["current_from_torque"]``). The effort's meaning is checked at standstill
    (:func:`effort_meaning`): a contradiction with ``effort`` is refused, and without ``effort``
    the one found is used, or the bag refused when it cannot tell. ``rows=(first, last)``
    keeps messages first..last of the topic (1-based, inclusive). Defects raise a one-line
    LogFormatError naming the bag, topic, message number and stamp; ``drop_bad`` drops the
    messages and counts them in ``metadata["dropped"]``.
    """
    path = Path(path)
    topic = topic or DEFAULT_TOPIC
    if effort is not None and effort not in EFFORTS:
        raise LogFormatError(f"effort {effort!r}: expected one of {', '.join(EFFORTS)}")
    if robot is None:
        raise LogFormatError(f"{path}: robot unknown (a bag names none); pass --robot")
    known = known_robots
    if known and robot not in known:
        raise LogFormatError(f"{path}: unknown robot {robot!r}; known: {', '.join(sorted(known))}")
    return _BagLoader(path, robot, topic, effort, rows, drop_bad).load()


class _BagLoader:
    def __init__(self, path, robot, topic, effort, rows, drop_bad) -> None:
        self.path, self.robot, self.topic, self.effort = path, robot, topic, effort
        self.rows, self.drop_bad = rows, bool(drop_bad)
        self.report = DropReport()
        self.notes: list[str] = []
        self.stamps: dict[int, float] = {}
        self.duplicates = 0
        self.speed_topic: str | None = None        # the driver's speed scaling topic, if recorded
        self.speed: np.ndarray | None = None       # its held value at each sample (fraction)
        self.speed_unit = 100.0

    def where(self, number: int) -> str:
        stamp = self.stamps.get(int(number))
        at = "" if stamp is None else f" (stamp {stamp:.6f} s)"
        return f"{self.path}: {self.topic} message {int(number)}{at}"

    def handle(self, issues: list[Issue]) -> None:
        if not issues:
            return
        if not self.drop_bad:
            first = min(issues, key=lambda i: i.line)
            more = len(issues) - 1
            col = f" {first.column}:" if first.column else ""
            tail = f" (and {more} more bad message{'s' if more > 1 else ''})" if more else ""
            raise LogFormatError(f"{self.where(first.line)}:{col} {first.detail}{tail}; {_DROP_HINT}")
        self.report.add(issues)

    def load(self) -> Recording:
        rosbag2, typesys = _rosbags()
        store = _typestore(typesys)
        joints = ur_joint_names(_robot_joints(self.robot))
        _check_metadata(Path(self.path))
        try:
            reader = rosbag2.Reader(self.path)
        except FileNotFoundError:
            raise LogFormatError(f"{self.path}: no such bag") from None
        except Exception as exc:  # noqa: BLE001 - rosbags raises its own and OS errors
            raise LogFormatError(f"{self.path}: not a readable rosbag2: {exc}") from None
        try:
            with reader:
                msgs, status = self._read(reader, store, joints)
        except LogFormatError:
            raise
        except Exception as exc:  # noqa: BLE001 - corrupt storage, unknown types
            raise LogFormatError(f"{self.path}: cannot read the bag: {exc}") from None
        return self._build(msgs, status, joints)

    # ------------------------------------------------------------------ reading
    def _read(self, reader, store, joints):
        conns = [c for c in reader.connections if c.topic == self.topic]
        if not conns:
            found = sorted({c.topic for c in reader.connections if c.msgtype == _JOINT_STATE})
            hint = f"; JointState topics: {', '.join(found)} (--topic)" if found else ""
            raise LogFormatError(f"{self.path}: no topic {self.topic}{hint}")
        bad_type = [c.msgtype for c in conns if c.msgtype != _JOINT_STATE]
        if bad_type:
            raise LogFormatError(
                f"{self.path}: topic {self.topic} is {bad_type[0]}, not {_JOINT_STATE}")
        conns = self._one_publisher(conns)
        status_conns = [c for c in reader.connections
                        if c.msgtype in (_SAFETY_MODE, _ROBOT_MODE)]
        speed = self._speed_scaling_connection(reader.connections)
        status_conns += [speed] if speed is not None else []
        stamps, recv, numbers, values, issues = [], [], [], [], []
        status: dict[str, list] = {_SAFETY_MODE: [], _ROBOT_MODE: [], _SPEED: []}
        index: dict[str, int] | None = None
        order_changes: list[int] = []
        n = 0
        for conn, t_recv, raw in reader.messages(connections=conns + status_conns):
            if conn.msgtype == _FLOAT64:
                value = float(store.deserialize_cdr(raw, conn.msgtype).data)
                status[_SPEED].append((int(t_recv), value))
                continue
            if conn.msgtype != _JOINT_STATE:
                msg = store.deserialize_cdr(raw, conn.msgtype)
                status[conn.msgtype].append((int(t_recv), int(msg.mode)))
                continue
            n += 1
            if self.rows is not None and not self.rows[0] <= n <= self.rows[1]:
                continue
            msg = store.deserialize_cdr(raw, conn.msgtype)
            stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            self.stamps[n] = stamp_ns / 1e9
            names = list(msg.name)
            if index is None or list(index) != names:
                new = self._match(names, joints)
                if isinstance(new, str):
                    issues.append(Issue(n, None, "missing joint", new))
                    continue
                if index is not None and names and set(index) == set(names):
                    order_changes.append(n)
                index = {name: k for k, name in enumerate(names)}
                cols = [index[j] for j in self._matched]
            row = self._row(msg, cols, len(names), n, issues)
            if row is None:
                continue
            stamps.append(stamp_ns)
            recv.append(int(t_recv))
            numbers.append(n)
            values.append(row)
        if self.rows is not None and self.rows[1] > n:
            raise LogFormatError(
                f"{self.path}: messages {self.rows[0]}-{self.rows[1]} asked, {self.topic} has {n}")
        if n == 0:
            raise LogFormatError(f"{self.path}: topic {self.topic} has no messages")
        stamp = np.array(stamps, dtype=np.int64)
        if stamp.size and not stamp.any():
            stamp = np.array(recv, dtype=np.int64)
            self.stamps.update(zip(numbers, stamp / 1e9))
            self.notes.append(f"{self.path}: {self.topic} messages carry no header.stamp; "
                              "time is the bag's receive time")
            self.time_source = "bag receive time"
        else:  # a lone zero stamp among others goes back in time: check_time names it
            self.time_source = "header.stamp"
        if order_changes:
            self.notes.append(f"{self.where(order_changes[0])}: joint order changes "
                              f"({len(order_changes)} time(s)); joints matched by name")
        self.handle(issues)
        msgs = _Messages(stamp / 1e9,  # correctly rounded: the CSV's decimal times exactly
                         np.array(values, dtype=np.float64).reshape(-1, 3 * N_JOINTS),
                         np.array(numbers, dtype=np.int64))
        return msgs, status

    def _speed_scaling_connection(self, connections):
        """The driver's speed scaling topic (any namespace or tf_prefix: ``…/speed_scaling``, a
        Float64), the one in the joint topic's namespace when several are recorded."""
        found = [c for c in connections
                 if c.msgtype == _FLOAT64 and c.topic.endswith("/speed_scaling")]
        if len({c.topic for c in found}) > 1:
            ns = self.topic.rsplit("/", 1)[0]
            found = [c for c in found if c.topic.rsplit("/", 2)[0] == ns] or found
        if len({c.topic for c in found}) > 1:
            self.notes.append(f"{self.path}: several speed scaling topics "
                              f"({', '.join(sorted({c.topic for c in found}))}); none used")
            return None
        if not found:
            return None
        self.speed_topic = found[0].topic
        return found[0]

    def _one_publisher(self, conns):
        """Several connections (or QoS profiles) on the topic are several publishers."""
        profiles = sum(max(len(getattr(c.ext, "offered_qos_profiles", []) or []), 1) for c in conns)
        if len(conns) == 1 and profiles <= 1:
            return conns
        what = f"{len(conns)} connections" if len(conns) > 1 else f"{profiles} publishers"
        if not self.drop_bad:
            raise LogFormatError(
                f"{self.path}: topic {self.topic} has several publishers ({what}); record only the "
                f"driver's joint_state_broadcaster, or {_DROP_HINT} of all but the busiest")
        if len(conns) == 1:
            self.notes.append(f"{self.path}: topic {self.topic} has {what}; their messages are "
                              "checked one by one")
            return conns
        busiest = max(conns, key=lambda c: c.msgcount)
        others = sum(c.msgcount for c in conns if c is not busiest)
        self.notes.append(f"{self.path}: topic {self.topic} has {what}; kept the busiest "
                          f"({busiest.msgcount} messages), dropped {others}")
        self.dropped_publishers = others
        return [busiest]

    def _match(self, names: list[str], joints: tuple[str, ...]) -> str | list[str]:
        """The message names of the robot's joints (one tf_prefix for all), or why not."""
        if len(set(names)) != len(names):
            return "a joint name appears twice"
        prefixes = [n[: -len(joints[0])] for n in names if n.endswith(joints[0])]
        full = [p for p in prefixes if all(p + j in names for j in joints)]
        if len(full) != 1:
            if len(full) > 1:
                return f"joints of several tf_prefixes: {', '.join(repr(p) for p in full)}"
            p = prefixes[0] if prefixes else ""
            missing = next(j for j in joints if p + j not in names)
            return f"joint {p + missing} missing (names: {', '.join(names) or 'none'})"
        self._matched = [full[0] + j for j in joints]
        return self._matched

    def _row(self, msg, cols, n_names, number, issues) -> np.ndarray | None:
        row = np.empty(3 * N_JOINTS)
        for k, label in enumerate(("position", "velocity", "effort")):
            arr = np.asarray(getattr(msg, label), dtype=np.float64)
            if arr.shape != (n_names,):
                what = "empty" if arr.size == 0 else f"{arr.size} values for {n_names} names"
                issues.append(Issue(number, label, "malformed", f"{label} array is {what}"))
                return None
            row[k * N_JOINTS:(k + 1) * N_JOINTS] = arr[cols]
        return row

    # ------------------------------------------------------------------ checking
    def _check(self, msgs: _Messages):
        names = ([f"position[{j}]" for j in range(N_JOINTS)]
                 + [f"velocity[{j}]" for j in range(N_JOINTS)]
                 + [f"effort[{j}]" for j in range(N_JOINTS)])
        eff = FIELDS_BY_ATTR["current" if self.effort == "current" else "tau"]
        bounds = np.concatenate([np.full(N_JOINTS, FIELDS_BY_ATTR["q"].bound),
                                 np.full(N_JOINTS, FIELDS_BY_ATTR["qd"].bound),
                                 np.full(N_JOINTS, eff.bound)])
        units = ["rad"] * N_JOINTS + ["rad/s"] * N_JOINTS + [eff.unit] * N_JOINTS
        t, v, num = msgs.stamp, msgs.values, msgs.number
        ok, issues = check_values(v, num, names, bounds, units, np.zeros(v.shape[1], dtype=bool))
        self.handle(issues)
        t, v, num = t[ok], v[ok], num[ok]
        keep, dup, issues = check_time(t, v, num, "header.stamp")
        issues = [replace(i, detail=i.detail.replace("line ", "message ")) for i in issues]
        self.handle(issues)
        self.duplicates += int(dup.sum())
        t, v, num = t[keep], v[keep], num[keep]
        keep, issues = check_jumps(t, v[:, :N_JOINTS], num, names[:N_JOINTS], self.drop_bad,
                                   f"{self.path}: {self.topic} message")
        self.handle([replace(i, detail=i.detail.replace("line ", "message ")) for i in issues])
        t, v, num = t[keep], v[keep], num[keep]
        t, v, num = self._rate(t, v, num)
        if t.size == 0:
            d = self.report.as_dict()
            raise LogFormatError(f"{self.path}: {self.topic}: no valid messages left "
                                 f"({d['count']} dropped)")
        return t, v, num

    def _rate(self, t, v, num):
        """A rate change (e.g. the driver restarted at another rate) is a defect: drop_bad
        keeps the longest stretch at one rate."""
        dt = np.diff(t)
        if dt.size < 2 * RATE_WINDOW:
            return t, v, num
        local = np.median(np.lib.stride_tricks.sliding_window_view(dt, RATE_WINDOW), axis=1)
        ref = local[0]
        cuts = []
        for k in range(1, local.size):
            r = local[k] / ref
            if (r > RATE_CHANGE_RATIO or r < 1.0 / RATE_CHANGE_RATIO) and \
                    self._rate_differs(t, k + RATE_WINDOW // 2 + 1):
                cuts.append(k + RATE_WINDOW // 2 + 1)
                ref = local[k]
        if not cuts:
            return t, v, num
        k = cuts[0]
        before = 1.0 / np.median(dt[: k - 1]) if k > 1 else float("nan")
        after = 1.0 / np.median(dt[k:]) if k < dt.size else float("nan")
        detail = f"rate changes from {before:.4g} Hz to {after:.4g} Hz"
        bounds = [0, *cuts, t.size]
        runs = [(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
        a, b = max(runs, key=lambda r: r[1] - r[0])
        issues = [Issue(int(num[i]), None, "rate change", detail)
                  for i in range(t.size) if not a <= i < b]
        if not self.drop_bad:
            raise LogFormatError(f"{self.where(num[k])}: {detail}; select one rate with --rows "
                                 f"or {_DROP_HINT} outside the longest stretch")
        self.report.add(issues)
        return t[a:b], v[a:b], num[a:b]

    @staticmethod
    def _rate_differs(t: np.ndarray, cut: int) -> bool:
        """The nominal periods (over spans, so a stall the control loop catches up averages out)
        of the stretches before and after ``cut`` differ by more than RATE_CHANGE_RATIO."""
        a = nominal_period(t[max(0, cut - 2 * RATE_WINDOW): cut])
        b = nominal_period(t[cut: cut + 2 * RATE_WINDOW])
        return bool(a and b and not 1 / RATE_CHANGE_RATIO <= b / a <= RATE_CHANGE_RATIO)

    def _stopped(self, t: np.ndarray, status) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Mask of samples in a stop (driver status topics, zero-order hold on receive time)."""
        stopped = np.zeros(t.size, dtype=bool)
        bits = mode = None
        t_ns = np.round(t * 1e9).astype(np.int64)
        reasons = np.full(t.size, "", dtype=object)
        self.speed = None
        for msgtype, samples in status.items():
            if not samples:
                continue
            samples.sort()
            at = np.array([s[0] for s in samples], dtype=np.int64)
            k = np.searchsorted(at, t_ns, side="right") - 1
            known = k >= 0
            if msgtype == _SPEED:
                val = np.array([s[1] for s in samples], dtype=np.float64)
                # the driver publishes percent; its first ROS 2 versions published the fraction
                self.speed_unit = 100.0 if np.nanmax(np.abs(val)) > 1.0 + 1e-9 else 1.0
                self.speed = np.where(known, val[np.maximum(k, 0)] / self.speed_unit, np.nan)
                bad = known & (self.speed <= SPEED_SCALING_PAUSED)
                reasons[bad & (reasons == "")] = "speed scaling 0 (paused)"
                stopped |= bad
                continue
            val = np.array([s[1] for s in samples], dtype=np.int64)
            held = np.where(known, val[np.maximum(k, 0)], -1)
            if msgtype == _SAFETY_MODE:
                bad = known & np.isin(held, list(SAFETY_STOPPED))
                bits = np.where(known, [1 << _SAFETY_BIT.get(int(m), 0) if m > 0 else 0
                                        for m in held], 0).astype(np.int64)
                for code, name in SAFETY_STOPPED.items():
                    reasons[(held == code) & (reasons == "")] = name
            else:
                bad = known & (held != ROBOT_MODE_RUNNING)
                mode = np.where(known, held, ROBOT_MODE_RUNNING)
                reasons[bad & (reasons == "")] = "robot not running"
            stopped |= bad
        self.stop_reasons = reasons
        return stopped, bits, mode

    # ------------------------------------------------------------------ result
    def _build(self, msgs: _Messages, status, joints) -> Recording:
        t, v, num = self._check(msgs)
        stopped, bits, mode = self._stopped(t, status)
        excluded = []
        if stopped.any():
            edges = np.flatnonzero(np.diff(np.concatenate(([0], stopped.astype(int), [0]))))
            for a, b in zip(edges[::2], edges[1::2]):
                excluded.append({"start_s": float(t[a]), "end_s": float(t[b - 1]),
                                 "messages": int(b - a), "reason": str(self.stop_reasons[a])})
            first = excluded[0]
            self.notes.append(
                f"{self.where(num[edges[0]])}: {first['reason']}; excluded {int(stopped.sum())} "
                f"message(s) in {len(excluded)} stop(s), not fitted")
            keep = ~stopped
            t, v, num = t[keep], v[keep], num[keep]
            bits = None if bits is None else bits[keep]
            mode = None if mode is None else mode[keep]
            self.speed = None if self.speed is None else self.speed[keep]
            if t.size == 0:
                raise LogFormatError(f"{self.path}: {self.topic}: every message is in a stop")
        speed = self._speed_report()
        period = nominal_period(t)
        gaps = find_gaps(t, period)
        if gaps:  # the consumers' gap rule; a stop's hole is one too (check_log_usable knows)
            self.notes.append(f"{self.where(num[gaps[0].index - 1])}: {self.topic}: "
                              f"{describe_gaps(gaps)} (period {period:.4g} s)")
        q, qd, eff = v[:, :N_JOINTS], v[:, N_JOINTS:2 * N_JOINTS], v[:, 2 * N_JOINTS:]
        from urident.model import load_robot

        spec = load_robot(self.robot)
        effort = self._effort(spec, t, q, qd, eff)
        tau = None
        current = eff
        metadata: dict[str, Any] = {
            "log_format": FORMAT_ROSBAG2, "status": "unknown", "topic": self.topic,
            "joint_names": list(self._matched), "effort": effort,
            "time_source": self.time_source, "rows": list(self.rows) if self.rows else None,
            "first_line": int(num[0]), "last_line": int(num[-1]),
            "duplicates_removed": self.duplicates, "excluded": excluded, "notes": self.notes,
            "speed_scaling": speed,
        }
        if effort != "current":
            gains = np.asarray(spec.drive_gains, dtype=float)
            tau = eff
            full = eff
            if effort == "compensated":
                full = eff + _nominal_gravity(spec, q)
            current = full / gains
            metadata["current_from_torque"] = True
            metadata["torque_kind"] = "full" if effort == "torque" else "compensated"
        dropped = self.report.as_dict()
        if self.report.issues:
            first = min(self.report.issues, key=lambda i: i.line)
            dropped["first"] = f"{self.where(first.line)}: {first.detail}"
        extra = getattr(self, "dropped_publishers", 0)
        if extra:
            dropped["count"] += extra
            dropped["reasons"]["other publisher"] = extra
        metadata["dropped"] = dropped
        rate = float(f"{1.0 / period:.6g}") if period else None
        return Recording(t=t, q=q, qd=qd, current=current, tau=tau, source=self.path,
                         robot=self.robot, rate_hz=rate, metadata=metadata,
                         safety_status_bits=bits, robot_mode=mode)

    def _effort(self, spec, t, q, qd, eff) -> str:
        """The effort's meaning: ``--effort`` checked (:func:`effort_meaning`), or the one found."""
        found, possible, figures = effort_meaning(spec, t, q, qd, eff)
        if self.effort is None:
            if found is None:
                raise LogFormatError(f"{self.path}: {self.topic}: cannot tell what JointState effort "
                                     f"holds ({figures}); pass --effort current, torque or "
                                     "compensated (docs/signals.md)")
            self.notes.append(f"{self.path}: effort read as {found} ({figures})")
            return found
        if self.effort not in possible:
            hint = f"; pass --effort {found}" if found else ""
            raise LogFormatError(f"{self.path}: --effort {self.effort} contradicts the effort "
                                 f"({figures}): not {_EFFORT_TEXT[self.effort]}{hint}")
        if found is None:
            self.notes.append(f"{self.path}: effort taken as {self.effort} (--effort), not fully "
                              f"checked: {figures}")
        else:
            self.notes.append(f"{self.path}: effort is {self.effort} as given ({figures})")
        return self.effort

    def _speed_report(self) -> dict | None:
        """Speed scaling over the samples kept: metadata and a note (None without the topic)."""
        topic = self.speed_topic
        if topic is None:
            return None
        held = self.speed[np.isfinite(self.speed)] if self.speed is not None else np.array([])
        if held.size == 0:
            self.notes.append(f"{self.path}: {topic} has no message before or during the "
                              f"{self.topic} messages kept")
            return {"topic": topic, "min_percent": None, "max_percent": None}
        lo, hi = 100.0 * float(held.min()), 100.0 * float(held.max())
        unit = "percent" if self.speed_unit == 100.0 else "fraction"
        self.notes.append(f"{self.path}: speed scaling {lo:.4g}–{hi:.4g} % over the samples kept "
                          f"({topic}, in {unit})")
        return {"topic": topic, "min_percent": lo, "max_percent": hi, "unit": unit}


_EFFORT_TEXT = {"current": "a motor current (the torque / drive gain, gravity in it)",
                "torque": "a full joint torque (N·m, gravity in it)",
                "compensated": "a gravity-compensated torque (N·m, near zero against gravity)"}


def _nominal_gravity(spec, q: np.ndarray) -> np.ndarray:
    from urident.model.regressor import joint_torques

    zero = np.zeros_like(q)
    return joint_torques(spec, spec.nominal_params, q, zero, zero)


def _effort_unit(spec, t, q, qd, effort) -> tuple[str | None, str]:
    """``A`` or ``N·m`` from the moving samples (module constants), with the figures."""
    from urident.model.regressor import joint_torques

    moving = np.flatnonzero(np.max(np.abs(qd), axis=1) >= MOVING_RAD_S)
    if moving.size < MIN_MOVING:
        return None, f"fewer than {MIN_MOVING} moving messages to tell A from N·m"
    # on the nominal period, not the stamps: receive times bunch messages (DDS batching), and a
    # derivative over their near-zero intervals is noise
    period = nominal_period(t) if t.size > 1 else 0.0
    qdd = np.gradient(qd, axis=0) / period if period > 0 else np.zeros_like(qd)
    kernel = np.ones(9) / 9.0  # the differentiated velocity's noise, smoothed over ~9 samples
    qdd = np.column_stack([np.convolve(qdd[:, j], kernel, mode="same") for j in range(N_JOINTS)])
    index = moving[np.linspace(0, moving.size - 1, min(moving.size, 2000)).astype(int)]
    full = joint_torques(spec, spec.nominal_params, q[index], qd[index], qdd[index])
    g = _nominal_gravity(spec, q[index])
    d = full - g
    gains = np.asarray(spec.drive_gains, dtype=float)
    units, parts = [], []
    for j in range(N_JOINTS):
        if np.sqrt(np.mean(d[:, j] ** 2)) < DYNAMIC_NM:
            continue
        a = float(np.linalg.lstsq(np.column_stack([d[:, j], g[:, j]]), effort[index, j], rcond=None)[0][0])
        unit = ("A" if UNIT_BAND[0] <= a * gains[j] <= UNIT_BAND[1] else
                "N·m" if UNIT_BAND[0] <= a <= UNIT_BAND[1] else None)
        units.append(unit)
        parts.append(f"{j + 1}: {a:.3g}")
    if not units:
        return None, f"no joint with {DYNAMIC_NM} N·m RMS of dynamic torque to tell A from N·m"
    figures = "effort / nominal dynamic torque on joints " + ", ".join(parts)
    found = {u for u in units if u is not None}
    if len(found) != 1:
        return None, figures + " (neither A nor N·m throughout)"
    return found.pop(), figures


def effort_meaning(spec, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                   effort: np.ndarray) -> tuple[str | None, set[str], str]:
    """What an (N, 6) effort holds: its unit from the motion (a current is the nominal torque /
    drive gain, a torque the torque), then, on joints 2-3 at standstill, its scale against the
    nominal gravity G (a current and a full torque follow G, a gravity-compensated torque stays
    near zero); module constants. Returns (``current`` / ``torque`` / ``compensated`` or None when
    it cannot tell, the kinds not excluded, the figures)."""
    kinds = set(EFFORTS)
    if not np.any(effort):  # a driver that lists the field but never fills it
        return None, kinds, "every effort is zero"
    unit, figures = _effort_unit(spec, t, q, qd, effort)
    if unit is not None:
        kinds = {"current"} if unit == "A" else {"torque", "compensated"}
        figures = f"{unit}: {figures}"
    still = np.max(np.abs(qd), axis=1) < STANDSTILL_RAD_S
    if int(still.sum()) < MIN_STANDSTILL:
        return None, kinds, (f"{figures}; fewer than {MIN_STANDSTILL} messages at standstill "
                             f"(|qd| < {STANDSTILL_RAD_S} rad/s)")
    index = np.flatnonzero(still)
    index = index[np.linspace(0, index.size - 1, min(index.size, 400)).astype(int)]
    g = _nominal_gravity(spec, q[index])
    stretched = np.abs(_nominal_gravity(spec, np.zeros((1, N_JOINTS)))[0])
    gains = np.asarray(spec.drive_gains, dtype=float)
    joints = [j for j in (1, 2) if np.mean(np.abs(g[:, j])) >= GRAVITY_SHARE * stretched[j]]
    if not joints:
        return None, kinds, (f"{figures}; no gravity load on joints 2-3 at standstill "
                             f"({int(still.sum())} messages; under {GRAVITY_SHARE:.0%} of the arm "
                             "stretched horizontal)")
    votes, parts = [], []
    for j in joints:
        e = effort[index, j]
        scale = float(e @ g[:, j] / (g[:, j] @ g[:, j]))
        vote = set()  # the kinds this joint allows (a small positive scale: current or compensated)
        if UNIT_BAND[0] <= scale * gains[j] <= UNIT_BAND[1]:
            vote.add("current")
        if FOLLOWS_GRAVITY[0] <= scale <= FOLLOWS_GRAVITY[1]:
            vote.add("torque")
        if abs(scale) < COMPENSATED_SCALE:
            vote.add("compensated")
        votes.append(vote)
        parts.append(f"joint {j + 1}: mean effort {np.mean(e):.4g} against nominal gravity "
                     f"{np.mean(g[:, j]):.4g} N·m (effort/gravity {scale:.3g})")
    for vote in votes:
        kinds &= vote
    figures = f"{figures}; {int(still.sum())} messages at standstill, " + ", ".join(parts)
    if unit is None or len(kinds) != 1:
        return None, kinds, figures + ("; contradictory" if not kinds else "")
    return next(iter(kinds)), kinds, figures


# --------------------------------------------------------------------------------------- output
def write_bag(
    recording: Recording,
    out: str | Path,
    joint_names: Collection[str],
    topic: str = DEFAULT_TOPIC,
    effort: str = "current",
    storage: str = "mcap",
    tf_prefix: str = "",
    values: np.ndarray | None = None,
) -> Path:
    """Write ``recording`` as a rosbag2 directory ``out`` (must not exist): one JointState per
    sample on ``topic`` (stamp = log time, names = ``tf_prefix`` + UR's joint names, effort =
    ``values`` (N, 6) if given, else the current or, with ``effort`` torque or compensated,
    ``recording.tau``), and the safety and robot modes the log carries on
    ``/io_and_status_controller/…``. Returns ``out``."""
    rosbag2, typesys = _rosbags()
    store = _typestore(typesys)
    out = Path(out)
    if effort not in EFFORTS:
        raise LogFormatError(f"effort {effort!r}: expected one of {', '.join(EFFORTS)}")
    if storage not in STORAGES:
        raise LogFormatError(f"storage {storage!r}: expected one of {', '.join(STORAGES)}")
    eff = values if values is not None else recording.current if effort == "current" else recording.tau
    if eff is None:
        raise LogFormatError(f"{recording.source}: the log carries no joint torque")
    names = [f"{tf_prefix}{n}" for n in ur_joint_names(joint_names)]
    plugin = rosbag2.StoragePlugin.MCAP if storage == "mcap" else rosbag2.StoragePlugin.SQLITE3
    types = store.types
    JointState = types[_JOINT_STATE]
    Header, Time = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    t_ns = np.round(np.asarray(recording.t, dtype=np.float64) * 1e9).astype(np.int64)
    if np.any(t_ns < 0):
        raise LogFormatError(f"{recording.source}: negative timestamps cannot be ROS stamps")
    with rosbag2.Writer(out, version=9, storage_plugin=plugin) as writer:
        conn = writer.add_connection(topic, _JOINT_STATE, typestore=store)
        for k, ns in enumerate(t_ns):
            msg = JointState(
                header=Header(stamp=Time(sec=int(ns // 1_000_000_000),
                                         nanosec=int(ns % 1_000_000_000)), frame_id=""),
                name=names, position=np.array(recording.q[k]),
                velocity=np.array(recording.qd[k]), effort=np.array(eff[k]))
            writer.write(conn, int(ns), store.serialize_cdr(msg, _JOINT_STATE))
        bits = recording.safety_status_bits
        if bits is not None:
            _write_modes(writer, store, _SAFETY_MODE, "/io_and_status_controller/safety_mode",
                         t_ns, [_safety_mode(int(b)) for b in bits])
        if recording.robot_mode is not None:
            _write_modes(writer, store, _ROBOT_MODE, "/io_and_status_controller/robot_mode",
                         t_ns, [int(m) for m in recording.robot_mode])
    return out


def _safety_mode(bits: int) -> int:
    """The UR safety mode of RTDE safety_status_bits (the highest set bit wins; 1 = normal)."""
    mode = 1
    for code, bit in _SAFETY_BIT.items():
        if bits >> bit & 1:
            mode = code
    return mode


def _write_modes(writer, store, msgtype, topic, t_ns, modes) -> None:
    """Mode messages on change only (the driver publishes them on change too)."""
    conn = writer.add_connection(topic, msgtype, typestore=store)
    cls = store.types[msgtype]
    last = None
    for ns, m in zip(t_ns, modes):
        if m != last:
            writer.write(conn, int(ns), store.serialize_cdr(cls(mode=m), msgtype))
            last = m


def _check_metadata(path: Path) -> None:
    """A bag directory's ``metadata.yaml`` read by the one strict YAML reader first: a garbage file
    is named with its line in one line (rosbags' own message spans several)."""
    meta = path / "metadata.yaml"
    if not (path.is_dir() and meta.is_file()):
        return
    from urident.yamlio import load_yaml

    doc = load_yaml(meta, "bag metadata", LogFormatError)
    if not isinstance(doc, dict) or not isinstance(doc.get("rosbag2_bagfile_information"), dict):
        raise LogFormatError(f"{meta}: not a rosbag2 metadata file (no rosbag2_bagfile_information mapping)")
