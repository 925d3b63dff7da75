"""The probe: `ros2 bag record` of the measured topics, and its bags read back as per-topic arrays
of header stamp, publish time (DDS source timestamp) and receive time."""
from __future__ import annotations

import struct
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graph_bench.facts import HAND_STREAMS, MOVE_FEEDBACK, MOVE_STATUS
from graph_bench.processes import Proc, start, stop


def start_probe(topics: list[str], bag: Path, logdir: Path, control: Any,
                host: Any = None, env: dict[str, str] | None = None) -> Proc:
    """`ros2 bag record` of `topics` (on another host: two_hosts.Host, with its DDS environment);
    returns once it has subscribed to every topic that `control` (control.Control) sees published."""
    qos = bag.parent / f"{bag.name}_qos.yaml"
    # a deep keep-last queue, so the probe never loses what the graph published
    qos.write_text("".join(f"{t}:\n  history: keep_last\n  depth: 1000\n  reliability: reliable\n"
                           f"  durability: volatile\n" for t in topics))
    cmd = ["ros2", "bag", "record", "-s", "mcap", "-o", str(bag), "--include-hidden-topics",
           "--qos-profile-overrides-path", str(qos), *topics]
    proc = start(f"probe_{bag.name}", host.run(cmd) if host else cmd, logdir, env)
    # recording starts once the recorder has subscribed to every topic that has a publisher (some,
    # such as /diagnostics for the relays, have none)
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        log = proc.log.read_bytes()
        if all(f"Subscribed to topic '{t}'".encode() in log for t in topics if control.node.count_publishers(t) > 0):
            time.sleep(1.0)  # let the subscriptions match every publisher
            return proc
        if proc.popen.poll() is not None:
            break
        time.sleep(0.2)
    stop([proc])
    raise RuntimeError(f"ros2 bag record did not subscribe to every published topic within 60 s; see {proc.log}")


@dataclass
class Recording:
    # per topic: arrays of header stamp, publish time, receive time (ns)
    stamps: dict[str, np.ndarray] = field(default_factory=dict)
    publish: dict[str, np.ndarray] = field(default_factory=dict)
    receive: dict[str, np.ndarray] = field(default_factory=dict)
    index_fz: np.ndarray | None = None  # force.z of /prisma/index/wrench, aligned with its stamps
    goals: dict[bytes, int] = field(default_factory=dict)  # MoveMotors goal id -> acceptance stamp
    feedback: dict[bytes, list] = field(default_factory=dict)  # goal id -> feedback messages
    diagnostics: list = field(default_factory=list)  # (stamp_ns, name, level, message)
    # working state while reading: topic -> rows of (stamp, publish, receive)
    rows: dict[str, list] = field(default_factory=dict, repr=False)
    fz: list = field(default_factory=list, repr=False)


def _stamp_ns(stamp: Any) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _read_goal_topics(rec: Recording, topic: str, msg: Any) -> None:
    """The MoveMotors status and feedback, and /diagnostics."""
    if topic == MOVE_STATUS:
        for s in msg.status_list:
            rec.goals.setdefault(bytes(s.goal_info.goal_id.uuid), _stamp_ns(s.goal_info.stamp))
    elif topic == MOVE_FEEDBACK:
        rec.feedback.setdefault(bytes(msg.goal_id.uuid), []).append(msg.feedback)
    else:
        stamp = _stamp_ns(msg.header.stamp)
        for s in msg.status:  # level is a `byte` field: bytes of length 1 in rclpy
            level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
            rec.diagnostics.append((stamp, s.name, level, s.message))


def _read_hand_stream(rec: Recording, kind: str, msg: Any, message: Any) -> None:
    """One per-hand message (one scan): each sample as if it came on its finger's topic."""
    pairs = (zip(msg.fingers, msg.wrenches) if kind == "wrench" else
             ((s.finger, s) for s in (msg.samples if kind == "taxels" else msg.contacts)))
    for finger, sample in pairs:
        rec.rows.setdefault(f"/prisma/{finger}/{kind}", []).append(
            (_stamp_ns(sample.header.stamp), message.publish_time, message.log_time))
        if kind == "wrench" and finger == "index":
            rec.fz.append(sample.wrench.force.z)


def read_probe(bag: Path, prefix: str = "") -> Recording:
    """The probe's bag; prefix: a hand's namespace ("/left"), its topics read as the root hand's."""
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from rosidl_runtime_py.utilities import get_message

    rec = Recording()
    types: dict[str, Any] = {}
    files = sorted(bag.glob("*.mcap"))
    if not files:
        raise RuntimeError(f"the probe wrote no bag in {bag}; see its log")
    for path in files:
        with open(path, "rb") as stream:
            for schema, channel, message in make_reader(stream).iter_messages():
                topic = channel.topic
                if prefix and topic.startswith(prefix + "/"):
                    topic = topic[len(prefix):]
                if topic not in types:
                    types[topic] = get_message(schema.name)
                if topic in (MOVE_STATUS, MOVE_FEEDBACK, "/diagnostics"):
                    _read_goal_topics(rec, topic, deserialize_message(message.data, types[topic]))
                elif topic in HAND_STREAMS:
                    _read_hand_stream(rec, HAND_STREAMS[topic], deserialize_message(message.data, types[topic]),
                                      message)
                else:
                    # every other topic starts with std_msgs/Header: CDR encapsulation (4 bytes), sec, nanosec
                    sec, nanosec = struct.unpack_from("<iI", message.data, 4)
                    rec.rows.setdefault(topic, []).append((sec * 1_000_000_000 + nanosec, message.publish_time,
                                                           message.log_time))
                    if topic == "/prisma/index/wrench":
                        rec.fz.append(deserialize_message(message.data, types[topic]).wrench.force.z)
    for topic, rows in rec.rows.items():
        a = np.array(rows, dtype=np.int64)
        rec.stamps[topic], rec.publish[topic], rec.receive[topic] = a[:, 0], a[:, 1], a[:, 2]
    if rec.fz:
        rec.index_fz = np.array(rec.fz)
    rec.rows, rec.fz = {}, []
    return rec


def read_messages(bag: Path, topic: str) -> list[tuple[int, Any]]:
    """(header stamp ns, message) of every message of one topic in a probe's bag."""
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from rosidl_runtime_py.utilities import get_message

    out = []
    for path in sorted(bag.glob("*.mcap")):
        with open(path, "rb") as stream:
            for schema, _, message in make_reader(stream).iter_messages(topics=[topic]):
                msg = deserialize_message(message.data, get_message(schema.name))
                out.append((_stamp_ns(msg.header.stamp), msg))
    return out


def bag_rates(bag: Path) -> dict[str, dict]:
    """Messages/s and serialised bytes/s per topic of a probe's bag (over the span of its receipts)."""
    from mcap.reader import make_reader

    seen: dict[str, list[int]] = {}  # topic -> [count, bytes, first, last receipt ns]
    for path in sorted(bag.glob("*.mcap")):
        with open(path, "rb") as stream:
            for _, channel, message in make_reader(stream).iter_messages():
                c = seen.setdefault(channel.topic, [0, 0, message.log_time, message.log_time])
                c[0] += 1
                c[1] += len(message.data)
                c[2], c[3] = min(c[2], message.log_time), max(c[3], message.log_time)
    out = {}
    for topic, (n, size, first, last) in seen.items():
        rate = (n - 1) / ((last - first) * 1e-9) if n > 1 and last > first else 0.0
        out[topic] = {"msgs_s": round(rate, 1), "bytes_s": round(size / n * rate)}
    return out
