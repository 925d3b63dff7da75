"""The hand and glove graphs over DDS, measured side by side with bare rclpy relays (needs ROS 2).

    python3 bench/ros_graph.py --repeat 2 --out perf_out --plots docs/img

needs ROS 2 Jazzy and this workspace's install/ sourced (bench_ros_graph.py runs the same
measurements as `python bench/run.py` entries). Each measurement runs the project's nodes ("real")
and the relays of bench/ros_relay.py ("relay", the same topics, types, rates, QoS and hop count on
rclpy's default executor) one after the other in the same invocation, in the same ROS_DOMAIN_ID:

- hand at 100 Hz: the real graph through `ros2 launch prisma_bringup hand.launch.py sim:=true`. After
  `settle_s`, the CPU of every node process over `cpu_s` (utime + stime from /proc/<pid>/stat, all
  threads; per thread name too), with nothing else subscribed. Then the probe, `ros2 bag record`
  (C++, keep-last 1000 per topic), records taxels, wrenches, contacts (the graph's per-hand
  topics, the relays' per-finger ones), /joint_states, /diagnostics and the MoveMotors status and
  feedback topics while pinch Grasp goals run, each followed by a
  MoveMotors position goal that opens the hand. Latencies are from the taxel header stamp (the
  sensor's clock when the scan was read) to the probe's receipt of the ContactState / WrenchStamped
  with that stamp (bag log time) and to their publication (bag publish time = DDS source
  timestamp), counted for samples stamped while a Grasp goal ran. The MoveMotors hop: the goal the
  grasp sends when the index force reaches its target (the first index wrench >= finger_force
  after the goal's acceptance) to its acceptance at the motor driver (GoalInfo.stamp); for the
  relay, the goal every 10th index wrench and the stamp it carries.
- scan-rate sweep: the four hand nodes started as hand.launch.py does (same executables and
  parameters) but with `-p rate_hz:=R`; at each R, pinch grasps run while the probe records, and
  dropped = taxel stamps without a wrench / contact of the same stamp, stale = any /diagnostics
  status mentioning "stale" at WARN or above, or a grasp ended with sensor_stale.
- glove at 7.3 frames/s: `ros2 launch prisma_bringup glove.launch.py` (sim backend), CPU of
  glove_driver and glove_perception over `cpu_s`, then frame counts at the probe.
- tactile markers: on one launched sim graph, the CPU of tactile_markers and of the hand nodes with
  nobody watching the markers, then, alternating, with a display's subscription on them (ros_relay.py
  watch) and with the relay role `markers` (the same inputs, the same MarkerArray at the same rate,
  nothing computed) watched instead.

Every process started here runs in its own process group and is stopped with SIGINT, then SIGTERM,
then SIGKILL; none outlives the run.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.hand import FINGERS
from prisma_common.procfs import comm, launched_pids, node_named, stat_fields

HERE = Path(__file__).resolve().parent
HAND_NODES = ("tactile_driver", "force_estimator", "manipulation", "motor_driver")
GLOVE_NODES = ("glove_driver", "glove_perception")
MARKER_TOPIC = "/prisma/tactile_markers"
RELAY_MARKER_TOPIC = "/prisma/relay_markers"
# the relay role standing in for each node (bench/ros_relay.py)
RELAY_ROLE = {"tactile_driver": "sensor", "force_estimator": "force", "manipulation": "manipulation",
              "motor_driver": "motor", "glove_driver": "glove_driver", "glove_perception": "glove_perception"}
MOVE_STATUS = "/prisma/motors/move/_action/status"
MOVE_FEEDBACK = "/prisma/motors/move/_action/feedback"
HAND_TOPICS = ([f"/prisma/{f}/{s}" for s in ("taxels", "wrench", "contact") for f in FINGERS]
               + ["/joint_states", "/diagnostics", MOVE_STATUS, MOVE_FEEDBACK])
# The graph's nodes take each other's per-hand topics and publish the per-finger ones only while
# someone subscribes: its probe records the per-hand form (the same samples, read back per finger),
# as the graph's own consumers do. The relays have only the per-finger topics.
HAND_STREAMS = {"/prisma/hand/taxels": "taxels", "/prisma/hand/wrench": "wrench", "/prisma/hand/contact": "contact"}
GRAPH_TOPICS = list(HAND_STREAMS) + ["/joint_states", "/diagnostics", MOVE_STATUS, MOVE_FEEDBACK]
GLOVE_TOPICS = ["/stag/frame", "/stag/image", "/stag/object", "/stag/hand_pose", "/stag/weight"]
GLOVE_RATE_HZ = 7.3  # config/glove_driver.yaml frame_rate_hz, the real glove's readout rate
# thumb_force 0.7 N, not the default 1.0: the sim world's support lets go of the ball once thumb and
# index both press it above 0.6 N for 0.5 s, after which the next grasp finds nothing to close on.
# The fingers phase (whose end sends the MoveMotors goal measured here) is the default one
GRASP = dict(grasp="pinch", finger_force=0.8, thumb_force=0.7, speed_rpm=60.0, timeout=10.0)
OPEN_RPM = 70.0  # config/motor_driver.yaml max_velocities_rpm
CLK_TCK = os.sysconf("SC_CLK_TCK")
ROS_HINT = ("needs ROS 2 (source /opt/ros/jazzy/setup.bash, or ../shared/ros2/setup.sh in this repository's "
            "development setup; then colcon build and source install/setup.bash)")


def ros_missing() -> str | None:
    """Why the ROS measurements cannot run here, or None when they can."""
    try:
        import rclpy  # noqa: F401
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
        from prisma_msgs.msg import TaxelArray  # noqa: F401
    except ImportError as exc:
        return f"{ROS_HINT} ({exc})"
    try:
        get_package_share_directory("prisma_bringup")
    except PackageNotFoundError:
        return f"{ROS_HINT} (prisma_bringup is not in AMENT_PREFIX_PATH)"
    if shutil.which("ros2") is None:
        return f"{ROS_HINT} (no ros2 command on PATH)"
    try:
        import mcap  # noqa: F401  (reads the probe's bags: publish and receive times)
    except ImportError:
        return "the probe's bags are read with the mcap package: pip install -e '.[test]'"
    return None


# ---- processes ---------------------------------------------------------------------------------
@dataclass
class Proc:
    name: str
    popen: subprocess.Popen
    log: Path


def _child_env() -> dict:
    env = dict(os.environ)
    # the tests turn rclpy's field checks on; a deployed graph runs without them
    env.pop("ROS_PYTHON_CHECK_FIELDS", None)
    return env


def start(name: str, cmd: list[str], logdir: Path, env: dict[str, str] | None = None) -> Proc:
    log = logdir / f"{name}.log"
    handle = open(log, "wb")
    # own process group (stopped as a whole); SIGINT back to default in case this script runs as a
    # background job, whose children would otherwise inherit SIGINT ignored
    popen = subprocess.Popen(cmd, stdout=handle, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                             env={**_child_env(), **(env or {})}, start_new_session=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    handle.close()
    return Proc(name, popen, log)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
        return True
    except ProcessLookupError:
        return False


def stop(procs: list[Proc], timeout_s: float = 15.0) -> None:
    """SIGINT each process group, then SIGTERM, then SIGKILL; waits until every group is gone."""
    for sig, wait_s in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        alive = [p for p in procs if _group_alive(p.popen.pid)]
        if not alive:
            break
        for p in alive:
            try:
                os.killpg(p.popen.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and any(_group_alive(p.popen.pid) for p in alive):
            for p in alive:
                p.popen.poll()
            time.sleep(0.1)
    for p in procs:
        try:
            p.popen.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            pass


def node_pids(launch_pid: int, names: tuple[str, ...], timeout_s: float = 60.0) -> dict[str, int]:
    """The pid of each node launched under `launch_pid` (launch_ros passes `-r __node:=<name>`)."""
    found = launched_pids([launch_pid], {name: node_named(name) for name in names}, timeout_s, poll_s=0.2)
    if len(found) < len(names):
        raise RuntimeError(f"launched nodes not found after {timeout_s:.0f} s: missing "
                           f"{sorted(set(names) - set(found))}")
    return found


def cpu_ticks(pid: int) -> tuple[int, dict[str, int]]:
    """utime + stime of a process (all its threads) and per thread name, in clock ticks."""
    f = stat_fields(f"/proc/{pid}/stat")
    total = int(f[11]) + int(f[12])
    threads: dict[str, int] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            tf = stat_fields(f"{task}/stat")
            name = comm(f"{task}/stat")
        except OSError:
            continue  # thread ended
        threads[name] = threads.get(name, 0) + int(tf[11]) + int(tf[12])
    return total, threads


def system_ticks() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine, all cores."""
    values = [int(v) for v in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    idle = values[3] + values[4]
    total = sum(values[:8])
    return total - idle, total


def wait_quiet(max_busy_pct: float | None, max_wait_s: float) -> dict:
    """Wait until the machine's CPU use (all processes, % of one core over 3 s) is at most
    max_busy_pct, for up to max_wait_s; returns what was seen. Other jobs share this machine."""
    t0 = time.monotonic()
    while True:
        busy0, total0 = system_ticks()
        time.sleep(3.0)
        busy1, total1 = system_ticks()
        busy = (busy1 - busy0) / max(1, total1 - total0) * (os.cpu_count() or 1) * 100
        waited = time.monotonic() - t0
        if max_busy_pct is None or busy <= max_busy_pct or waited >= max_wait_s:
            return {"busy_before_pct": round(busy, 1), "waited_s": round(waited, 1),
                    "quiet": None if max_busy_pct is None else busy <= max_busy_pct}
        time.sleep(7.0)


def measure_cpu(pids: dict[str, int], seconds: float) -> dict:
    """CPU of each process over `seconds`, in % of one core, with the machine's load beside it."""
    start = {name: cpu_ticks(pid) for name, pid in pids.items()}
    busy0, total0 = system_ticks()
    load0 = os.getloadavg()
    t0 = time.monotonic()
    time.sleep(seconds)
    elapsed = time.monotonic() - t0
    end = {name: cpu_ticks(pid) for name, pid in pids.items()}
    busy1, total1 = system_ticks()
    cores = os.cpu_count() or 1
    out = {"window_s": round(elapsed, 2), "processes": {}}
    ours = 0.0
    for name in pids:
        pct = (end[name][0] - start[name][0]) / CLK_TCK / elapsed * 100
        ours += pct
        threads = {t: round((v - start[name][1].get(t, 0)) / CLK_TCK / elapsed * 100, 1)
                   for t, v in end[name][1].items()}
        busy_threads = {t: v for t, v in sorted(threads.items(), key=lambda kv: -kv[1]) if v > 0}
        out["processes"][name] = {"cpu_pct": round(pct, 1), "threads": busy_threads}
    machine = (busy1 - busy0) / max(1, total1 - total0) * cores * 100
    out["machine_busy_pct"] = round(machine, 1)  # all cores, % of one core
    out["others_pct"] = round(machine - ours, 1)  # everything not listed above
    out["loadavg_1min"] = [round(load0[0], 2), round(os.getloadavg()[0], 2)]
    return out


# ---- the benchmark's own ROS node: goals and graph queries ---------------------------------------
class Control:
    """An rclpy node in this process: waits for the graph, sends Grasp and MoveMotors goals. It
    subscribes to no sensor topic (the probe is the bag recorder)."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("perf_bench_control", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()
        self._clients = {}

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except (ExternalShutdownException, self._rclpy.executors.ShutdownException):
            pass

    def close(self) -> None:
        for client in self._clients.values():
            client.destroy()
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=2.0)

    def wait_publishers(self, topics: list[str], timeout_s: float, procs: list[Proc]) -> None:
        """Until every topic has a publisher; fails early when one of `procs` exits."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            _check_alive(procs)
            if all(self.node.count_publishers(t) > 0 for t in topics):
                return
            time.sleep(0.2)
        raise RuntimeError(f"timed out after {timeout_s:.0f} s waiting for publishers of "
                           f"{[t for t in topics if self.node.count_publishers(t) == 0]}")

    def _client(self, action_type, name: str):
        from rclpy.action import ActionClient

        key = (action_type, name)
        if key not in self._clients:
            self._clients[key] = ActionClient(self.node, action_type, name)
        return self._clients[key]

    def _await(self, future, timeout_s: float):
        done = threading.Event()
        future.add_done_callback(lambda f: done.set())
        if not done.wait(timeout_s):
            return None
        return future.result()

    def send(self, action_type, name: str, goal, timeout_s: float):
        """(accepted, accept_stamp_ns, status, result, end_ns) of one goal."""
        client = self._client(action_type, name)
        if not client.wait_for_server(timeout_sec=timeout_s):
            raise RuntimeError(f"action server {name} not available after {timeout_s:.0f} s")
        handle = self._await(client.send_goal_async(goal), timeout_s)
        if handle is None or not handle.accepted:
            return False, 0, None, None, time.time_ns()
        accept_ns = handle.stamp.sec * 1_000_000_000 + handle.stamp.nanosec
        response = self._await(handle.get_result_async(), timeout_s)
        end_ns = time.time_ns()
        if response is None:
            handle.cancel_goal_async()
            return True, accept_ns, None, None, end_ns
        return True, accept_ns, response.status, response.result, end_ns

    def grasp_cycle(self, prefix: str = "") -> dict:
        """One pinch Grasp goal (sent again while refused for now: streams not flowing yet), then
        the hand opened by a MoveMotors position goal. prefix: the hand's namespace ("/left")."""
        from prisma_msgs.action import Grasp, MoveMotors

        from prisma_common.goal_refusal import RETRY_LATER, refusal_code

        deadline = time.monotonic() + 20.0
        while True:
            accepted, accept_ns, status, result, end_ns = self.send(Grasp, f"{prefix}/prisma/grasp",
                                                                    Grasp.Goal(**GRASP), 20.0)
            # the node accepts every goal and aborts one it cannot run yet at once, saying why
            accepted = accepted and not (result is not None and refusal_code(result.reason) in RETRY_LATER)
            if accepted or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        out = {"accepted": accepted, "accept_ns": accept_ns, "end_ns": end_ns,
               "success": bool(result.success) if result is not None else False,
               "reason": result.reason if result is not None else ("rejected" if not accepted else "no result")}
        # at full speed, thumb first, each until its open stop: a fast release keeps the presenting
        # support from letting go, and opening both at once would roll the ball along the pads (the
        # sim world keeps it), ~0.3 mm per grasp, until the pads miss it
        opened = [self.send(MoveMotors, f"{prefix}/prisma/motors/move",
                            MoveMotors.Goal(motors=[motor], mode="velocity", targets=[-OPEN_RPM], timeout=0.0), 20.0)
                  for motor in ("thumb_flexion", "fingers")]
        out["opened"] = all(o[3] is not None and o[3].success for o in opened)
        return out


# ---- the probe ----------------------------------------------------------------------------------
def start_probe(topics: list[str], bag: Path, logdir: Path, control: Control,
                host: Any = None, env: dict[str, str] | None = None) -> Proc:
    """`ros2 bag record` of `topics` (on another host: two_hosts.Host, with its DDS environment)."""
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


def read_probe(bag: Path, prefix: str = "") -> Recording:
    """The probe's bag; prefix: a hand's namespace ("/left"), its topics read as the root hand's."""
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from rosidl_runtime_py.utilities import get_message

    rec = Recording()
    raw: dict[str, list] = {}
    fz = []
    types = {}
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
                    msg = deserialize_message(message.data, types[topic])
                    if topic == MOVE_STATUS:
                        for s in msg.status_list:
                            rec.goals.setdefault(bytes(s.goal_info.goal_id.uuid),
                                                 s.goal_info.stamp.sec * 1_000_000_000 + s.goal_info.stamp.nanosec)
                    elif topic == MOVE_FEEDBACK:
                        rec.feedback.setdefault(bytes(msg.goal_id.uuid), []).append(msg.feedback)
                    else:
                        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                        for s in msg.status:  # level is a `byte` field: bytes of length 1 in rclpy
                            level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
                            rec.diagnostics.append((stamp, s.name, level, s.message))
                    continue
                if topic in HAND_STREAMS:  # one message per scan: each sample as if on its finger's topic
                    msg = deserialize_message(message.data, types[topic])
                    kind = HAND_STREAMS[topic]
                    pairs = (zip(msg.fingers, msg.wrenches) if kind == "wrench" else
                             ((s.finger, s) for s in (msg.samples if kind == "taxels" else msg.contacts)))
                    for finger, sample in pairs:
                        stamp = sample.header.stamp.sec * 1_000_000_000 + sample.header.stamp.nanosec
                        raw.setdefault(f"/prisma/{finger}/{kind}", []).append(
                            (stamp, message.publish_time, message.log_time))
                        if kind == "wrench" and finger == "index":
                            fz.append(sample.wrench.force.z)
                    continue
                # every other topic starts with std_msgs/Header: CDR encapsulation (4 bytes), sec, nanosec
                sec, nanosec = struct.unpack_from("<iI", message.data, 4)
                stamp = sec * 1_000_000_000 + nanosec
                raw.setdefault(topic, []).append((stamp, message.publish_time, message.log_time))
                if topic == "/prisma/index/wrench":
                    fz.append(deserialize_message(message.data, types[topic]).wrench.force.z)
    for topic, rows in raw.items():
        a = np.array(rows, dtype=np.int64)
        rec.stamps[topic], rec.publish[topic], rec.receive[topic] = a[:, 0], a[:, 1], a[:, 2]
    if fz:
        rec.index_fz = np.array(fz)
    return rec


def _stats(ms: np.ndarray) -> dict:
    if len(ms) == 0:
        return {"n": 0}
    p = np.percentile(ms, [50, 90, 99])
    return {"n": int(len(ms)), "p50_ms": round(float(p[0]), 3), "p90_ms": round(float(p[1]), 3),
            "p99_ms": round(float(p[2]), 3), "max_ms": round(float(ms.max()), 3)}


def _in_windows(stamps: np.ndarray, windows: list[tuple[int, int]]) -> np.ndarray:
    mask = np.zeros(len(stamps), dtype=bool)
    for lo, hi in windows:
        mask |= (stamps >= lo) & (stamps <= hi)
    return mask


def latencies(rec: Recording, windows: list[tuple[int, int]]) -> tuple[dict, dict]:
    """(stats, samples in ms) of the hops, for samples stamped inside `windows`."""
    samples: dict[str, np.ndarray] = {}
    parts = {"contact_received": ("contact", "receive"), "contact_published": ("contact", "publish"),
             "wrench_received": ("wrench", "receive"), "wrench_published": ("wrench", "publish"),
             "taxels_published": ("taxels", "publish")}
    for key, (suffix, when) in parts.items():
        chunks, per_finger = [], {}
        for f in FINGERS:
            topic = f"/prisma/{f}/{suffix}"
            if topic not in rec.stamps:
                continue
            stamps = rec.stamps[topic]
            times = (rec.receive if when == "receive" else rec.publish)[topic]
            mask = _in_windows(stamps, windows)
            ms = (times[mask] - stamps[mask]) / 1e6
            chunks.append(ms)
            per_finger[f] = ms
        samples[key] = np.concatenate(chunks) if chunks else np.array([])
        if key == "contact_received":
            samples.update({f"contact_received/{f}": v for f, v in per_finger.items()})
    stats = {k: _stats(v) for k, v in samples.items()}
    return stats, samples


def move_latency_real(rec: Recording, grasps: list[dict]) -> tuple[np.ndarray, dict]:
    """Per grasp: the index wrench that reached finger_force and the MoveMotors goal it caused (the
    first goal accepted after it whose feedback shows the thumb flexing), acceptance - taxel stamp.
    Also how many grasps had no such wrench (ended before) or no such goal."""
    stamps = rec.stamps.get("/prisma/index/wrench", np.array([], dtype=np.int64))
    fz = rec.index_fz if rec.index_fz is not None else np.array([])
    # velocities are in the goal's motor order: fingers, thumb_flexion, thumb_rotation
    thumb_goals = sorted(accept for gid, accept in rec.goals.items()
                         if any(len(fb.velocities) > 1 and fb.velocities[1] > 1.0
                                for fb in rec.feedback.get(gid, [])))
    out, counts = [], {"grasps_without_trigger": 0, "triggers_without_goal": 0}
    for g in grasps:
        if not g["accepted"]:
            continue
        hits = np.nonzero((stamps >= g["accept_ns"]) & (stamps <= g["end_ns"]) & (fz >= GRASP["finger_force"]))[0]
        if len(hits) == 0:
            counts["grasps_without_trigger"] += 1
            continue
        trigger = int(stamps[hits].min())
        after = [a for a in thumb_goals if trigger <= a <= g["end_ns"]]
        if not after:
            counts["triggers_without_goal"] += 1
            continue
        out.append((after[0] - trigger) / 1e6)
    return np.array(out), counts


def move_latency_relay(rec: Recording) -> np.ndarray:
    out = []
    for gid, accept in rec.goals.items():
        fbs = rec.feedback.get(gid)
        if fbs and len(fbs[0].positions) >= 2:
            trigger = int(fbs[0].positions[0]) * 1_000_000_000 + int(fbs[0].positions[1])
            out.append((accept - trigger) / 1e6)
    return np.array(out)


def drops(rec: Recording, lo: int, hi: int, rate_hz: float) -> dict:
    """Taxel samples stamped in [lo, hi] against the wrench / contact samples of the same stamps."""
    out = {"taxels": 0, "dropped_wrench": 0, "dropped_contact": 0, "scan_gaps": 0}
    received = []
    for f in FINGERS:
        t = rec.stamps.get(f"/prisma/{f}/taxels", np.array([], dtype=np.int64))
        t = np.unique(t[(t >= lo) & (t <= hi)])
        out["taxels"] += len(t)
        received.append(len(t) / ((hi - lo) / 1e9))
        for kind in ("wrench", "contact"):
            other = rec.stamps.get(f"/prisma/{f}/{kind}", np.array([], dtype=np.int64))
            out[f"dropped_{kind}"] += int(len(np.setdiff1d(t, other)))
        if f == FINGERS[0] and len(t) > 1:
            out["scan_gaps"] = int(np.sum(np.diff(t) > 1.5e9 / rate_hz))  # scans the driver did not make
    out["received_hz"] = round(float(np.mean(received)), 1)
    return out


def stale_statuses(rec: Recording, lo: int, hi: int) -> list[str]:
    return sorted({f"{name}: {message}" for stamp, name, level, message in rec.diagnostics
                   if lo <= stamp <= hi and level >= 1 and "stale" in message.lower()})


# ---- the graphs ---------------------------------------------------------------------------------
def _share() -> Path:
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("prisma_bringup"))


def _executable(package: str, name: str) -> str:
    from ament_index_python.packages import get_package_prefix

    return str(Path(get_package_prefix(package)) / "lib" / package / name)


def start_hand(kind: str, rate_hz: float, logdir: Path, launch: bool,
               relay_args: dict[str, list[str]] | None = None) -> tuple[list[Proc], dict[str, int]]:
    """The hand graph; returns the processes to stop and the pid of each node (or its relay).
    relay_args: extra arguments of a relay role (bench/ros_relay.py), by the node it stands in for."""
    if kind == "relay":
        relay = {node: start(f"relay_{RELAY_ROLE[node]}",
                             [sys.executable, str(HERE / "ros_relay.py"), RELAY_ROLE[node],
                              "--rate-hz", str(rate_hz if node == "tactile_driver" else 100.0),
                              "--goal-every", str(max(1, round(rate_hz / 10))),
                              *(relay_args or {}).get(node, [])], logdir)
                 for node in HAND_NODES}
        return list(relay.values()), {node: p.popen.pid for node, p in relay.items()}
    if launch:
        if rate_hz != 100.0:
            raise ValueError(f"hand.launch.py runs the sim scan at config/tactile_driver.yaml's rate_hz; "
                             f"{rate_hz} Hz needs launch=False")
        proc = start("hand_launch", ["ros2", "launch", "prisma_bringup", "hand.launch.py", "sim:=true"], logdir)
        return [proc], {**node_pids(proc.popen.pid, HAND_NODES), "launch": proc.popen.pid}
    config = _share() / "config"
    # as hand.launch.py sim:=true starts them: config/<node>.yaml plus its inline parameters
    args = {
        "tactile_driver": ("prisma_tactile_driver", ["-p", "backend:=sim", "-p", "contact_source:=hand_world",
                                                     "-p", f"rate_hz:={rate_hz:.1f}"]),
        "force_estimator": ("prisma_force_estimator", ["-p", f"model_bundle:={config / 'models' / 'cnn2'}"]),
        "manipulation": ("prisma_manipulation", []),
        "motor_driver": ("prisma_motor_driver", ["-p", "backend:=sim"]),
    }
    procs = {node: start(node, [_executable(package, node), "--ros-args", "-r", f"__node:={node}",
                                "--params-file", str(config / f"{node}.yaml"), *extra], logdir)
             for node, (package, extra) in args.items()}
    return list(procs.values()), {node: p.popen.pid for node, p in procs.items()}


def _check_alive(procs: list[Proc]) -> None:
    dead = [p for p in procs if p.popen.poll() is not None]
    if dead:
        tail = dead[0].log.read_text(errors="replace")[-1500:]
        raise RuntimeError(f"{dead[0].name} exited with {dead[0].popen.returncode}; log {dead[0].log}:\n{tail}")


def run_hand(control: Control, kind: str, out: Path, rate_hz: float = 100.0, launch: bool = True,
             settle_s: float = 3.0, cpu_s: float = 12.0, grasps: int = 10, relay_s: float = 20.0,
             probe_s: float | None = None, quiet: tuple[float | None, float] = (None, 0.0),
             graph_probe: str = "hand") -> dict:
    """One hand graph: CPU window, then the probe while grasps run (real) or for relay_s (relay).
    probe_s: record for this long (grasping meanwhile) instead of a number of grasps (the sweep).
    graph_probe: "hand" records the graph's per-hand topics, "finger" its 15 per-finger ones.
    quiet: (max machine CPU %, max wait s) before starting, see wait_quiet."""
    before = wait_quiet(*quiet)
    tag = f"hand_{kind}_{rate_hz:g}hz_{time.strftime('%H%M%S')}"
    logdir = out / tag
    logdir.mkdir(parents=True, exist_ok=True)
    started_by = ("bench/ros_relay.py" if kind == "relay" else "ros2 launch hand.launch.py" if launch
                  else "the node executables with config/<node>.yaml")
    result: dict = {"kind": kind, "rate_hz": rate_hz, "machine_before": before, "started_by": started_by}
    procs, pids = start_hand(kind, rate_hz, logdir, launch)
    probe = None
    try:
        control.wait_publishers([f"/prisma/{f}/{s}" for f in FINGERS for s in ("taxels", "wrench", "contact")]
                                + ["/joint_states"], 90.0, procs)
        time.sleep(settle_s)
        result["cpu"] = measure_cpu(pids, cpu_s) if cpu_s > 0 else None
        _check_alive(procs)
        topics = GRAPH_TOPICS if kind == "real" and graph_probe == "hand" else HAND_TOPICS
        probe = start_probe(topics, logdir / "probe", logdir, control)
        t_lo = time.time_ns()
        cycles = []
        load_pids = {**pids, "probe (ros2 bag record)": probe.popen.pid}
        sampler = _Sampler(load_pids)
        if kind == "real":
            deadline = time.monotonic() + (probe_s or math.inf)
            while (len(cycles) < grasps) if probe_s is None else (time.monotonic() < deadline):
                cycles.append(control.grasp_cycle())
                _check_alive(procs)
        else:
            time.sleep(probe_s or relay_s)
        result["cpu_with_probe"] = sampler.done()
        t_hi = time.time_ns()
        stop([probe])
        rec = read_probe(logdir / "probe")
        _check_alive(procs)
    finally:
        stop(([probe] if probe else []) + procs)
    result["grasps"] = [{k: g[k] for k in ("success", "reason", "opened")}
                        | {"duration_s": round((g["end_ns"] - g["accept_ns"]) / 1e9, 3)} for g in cycles]
    windows = [(g["accept_ns"], g["end_ns"]) for g in cycles if g["accepted"]] if kind == "real" else [(t_lo, t_hi)]
    stats, samples = latencies(rec, windows)
    if kind == "real":
        move, counts = move_latency_real(rec, cycles)
        stats["move_accepted"] = _stats(move) | counts
    else:
        move = move_latency_relay(rec)
        stats["move_accepted"] = _stats(move)
    samples["move_accepted"] = move
    result["latency"] = stats
    result["latency_all_samples"] = {k: v for k, v in latencies(rec, [(t_lo, t_hi)])[0].items()
                                     if k in ("contact_received", "wrench_received")}
    lo, hi = t_lo + 500_000_000, t_hi - 500_000_000  # by stamp: leave the edges of the recording
    result["flow"] = drops(rec, lo, hi, rate_hz)
    result["stale"] = stale_statuses(rec, lo, hi)
    result["sensor_stale_aborts"] = sum(1 for g in cycles if g["reason"] == "sensor_stale")
    result["samples_ms"] = {k: [round(float(x), 4) for x in v] for k, v in samples.items()}
    return result


class _Sampler:
    """CPU of processes between construction and done() (the window with the probe)."""

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = pids
        self.start = {name: cpu_ticks(pid)[0] for name, pid in pids.items()}
        self.t0 = time.monotonic()

    def done(self) -> dict:
        elapsed = time.monotonic() - self.t0
        return {"window_s": round(elapsed, 2),
                **{name: round((cpu_ticks(pid)[0] - self.start[name]) / CLK_TCK / elapsed * 100, 1)
                   for name, pid in self.pids.items()}}


def run_glove(control: Control, kind: str, out: Path, settle_s: float = 5.0, cpu_s: float = 20.0,
              probe_s: float = 10.0, quiet: tuple[float | None, float] = (None, 0.0)) -> dict:
    before = wait_quiet(*quiet)
    tag = f"glove_{kind}_{time.strftime('%H%M%S')}"
    logdir = out / tag
    logdir.mkdir(parents=True, exist_ok=True)
    if kind == "relay":
        relay = {node: start(f"relay_{RELAY_ROLE[node]}", [sys.executable, str(HERE / "ros_relay.py"),
                                                           RELAY_ROLE[node]], logdir) for node in GLOVE_NODES}
        procs, pids = list(relay.values()), {n: p.popen.pid for n, p in relay.items()}
    else:
        proc = start("glove_launch", ["ros2", "launch", "prisma_bringup", "glove.launch.py"], logdir)
        procs, pids = [proc], {**node_pids(proc.popen.pid, GLOVE_NODES), "launch": proc.popen.pid}
    probe = None
    try:
        control.wait_publishers(["/stag/frame", "/stag/hand_pose", "/stag/weight"], 90.0, procs)
        time.sleep(settle_s)
        result = {"kind": kind, "machine_before": before, "cpu": measure_cpu(pids, cpu_s)}
        probe = start_probe(GLOVE_TOPICS, logdir / "probe", logdir, control)
        t0 = time.time_ns()
        time.sleep(probe_s)
        t1 = time.time_ns()
        stop([probe])
        _check_alive(procs)
    finally:
        stop(([probe] if probe else []) + procs)
    rec = read_probe(logdir / "probe")
    lo, hi = t0 + 500_000_000, t1 - 500_000_000
    result["rates_hz"] = {t: round(float(np.sum((s >= lo) & (s <= hi)) / ((hi - lo) / 1e9)), 2)
                          for t, s in rec.stamps.items()}
    return result


def _watched(log: Path) -> dict:
    """What a `ros_relay.py watch` received, from its last line."""
    words = log.read_text().strip().splitlines()[-1].split() if log.is_file() and log.read_text().strip() else []
    if len(words) >= 5 and words[0] == "watch:":
        count, seconds = int(words[1]), float(words[4])
        return {"messages": count, "seconds": seconds, "rate_hz": round(count / seconds, 1) if seconds else None}
    return {"messages": None}


def run_markers(control: Control, out: Path, repeat: int, settle_s: float = 4.0, cpu_s: float = 12.0,
                quiet: tuple[float | None, float] = (None, 0.0)) -> dict:
    """tactile_markers on the launched sim graph: idle (nobody watches), then `repeat` times watched
    by a display and, right after, the relay role `markers` watched instead."""
    before = wait_quiet(*quiet)
    logdir = out / f"markers_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    launch = start("hand_launch", ["ros2", "launch", "prisma_bringup", "hand.launch.py", "sim:=true"], logdir)
    procs = [launch]
    try:
        pids = node_pids(launch.popen.pid, HAND_NODES + ("tactile_markers",))
        control.wait_publishers(["/prisma/hand/taxels", "/joint_states"], 90.0, procs)
        time.sleep(settle_s)
        result: dict = {"machine_before": before, "idle": measure_cpu(pids, cpu_s), "real": [], "relay": []}
        relay_cmd = [sys.executable, str(HERE / "ros_relay.py")]
        for i in range(repeat):
            print(f"markers watched, run {i + 1}/{repeat}", flush=True)
            watch = start(f"watch_real_{i}", relay_cmd + ["watch", "--topic", MARKER_TOPIC], logdir)
            time.sleep(settle_s)
            cpu = measure_cpu(pids, cpu_s)
            stop([watch])
            result["real"].append({**cpu, "watched": _watched(watch.log)})
            print(f"relay markers watched, run {i + 1}/{repeat}", flush=True)
            relay = start(f"relay_markers_{i}", relay_cmd + ["markers"], logdir)
            watch = start(f"watch_relay_{i}", relay_cmd + ["watch", "--topic", RELAY_MARKER_TOPIC], logdir)
            time.sleep(settle_s)
            cpu = measure_cpu({**pids, "relay_markers": relay.popen.pid}, cpu_s)
            stop([watch, relay])
            result["relay"].append({**cpu, "watched": _watched(watch.log)})
            _check_alive(procs)
    finally:
        stop(procs)
    real = [r["processes"]["tactile_markers"]["cpu_pct"] for r in result["real"]]
    relay = [r["processes"]["relay_markers"]["cpu_pct"] for r in result["relay"]]
    graph = lambda row: sum(row["processes"][n]["cpu_pct"] for n in HAND_NODES + ("tactile_markers",))  # noqa: E731
    result["summary"] = {
        "tactile_markers_idle_pct": result["idle"]["processes"]["tactile_markers"]["cpu_pct"],
        "tactile_markers_watched_pct": _median_spread(real),
        "relay_markers_watched_pct": _median_spread(relay),
        "ratio": _median_spread([a / max(1e-9, b) for a, b in zip(real, relay)]),
        "graph_idle_pct": round(graph(result["idle"]), 1),
        "graph_watched_pct": _median_spread([graph(r) for r in result["real"]]),
        "markers_hz": [r["watched"].get("rate_hz") for r in result["real"]],
        "relay_markers_hz": [r["watched"].get("rate_hz") for r in result["relay"]],
    }
    return result


def relay_entities(control: Control, out: Path, settle_s: float = 3.0, cpu_s: float = 12.0,
                   quiet: tuple[float | None, float] = (None, 0.0)) -> dict:
    """CPU of the relay chain at 100 Hz with the manipulation relay bare and with the node's idle
    entities added (--like-node): what the executor charges for a bigger wait set."""
    out_rows = {}
    for label, extra in (("bare", []), ("with the node's idle action servers and timer", ["--like-node"])):
        wait_quiet(*quiet)
        logdir = out / f"entities_{time.strftime('%H%M%S')}"
        logdir.mkdir(parents=True, exist_ok=True)
        procs, pids = start_hand("relay", 100.0, logdir, launch=False, relay_args={"manipulation": extra})
        try:
            control.wait_publishers([f"/prisma/{f}/contact" for f in FINGERS], 60.0, procs)
            time.sleep(settle_s)
            cpu = measure_cpu(pids, cpu_s)
        finally:
            stop(procs)
        out_rows[label] = {"manipulation relay %": cpu["processes"]["manipulation"]["cpu_pct"],
                           "others_pct": cpu["others_pct"]}
    return out_rows


# ---- profiles -----------------------------------------------------------------------------------
# A sample's category: the first rule, from the innermost frame outwards, that matches a frame
# "function (file)" of py-spy's raw output. Samples of threads waiting (in rcl_wait) are not counted.
CATEGORIES = (
    ("torch", lambda fn, path: path.startswith("torch/")),
    ("sim pad model", lambda fn, path: path.endswith("pad_model.py")),
    ("sim backends, hand/world", lambda fn, path: path.endswith(("hand_world.py", "sim_backend.py"))),
    ("publish (serialise + DDS write)",
     lambda fn, path: fn in ("Publisher.publish", "ServerGoalHandle.publish_feedback")),
    ("message classes (construct/convert)",
     lambda fn, path: any(part in path for part in ("/msg/_", "/action/_", "/srv/_"))),
    ("converters (ros_conversions)", lambda fn, path: path.endswith("ros_conversions.py")),
    ("node callbacks (*_node.py)", lambda fn, path: path.endswith("_node.py")),
    ("project cores", lambda fn, path: path.startswith(("prisma_", "stag_glove/"))),
    ("rclpy actions", lambda fn, path: path.startswith("rclpy/action/")),
    ("rclpy executor + other rclpy", lambda fn, path: path.startswith("rclpy/")),
)


def _frame(text: str) -> tuple[str, str, int]:
    fn, _, rest = text.rpartition(" (")
    path, _, line = rest.rstrip(")").rpartition(":")
    return (fn, path, int(line)) if line.isdigit() else (fn, rest.rstrip(")"), 0)


def _wait_line() -> int:
    """The line of rclpy's executor that blocks in rcl_wait (py-spy counts a thread blocked there as
    active: its samples are set aside as waiting, so only CPU work is attributed)."""
    import inspect

    from rclpy.executors import Executor

    lines, first = inspect.getsourcelines(Executor._wait_for_ready_callbacks)
    return first + next(i for i, line in enumerate(lines) if "wait_set.wait(" in line)


def summarise_profile(raw: Path, cpu_pct: float, top: int = 12) -> dict:
    """Per category and per function (self and inclusive): % of the working samples and the share
    of the process's measured CPU (% of one core) that this makes."""
    wait_line = _wait_line()
    stacks, waiting = [], 0
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        if not stack or not count.isdigit():
            continue
        frames = [_frame(f) for f in stack.split(";")]
        leaf = frames[-1]
        if leaf[0] == "Executor._wait_for_ready_callbacks" and leaf[2] == wait_line:
            waiting += int(count)
            continue
        stacks.append(([(fn, path) for fn, path, _ in frames], int(count)))
    total = sum(c for _, c in stacks) or 1
    cats: dict[str, int] = {}
    self_t: dict[str, int] = {}
    incl: dict[str, int] = {}
    for frames, count in stacks:
        category = "other (numpy, stdlib, ...)"
        for fn, path in reversed(frames):
            hit = next((name for name, rule in CATEGORIES if rule(fn, path)), None)
            if hit:
                category = hit
                break
        cats[category] = cats.get(category, 0) + count
        leaf = f"{frames[-1][0]} ({frames[-1][1]})"
        self_t[leaf] = self_t.get(leaf, 0) + count
        for key in {f"{fn} ({path})" for fn, path in frames}:
            incl[key] = incl.get(key, 0) + count

    def table(d: dict[str, int], n: int) -> list:
        return [{"what": k, "samples_pct": round(100 * v / total, 1), "core_pct": round(cpu_pct * v / total, 1)}
                for k, v in sorted(d.items(), key=lambda kv: -kv[1])[:n]]

    return {"working_samples": total, "waiting_samples": waiting, "cpu_pct": cpu_pct,
            "categories": table(cats, len(cats)), "self": table(self_t, top), "inclusive": table(incl, top * 2)}


def profile_hand(control: Control, out: Path, seconds: float = 8.0, rate: int = 200, settle_s: float = 3.0) -> dict:
    """py-spy of each hand node in turn (the 100 Hz graph of hand.launch.py, pinch grasps running)."""
    logdir = out / f"profile_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    procs, pids = start_hand("real", 100.0, logdir, launch=True)
    stop_grasps = threading.Event()
    cycles: list[dict] = []

    def grasping() -> None:
        while not stop_grasps.is_set():
            cycles.append(control.grasp_cycle())

    worker = threading.Thread(target=grasping, daemon=True)
    result: dict = {}
    try:
        control.wait_publishers([f"/prisma/{f}/contact" for f in FINGERS] + ["/prisma/little/wrench"], 90.0, procs)
        time.sleep(settle_s)
        worker.start()
        time.sleep(2.0)
        for node in HAND_NODES:
            raw = logdir / f"{node}.raw.txt"
            sampler = _Sampler({node: pids[node]})
            subprocess.run(["py-spy", "record", "-p", str(pids[node]), "-d", f"{seconds:g}", "-r", str(rate),
                            "-f", "raw", "-o", str(raw)], check=True, capture_output=True)
            cpu = sampler.done()[node]
            result[node] = summarise_profile(raw, cpu)
            _check_alive(procs)
    finally:
        stop_grasps.set()
        worker.join(timeout=30.0)
        stop(procs)
    result["grasps"] = [f"{g['reason']}" for g in cycles]
    return result


# ---- the graph across two hosts ----------------------------------------------------------------
# bimanual.launch.py's nodes: (label, node name, namespace, the computer parts:= puts it on)
BIMANUAL_NODES = ([(f"{hand}/{node}", node, f"/{hand}", side) for hand in ("left", "right")
                   for node, side in (("tactile_driver", "robot"), ("motor_driver", "robot"),
                                      ("robot_state_publisher", "robot"), ("force_estimator", "workstation"),
                                      ("manipulation", "workstation"), ("tactile_markers", "workstation"))]
                  + [("glove/glove_driver", "glove_driver", "", "robot"),
                     ("glove/glove_perception", "glove_perception", "", "workstation")])
HOSTS_HAND = "/left"  # the hand the grasps run on and the latency probe records
# --hosts-graph: the launch command and its nodes (hand: the one hand alone, under the same namespace)
HOSTS_GRAPHS = {"bimanual": (["bimanual.launch.py"], BIMANUAL_NODES),
                "hand": (["hand.launch.py", f"namespace:={HOSTS_HAND[1:]}"],
                         [n for n in BIMANUAL_NODES if n[2] == HOSTS_HAND])}
LAYOUTS = ("one host", "two hosts")
CLONE_NEWNET = 0x40000000


def enter_netns(name: str) -> None:
    """Move this process's main thread into the network namespace `name` (`ip netns add`): every
    thread and process it starts from then on (rclpy's DDS participant, ros2 launch, the probes) is
    on that host."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    fd = os.open(f"/run/netns/{name}", os.O_RDONLY)
    try:
        if libc.setns(fd, CLONE_NEWNET) != 0:
            errno = ctypes.get_errno()
            raise OSError(errno, f"setns into network namespace {name}: {os.strerror(errno)}")
    finally:
        os.close(fd)


def namespaced_node_pids(root_pids: list[int], nodes: list[tuple[str, str, str, str]],
                         timeout_s: float = 90.0) -> dict[str, int]:
    """The pid of each of `nodes` (BIMANUAL_NODES rows) launched under `root_pids` (launch_ros
    passes `-r __node:=<name>` and, under a namespace, `-r __ns:=<namespace>`)."""
    found = launched_pids(root_pids, {label: node_named(node, namespace) for label, node, namespace, _ in nodes},
                          timeout_s)
    if len(found) == len(nodes):
        return found
    raise RuntimeError(f"launched nodes not found after {timeout_s:.0f} s: missing "
                       f"{sorted({n[0] for n in nodes} - set(found))}")


def link_counters(interface: str) -> dict[str, int]:
    """Bytes and packets through this namespace's end of the veth (rx: from the robot)."""
    done = subprocess.run(["ip", "-j", "-s", "link", "show", "dev", interface], capture_output=True, text=True,
                          check=True)
    stats = json.loads(done.stdout)[0]["stats64"]
    return {f"{way}_{what}": int(stats[way][what]) for way in ("rx", "tx") for what in ("bytes", "packets")}


def link_rates(before: dict[str, int], after: dict[str, int], seconds: float) -> dict:
    """Per direction: packets/s and bytes/s on the link (IP packets of UDP: DDS data, acks, discovery)."""
    return {direction: {"packets_s": round((after[f"{way}_packets"] - before[f"{way}_packets"]) / seconds, 1),
                        "bytes_s": round((after[f"{way}_bytes"] - before[f"{way}_bytes"]) / seconds)}
            for direction, way in (("robot -> workstation", "rx"), ("workstation -> robot", "tx"))}


def crossing_topics(control: Control) -> list[dict]:
    """Every topic published on one computer and subscribed on the other (bimanual.launch.py split):
    its direction and how many subscriber processes on the far side (DDS sends each its own copy)."""
    side = {(ns or "/", node): where for _, node, ns, where in BIMANUAL_NODES}
    out = []
    for topic, _ in control.node.get_topic_names_and_types():
        pubs = {side.get((i.node_namespace, i.node_name)) for i in control.node.get_publishers_info_by_topic(topic)}
        subs = [side.get((i.node_namespace, i.node_name)) for i in control.node.get_subscriptions_info_by_topic(topic)]
        for where in ("robot", "workstation"):
            far = [s for s in subs if s is not None and s != where]
            if where in pubs and far:
                out.append({"topic": topic, "direction": f"{where} -> {far[0]}", "far_subscribers": len(far)})
    return sorted(out, key=lambda t: (t["direction"], t["topic"]))


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


def run_hosts(control: Control, layout: str, out: Path, hosts: Any, discovery: str, graph: str = "bimanual",
              settle_s: float = 5.0, cpu_s: float = 12.0, link_s: float = 10.0, grasps: int = 5,
              quiet: tuple[float | None, float] = (None, 0.0)) -> dict:
    """The graph of HOSTS_GRAPHS on one host (parts:=all in the workstation's namespace) or split
    (the robot part in the robot's namespace): CPU of every node, then (split) what crosses the
    link, then the latency probe on the workstation while pinch grasps run on the left hand."""
    launch_args, nodes = HOSTS_GRAPHS[graph]
    before = wait_quiet(*quiet)
    tag = f"hosts_{layout.replace(' ', '_')}_{time.strftime('%H%M%S')}"
    logdir = out / tag
    logdir.mkdir(parents=True, exist_ok=True)
    launch = ["ros2", "launch", "prisma_bringup", *launch_args]
    robot_env = hosts.dds_env(hosts.robot, discovery)
    if layout == "one host":
        procs = [start("bimanual", launch, logdir)]
    else:
        procs = [start("bimanual_robot", hosts.robot.run([*launch, "parts:=robot"]), logdir, robot_env),
                 start("bimanual_workstation", [*launch, "parts:=workstation"], logdir)]
    result: dict = {"kind": layout, "machine_before": before, "discovery": discovery, "graph": graph}
    probes: list[Proc] = []
    try:
        hands = sorted({ns for _, _, ns, _ in nodes if ns})
        control.wait_publishers([f"{h}/prisma/hand/{s}" for h in hands for s in ("taxels", "wrench")]
                                + (["/stag/hand_pose"] if graph == "bimanual" else []), 120.0, procs)
        pids = namespaced_node_pids([p.popen.pid for p in procs], nodes)
        pids.update({f"launch ({p.name})": p.popen.pid for p in procs})
        time.sleep(settle_s)
        if layout == "two hosts":
            link0 = link_counters(hosts.workstation.interface)
        result["cpu"] = measure_cpu(pids, cpu_s)
        if layout == "two hosts":
            result["link_idle"] = link_rates(link0, link_counters(hosts.workstation.interface),
                                             result["cpu"]["window_s"])
            # what each crossing topic carries: recorded on the side that publishes it, where the
            # recorder adds no copy to the link
            crossing = crossing_topics(control)
            bags = {}
            for where, host in (("robot", hosts.robot), ("workstation", None)):
                topics = [t["topic"] for t in crossing if t["direction"].startswith(where)]
                if topics:
                    probes.append(start_probe(topics, logdir / f"link_{where}", logdir, control, host,
                                              robot_env if host else None))
                    bags[where] = logdir / f"link_{where}"
            time.sleep(link_s)
            stop(probes)
            probes = []
            rates = {t: r for bag in bags.values() for t, r in bag_rates(bag).items()}
            result["crossing"] = [t | rates.get(t["topic"], {"msgs_s": 0.0, "bytes_s": 0}) for t in crossing]
        topics = [f"{HOSTS_HAND}{t}" for t in ("/prisma/hand/contact", "/prisma/hand/wrench")] + [
            f"{HOSTS_HAND}{MOVE_STATUS}", f"{HOSTS_HAND}{MOVE_FEEDBACK}"]
        probes.append(start_probe(topics, logdir / "probe", logdir, control))
        link0 = link_counters(hosts.workstation.interface) if layout == "two hosts" else None
        t0 = time.monotonic()
        cycles = [control.grasp_cycle(HOSTS_HAND) for _ in range(grasps)]
        if link0 is not None:
            result["link_grasping"] = link_rates(link0, link_counters(hosts.workstation.interface),
                                                 time.monotonic() - t0)
        stop(probes)
        probes = []
        _check_alive(procs)
        rec = read_probe(logdir / "probe", HOSTS_HAND)
    finally:
        stop(probes + procs)
    result["grasps"] = [{k: g[k] for k in ("success", "reason", "opened")} for g in cycles]
    windows = [(g["accept_ns"], g["end_ns"]) for g in cycles if g["accepted"]]
    stats, _ = latencies(rec, windows)
    move, counts = move_latency_real(rec, cycles)
    stats["move_accepted"] = _stats(move) | counts
    result["latency"] = {k: v for k, v in stats.items() if "/" not in k}
    return result


def summarise_hosts(runs: list[dict]) -> dict:
    """Medians (and spread over repeats) of the one-host and two-host runs, side by side."""
    by = {k: [r for r in runs if r["kind"] == k] for k in LAYOUTS}
    out: dict = {"cpu_pct": {}, "latency_ms": {}, "repeats": len(by["two hosts"]),
                 "graph": " ".join(HOSTS_GRAPHS[runs[0].get("graph", "bimanual")][0])}

    def cpu(run: dict, labels: list[str]) -> float:
        return sum(run["cpu"]["processes"][label]["cpu_pct"] for label in labels)

    nodes = HOSTS_GRAPHS[runs[0].get("graph", "bimanual")][1]
    groups = {label: [label] for label, *_ in nodes}
    for hand in sorted({ns for _, _, ns, _ in nodes if ns}):
        for where in ("robot", "workstation"):
            groups[f"{hand[1:]} hand, {where} part"] = [lb for lb, _, ns, w in nodes if ns == hand and w == where]
        groups[f"{hand[1:]} hand"] = [lb for lb, _, ns, _ in nodes if ns == hand]
    for where in ("robot", "workstation"):
        groups[f"{where} computer (its nodes)"] = [lb for lb, *_, w in nodes if w == where]
    groups["all nodes"] = [lb for lb, *_ in nodes]
    for name, labels in groups.items():
        one = [cpu(r, labels) for r in by["one host"]]
        two = [cpu(r, labels) for r in by["two hosts"]]
        out["cpu_pct"][name] = {"one host": _median_spread(one), "two hosts": _median_spread(two),
                                "ratio": _median_spread([b / a for a, b in zip(one, two) if a])}
    for hop in ("contact_received", "wrench_received", "move_accepted", "contact_published", "wrench_published"):
        entry = {}
        for q in ("p50_ms", "p99_ms"):
            one = [r["latency"][hop].get(q) for r in by["one host"]]
            two = [r["latency"][hop].get(q) for r in by["two hosts"]]
            entry[q] = {"one host": _median_spread(one), "two hosts": _median_spread(two),
                        "added": _median_spread([b - a for a, b in zip(one, two) if a is not None and b is not None])}
        entry["n"] = {k: [r["latency"][hop]["n"] for r in by[k]] for k in LAYOUTS}
        out["latency_ms"][hop] = entry
    out["grasps"] = {k: [f"{sum(g['success'] for g in r['grasps'])}/{len(r['grasps'])}" for r in by[k]]
                     for k in LAYOUTS}
    split = by["two hosts"]
    for window in ("link_idle", "link_grasping"):
        out[window] = {d: {q: _median_spread([r[window][d][q] for r in split]) for q in ("packets_s", "bytes_s")}
                       for d in ("robot -> workstation", "workstation -> robot")}
    topics: dict[tuple[str, str], list] = {}
    for r in split:
        for t in r["crossing"]:
            topics.setdefault((t["direction"], t["topic"]), []).append(t)
    out["crossing"] = [{"direction": d, "topic": t, "far_subscribers": rows[0]["far_subscribers"],
                        "msgs_s": _median_spread([x["msgs_s"] for x in rows]),
                        "bytes_s": _median_spread([x["bytes_s"] for x in rows])}
                       for (d, t), rows in sorted(topics.items())]
    out["machine"] = {k: [r["cpu"][k] for r in runs] for k in ("others_pct", "loadavg_1min")}
    return out


def markdown_hosts(h: dict) -> list[str]:
    graph = h.get("graph", "bimanual.launch.py")
    out = [f"### One host and two hosts: {graph} (% of one core, median (min-max) of {h['repeats']} runs each)",
           "", "| processes | one host | two hosts | two / one |", "|---|---|---|---|"]
    for name, row in h["cpu_pct"].items():
        out.append(f"| {name} | {_cell(row['one host'])} | {_cell(row['two hosts'])} | {_cell(row['ratio'])} |")
    out += ["", f"### Latency, {HOSTS_HAND} hand, probe on the workstation (ms)", "",
            "| from the taxel stamp to | one host p50 | two hosts p50 | one host p99 | two hosts p99 | p99 added "
            "| samples (one; two) |", "|---|---|---|---|---|---|---|"]
    names = {"contact_received": "ContactState received at the workstation's probe",
             "wrench_received": "WrenchStamped received at the workstation's probe",
             "move_accepted": "MoveMotors goal accepted at the motor driver (robot)",
             "contact_published": "ContactState published (DDS source time)",
             "wrench_published": "WrenchStamped published (DDS source time)"}
    for hop, label in names.items():
        e = h["latency_ms"][hop]
        out.append(f"| {label} | {_cell(e['p50_ms']['one host'])} | {_cell(e['p50_ms']['two hosts'])} | "
                   f"{_cell(e['p99_ms']['one host'])} | {_cell(e['p99_ms']['two hosts'])} | "
                   f"{_cell(e['p99_ms']['added'])} | {sum(e['n']['one host'])}; {sum(e['n']['two hosts'])} |")
    out += ["", f"Grasps (succeeded/sent): one host {', '.join(h['grasps']['one host'])}; two hosts "
                f"{', '.join(h['grasps']['two hosts'])}.", "",
            "### On the link (IP packets and bytes, both hands and the glove)", "",
            "| window | direction | packets/s | bytes/s |", "|---|---|---|---|"]
    for window, label in (("link_idle", "no goal"), ("link_grasping", "pinch grasps on the left hand")):
        for d, row in h[window].items():
            out.append(f"| {label} | {d} | {_cell(row['packets_s'])} | {_cell(row['bytes_s'])} |")
    out += ["", "| direction | topic | subscribers across | messages/s | serialised bytes/s (one copy) |",
            "|---|---|---|---|---|"]
    for t in h["crossing"]:
        out.append(f"| {t['direction']} | {t['topic']} | {t['far_subscribers']} | {_cell(t['msgs_s'])} | "
                   f"{_cell(t['bytes_s'])} |")
    out += ["", f"Other load during the CPU windows (% of one core): {h['machine']['others_pct']}; 1-min load "
                f"average at each window's start and end: {h['machine']['loadavg_1min']}.", ""]
    return out


# ---- the whole measurement -----------------------------------------------------------------------
def _median_spread(values: list[float]) -> dict:
    v = [x for x in values if x is not None and not (isinstance(x, float) and math.isnan(x))]
    if not v:
        return {"median": None}
    return {"median": round(float(np.median(v)), 3), "min": round(float(min(v)), 3),
            "max": round(float(max(v)), 3), "runs": len(v)}


def summarise_hand(runs: list[dict]) -> dict:
    """Median (and spread over repeats) of every figure of the 100 Hz runs, real vs relay."""
    by = {k: [r for r in runs if r["kind"] == k] for k in ("real", "relay")}
    out: dict = {"cpu_pct": {}, "latency_ms": {}, "repeats": len(by["real"])}
    for node in HAND_NODES:
        real = _median_spread([r["cpu"]["processes"][node]["cpu_pct"] for r in by["real"]])
        relay = _median_spread([r["cpu"]["processes"][node]["cpu_pct"] for r in by["relay"]])
        ratios = [a["cpu"]["processes"][node]["cpu_pct"] / max(1e-9, b["cpu"]["processes"][node]["cpu_pct"])
                  for a, b in zip(by["real"], by["relay"])]
        out["cpu_pct"][node] = {"real": real, "relay": relay, "ratio": _median_spread(ratios)}
    total_real = [sum(r["cpu"]["processes"][n]["cpu_pct"] for n in HAND_NODES) for r in by["real"]]
    total_relay = [sum(r["cpu"]["processes"][n]["cpu_pct"] for n in HAND_NODES) for r in by["relay"]]
    out["cpu_pct"]["graph (4 nodes)"] = {"real": _median_spread(total_real), "relay": _median_spread(total_relay),
                                         "ratio": _median_spread([a / b for a, b in zip(total_real, total_relay)])}
    out["cpu_pct"]["ros2 launch process"] = {"real": _median_spread(
        [r["cpu"]["processes"]["launch"]["cpu_pct"] for r in by["real"] if "launch" in r["cpu"]["processes"]])}
    for hop in ("contact_received", "wrench_received", "move_accepted", "contact_published", "wrench_published",
                "taxels_published"):
        entry = {}
        for q in ("p50_ms", "p99_ms"):
            real = [r["latency"][hop].get(q) for r in by["real"]]
            relay = [r["latency"][hop].get(q) for r in by["relay"]]
            entry[q] = {"real": _median_spread(real), "relay": _median_spread(relay),
                        "ratio": _median_spread([a / b for a, b in zip(real, relay) if a is not None and b])}
        entry["n"] = {"real": [r["latency"][hop]["n"] for r in by["real"]],
                      "relay": [r["latency"][hop]["n"] for r in by["relay"]]}
        out["latency_ms"][hop] = entry
    out["grasps"] = {"real": [f"{sum(g['success'] for g in r['grasps'])}/{len(r['grasps'])}" for r in by["real"]]}
    out["machine"] = {k: [r["cpu"][k] for r in runs] for k in ("others_pct", "loadavg_1min")}
    return out


def sweep(control: Control, out: Path, rates: list[float], kinds: tuple[str, ...], probe_s: float,
          quiet: tuple[float | None, float] = (None, 0.0), graph_probe: str = "hand") -> list[dict]:
    rows = []
    for rate in rates:
        for kind in kinds:
            r = run_hand(control, kind, out, rate_hz=rate, launch=False, cpu_s=0.0, probe_s=probe_s, quiet=quiet,
                         graph_probe=graph_probe)
            f = r["flow"]
            row = {"kind": kind, "rate_hz": rate, **f, "stale": r["stale"],
                   "sensor_stale_aborts": r["sensor_stale_aborts"],
                   "grasps": f"{sum(g['success'] for g in r['grasps'])}/{len(r['grasps'])}" if kind == "real" else "",
                   "cpu_with_probe": r["cpu_with_probe"], "machine_before": r["machine_before"],
                   "contact_received_p99_ms": r["latency_all_samples"]["contact_received"].get("p99_ms")}
            row["sustained"] = (f["dropped_wrench"] == 0 and f["dropped_contact"] == 0 and not r["stale"]
                                and r["sensor_stale_aborts"] == 0 and f["received_hz"] >= 0.98 * rate)
            print(f"  sweep {kind:5s} {rate:5.0f} Hz: received {f['received_hz']:6.1f} Hz, dropped wrench "
                  f"{f['dropped_wrench']}, contact {f['dropped_contact']}, scan gaps {f['scan_gaps']}, stale "
                  f"{len(r['stale'])}, sustained {row['sustained']}", flush=True)
            rows.append(row)
    return rows


def max_sustained(rows: list[dict], kind: str) -> float:
    """The highest rate of the sweep below which (inclusive) every rate was sustained."""
    best = 0.0
    for row in sorted((r for r in rows if r["kind"] == kind), key=lambda r: r["rate_hz"]):
        if not row["sustained"]:
            break
        best = row["rate_hz"]
    return best


def plot(results: dict, plots: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plots.mkdir(parents=True, exist_ok=True)
    written = []
    if results.get("sweep"):
        rows = results["sweep"]
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
        for kind, color in (("real", "C0"), ("relay", "C1")):
            rs = sorted((r for r in rows if r["kind"] == kind), key=lambda r: r["rate_hz"])
            if not rs:
                continue
            x = [r["rate_hz"] for r in rs]
            ax1.plot(x, [r["received_hz"] for r in rs], "o-", color=color, label=f"{kind}: taxel scans received")
            ax2.plot(x, [100 * r["dropped_wrench"] / max(1, r["taxels"]) for r in rs], "o-", color=color,
                     label=f"{kind}: no WrenchStamped")
            ax2.plot(x, [100 * r["dropped_contact"] / max(1, r["taxels"]) for r in rs], "s--", color=color,
                     label=f"{kind}: no ContactState")
        lim = max(r["rate_hz"] for r in rows)
        ax1.plot([0, lim], [0, lim], ":", color="grey", label="commanded")
        ax1.set(xlabel="commanded scan rate (Hz)", ylabel="received scan rate per finger (Hz)",
                title="scans received at the probe", xlim=(0, lim * 1.05), ylim=(0, lim * 1.05))
        ax2.set(xlabel="commanded scan rate (Hz)", ylabel="% of taxel samples", yscale="symlog",
                title="taxel samples without a wrench / contact")
        ax2.set_yscale("symlog", linthresh=0.1)
        ax2.set_ylim(bottom=0)
        for ax in (ax1, ax2):
            ax.axvline(350, color="red", lw=0.8, ls=":", label="I2C limit, 5 fingers (350 Hz)")
            ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
        fig.tight_layout()
        path = plots / "perf_sweep.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    hand = [r for r in results.get("hand", [])]
    if hand:
        fig, axes = plt.subplots(1, 3, figsize=(13, 4))
        for ax, hop, title in zip(axes, ("contact_received", "wrench_received", "move_accepted"),
                                  ("taxel stamp -> ContactState at probe", "taxel stamp -> WrenchStamped at probe",
                                   "taxel stamp -> MoveMotors goal accepted")):
            for kind, color in (("real", "C0"), ("relay", "C1")):
                runs = [r for r in hand if r["kind"] == kind]
                for i, r in enumerate(runs):
                    v = np.sort(np.array(r["samples_ms"][hop]))
                    if len(v) == 0:
                        continue
                    y = np.arange(1, len(v) + 1) / len(v)
                    ax.step(v, y, where="post", color=color, alpha=0.8, ls=("-", "--", ":")[i % 3],
                            label=f"{kind} run {i + 1} (n={len(v)})")
                    if len(v) < 60:  # few samples (one per grasp): show each
                        ax.plot(v, y, "o", color=color, ms=3)
            ax.set(xscale="log", xlabel="latency (ms)", ylabel="fraction of samples", title=title)
            ax.axhline(0.99, color="grey", lw=0.6, ls=":")
            ax.grid(alpha=0.3, which="both")
            ax.legend(fontsize=7)
        fig.suptitle("100 Hz, 5 fingers; real = hand.launch.py sim:=true during pinch Grasp goals; "
                     "relay = bench/ros_relay.py", fontsize=9)
        fig.tight_layout()
        path = plots / "perf_latency_cdf.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written


def _cell(d: dict | None, unit: str = "") -> str:
    """median (min-max over runs) of a _median_spread dict."""
    if not d or d.get("median") is None:
        return "-"
    if d.get("runs", 1) > 1:
        return f"{d['median']:.3g}{unit} ({d['min']:.3g}-{d['max']:.3g})"
    return f"{d['median']:.3g}{unit}"


def markdown(results: dict) -> str:
    """The tables of docs/performance.md from a results.json."""
    out = []
    if "hand_summary" in results:
        h = results["hand_summary"]
        out += [f"### CPU at 100 Hz (% of one core, median (min-max) of {h['repeats']} runs)", "",
                "| process | hand graph | relay | ratio graph / relay |", "|---|---|---|---|"]
        for name, row in h["cpu_pct"].items():
            out.append(f"| {name} | {_cell(row.get('real'))} | {_cell(row.get('relay'))} | {_cell(row.get('ratio'))} |")
        out += ["", "### Latency at 100 Hz, 5 fingers (ms; graph: samples stamped during pinch Grasp goals)", "",
                "| from the taxel stamp to | graph p50 | graph p99 | relay p50 | relay p99 | p99 ratio "
                "| samples (graph; relay) |",
                "|---|---|---|---|---|---|---|"]
        names = {"contact_received": "ContactState received at the probe",
                 "wrench_received": "WrenchStamped received at the probe",
                 "move_accepted": "MoveMotors goal accepted at the motor driver",
                 "contact_published": "ContactState published (DDS source time)",
                 "wrench_published": "WrenchStamped published (DDS source time)",
                 "taxels_published": "TaxelArray published (DDS source time)"}
        for hop, label in names.items():
            e = h["latency_ms"][hop]
            out.append(f"| {label} | {_cell(e['p50_ms']['real'])} | {_cell(e['p99_ms']['real'])} | "
                       f"{_cell(e['p50_ms']['relay'])} | {_cell(e['p99_ms']['relay'])} | "
                       f"{_cell(e['p99_ms']['ratio'])} | {sum(e['n']['real'])}; {sum(e['n']['relay'])} |")
        out += ["", f"Grasps per run (succeeded/sent): {', '.join(h['grasps']['real'])}.",
                f"Other load during the CPU windows (% of one core, all other processes): "
                f"{h['machine']['others_pct']}; 1-min load average at the window's start and end: "
                f"{h['machine']['loadavg_1min']}.", ""]
    if "hosts_summary" in results:
        out += markdown_hosts(results["hosts_summary"])
    if results.get("sweep"):
        out += ["### Scan-rate sweep (5 fingers, pinch grasps running, probe = ros2 bag record)", "",
                "| commanded Hz | graph: received Hz | no wrench | no contact | stale | grasps | "
                "relay: received Hz | no wrench | no contact | sustained (graph; relay) |",
                "|---|---|---|---|---|---|---|---|---|---|"]
        rows = {(r["kind"], r["rate_hz"]): r for r in results["sweep"]}
        for rate in sorted({r["rate_hz"] for r in results["sweep"]}):
            g, r = rows.get(("real", rate)), rows.get(("relay", rate))
            if not g or not r:
                continue
            stale = len(g["stale"]) + g["sensor_stale_aborts"]
            out.append(f"| {rate:g} | {g['received_hz']:g} | {g['dropped_wrench']} | {g['dropped_contact']} | "
                       f"{stale} | {g['grasps']} | {r['received_hz']:g} | {r['dropped_wrench']} | "
                       f"{r['dropped_contact']} | "
                       f"{'yes' if g['sustained'] else 'no'}; {'yes' if r['sustained'] else 'no'} |")
        m = results.get("sweep_max_sustained_hz", {})
        out += ["", f"Highest rate sustained from 100 Hz up: graph {m.get('real', 0):g} Hz, "
                    f"relay {m.get('relay', 0):g} Hz.", ""]
    if results.get("glove"):
        out += ["### Glove at 7.3 frames/s (% of one core)", "", "| process | glove nodes | relay | ratio |",
                "|---|---|---|---|"]
        for node in GLOVE_NODES:
            real = _median_spread([g["cpu"]["processes"][node]["cpu_pct"]
                                   for g in results["glove"] if g["kind"] == "real"])
            relay = _median_spread([g["cpu"]["processes"][node]["cpu_pct"]
                                    for g in results["glove"] if g["kind"] == "relay"])
            ratio = (_median_spread([a["cpu"]["processes"][node]["cpu_pct"]
                                     / max(1e-9, b["cpu"]["processes"][node]["cpu_pct"])
                                     for a, b in zip([g for g in results["glove"] if g["kind"] == "real"],
                                                     [g for g in results["glove"] if g["kind"] == "relay"])]))
            out.append(f"| {node} | {_cell(real)} | {_cell(relay)} | {_cell(ratio)} |")
        rates = [g["rates_hz"].get("/stag/frame") for g in results["glove"] if g["kind"] == "real"]
        out += ["", f"/stag/frame at the probe: {rates} frames/s.", ""]
    if results.get("markers"):
        m = results["markers"]["summary"]
        out += ["### Tactile markers (% of one core; median (min-max) of the watched runs)", "",
                "| | tactile_markers | relay (same inputs and MarkerArray, nothing computed) | ratio |",
                "|---|---|---|---|",
                f"| nobody watching | {m['tactile_markers_idle_pct']} | - | - |",
                f"| a display watching | {_cell(m['tactile_markers_watched_pct'])} | "
                f"{_cell(m['relay_markers_watched_pct'])} | {_cell(m['ratio'])} |", "",
                f"The hand graph's four nodes and tactile_markers together: {m['graph_idle_pct']} % of one core "
                f"with nobody watching the markers, {_cell(m['graph_watched_pct'])} % with a display watching. "
                f"MarkerArrays received by the display: {m['markers_hz']} /s (relay {m['relay_markers_hz']} /s).",
                ""]
    if results.get("entities"):
        out += ["### The manipulation relay with the node's idle entities (% of one core)", "",
                "| relay manipulation | CPU |", "|---|---|"]
        out += [f"| {k} | {v['manipulation relay %']} |" for k, v in results["entities"].items()]
        out.append("")
    if results.get("profile"):
        out += ["### Where each node's CPU goes (py-spy, 100 Hz graph with pinch grasps running)", ""]
        for node in HAND_NODES:
            p = results["profile"][node]
            out += [f"**{node}** ({p['cpu_pct']} % of one core while profiled; "
                    f"{p['working_samples']} working samples)", "",
                    "| category | % of samples | % of one core |", "|---|---|---|"]
            out += [f"| {c['what']} | {c['samples_pct']} | {c['core_pct']} |" for c in p["categories"]]
            out += ["", "| top functions (self time) | % of samples | % of one core |", "|---|---|---|"]
            out += [f"| `{c['what']}` | {c['samples_pct']} | {c['core_pct']} |" for c in p["self"][:8]]
            out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("perf_out"), help="logs, bags and results.json")
    parser.add_argument("--repeat", type=int, default=1, help="100 Hz runs of each kind, alternating (spread)")
    parser.add_argument("--grasps", type=int, default=10, help="pinch grasps per real 100 Hz run")
    parser.add_argument("--cpu-s", type=float, default=12.0, help="CPU window (s)")
    parser.add_argument("--sweep", default="100,150,200,250,300,350,400,450,500",
                        help="scan rates (Hz), comma separated; '' = no sweep")
    parser.add_argument("--sweep-s", type=float, default=12.0, help="probe recording per sweep rate (s)")
    parser.add_argument("--parts", default="hand,sweep,glove,entities,profile",
                        help="which measurements, comma separated (hand, sweep, glove, entities, profile, "
                             "markers); hosts (alone): the bimanual graph on one host and split across two "
                             "network namespaces (root)")
    parser.add_argument("--hosts-discovery", choices=("subnet", "static"), default="subnet",
                        help="--parts hosts: DDS discovery over the link (test/support/two_hosts.py)")
    parser.add_argument("--hosts-graph", choices=tuple(HOSTS_GRAPHS), default="bimanual",
                        help="--parts hosts: both hands and the glove, or the left hand alone")
    parser.add_argument("--quiet-below", type=float,
                        help="before each run, wait until the machine uses at most this CPU %% (of one core)")
    parser.add_argument("--quiet-wait", type=float, default=600.0, help="... for at most this many seconds")
    parser.add_argument("--plots", type=Path, help="write perf_sweep.png and perf_latency_cdf.png here")
    parser.add_argument("--keep-bags", action="store_true", help="keep the probe's bags under --out")
    parser.add_argument("--graph-probe", choices=("hand", "finger"), default="hand",
                        help="what the probe records from the graph: its per-hand topics (what its own nodes "
                             "take) or the 15 per-finger ones (a recorder of the README's list beside it)")
    parser.add_argument("--markdown", action="store_true",
                        help="only print the tables of an earlier run's --out/results.json (no ROS needed)")
    args = parser.parse_args(argv)
    if args.markdown:
        path = args.out / "results.json"
        if not path.is_file():
            parser.error(f"no {path}: run the measurements with --out {args.out} first")
        print(markdown(json.loads(path.read_text())))
        return 0
    missing = ros_missing()
    if missing:
        print(f"skipped: {missing}", file=sys.stderr)
        return 2
    parts = set(args.parts.split(","))
    unknown = parts - {"hand", "sweep", "glove", "entities", "profile", "markers", "hosts"}
    if unknown:
        parser.error(f"unknown --parts {sorted(unknown)}; choose from hand, sweep, glove, entities, profile, "
                     "markers, hosts")
    if "hosts" in parts and parts != {"hosts"}:
        parser.error("--parts hosts runs alone: it moves this process onto the workstation's network namespace")
    if "profile" in parts and shutil.which("py-spy") is None:
        parser.error("--parts profile needs py-spy on PATH (pip install py-spy)")
    quiet = (args.quiet_below, args.quiet_wait)
    args.out.mkdir(parents=True, exist_ok=True)
    rates = [float(r) for r in args.sweep.split(",") if r.strip()]
    results: dict = {"machine": {"cpus": os.cpu_count(), "uname": " ".join(os.uname()[2:5]),
                                 "loadavg_at_start": [round(x, 2) for x in os.getloadavg()],
                                 "ros_domain_id": os.environ.get("ROS_DOMAIN_ID"),
                                 "rmw": os.environ.get("RMW_IMPLEMENTATION")},
                     "started": time.strftime("%Y-%m-%d %H:%M:%S"), "command": " ".join(sys.argv),
                     "graph_probe": args.graph_probe}
    hosts = None
    if "hosts" in parts:
        sys.path.insert(0, str(HERE.parent / "test" / "support"))
        from two_hosts import HostsUnavailable, TwoHosts

        try:
            hosts = TwoHosts.create()
        except HostsUnavailable as exc:
            print(f"skipped: two hosts need network namespaces: {exc}", file=sys.stderr)
            return 2
        # this process (the goals' client) runs on the workstation, with its DDS settings
        enter_netns(hosts.workstation.netns)
        os.environ.update(hosts.dds_env(hosts.workstation, args.hosts_discovery))
        results["hosts_discovery"] = args.hosts_discovery
    try:
        control = Control()
    except BaseException:
        if hosts is not None:
            hosts.delete()
        raise
    try:
        if "hosts" in parts:
            results["hosts"] = []
            for i in range(args.repeat):
                for layout in LAYOUTS:
                    print(f"bimanual graph, {layout}, run {i + 1}/{args.repeat}", flush=True)
                    results["hosts"].append(run_hosts(control, layout, args.out, hosts, args.hosts_discovery,
                                                      args.hosts_graph, cpu_s=args.cpu_s, grasps=args.grasps,
                                                      quiet=quiet))
            results["hosts_summary"] = summarise_hosts(results["hosts"])
            print(json.dumps(results["hosts_summary"], indent=1), flush=True)
        if "hand" in parts:
            results["hand"] = []
            for i in range(args.repeat):
                for kind in ("real", "relay"):
                    print(f"hand 100 Hz {kind}, run {i + 1}/{args.repeat}", flush=True)
                    results["hand"].append(run_hand(control, kind, args.out, grasps=args.grasps, cpu_s=args.cpu_s,
                                                    quiet=quiet, graph_probe=args.graph_probe))
            results["hand_summary"] = summarise_hand(results["hand"])
            print(json.dumps(results["hand_summary"], indent=1), flush=True)
        if "sweep" in parts and rates:
            print("scan-rate sweep", flush=True)
            results["sweep"] = sweep(control, args.out, rates, ("real", "relay"), args.sweep_s, quiet,
                                     args.graph_probe)
            results["sweep_max_sustained_hz"] = {k: max_sustained(results["sweep"], k) for k in ("real", "relay")}
            print(results["sweep_max_sustained_hz"], flush=True)
        if "glove" in parts:
            results["glove"] = []
            for i in range(args.repeat):
                for kind in ("real", "relay"):
                    print(f"glove {kind}, run {i + 1}/{args.repeat}", flush=True)
                    results["glove"].append(run_glove(control, kind, args.out, cpu_s=max(args.cpu_s, 20.0),
                                                      quiet=quiet))
            print(json.dumps(results["glove"], indent=1), flush=True)
        if "markers" in parts:
            print("tactile markers, idle and watched, beside the relay", flush=True)
            results["markers"] = run_markers(control, args.out, args.repeat, cpu_s=args.cpu_s, quiet=quiet)
            print(json.dumps(results["markers"]["summary"], indent=1), flush=True)
        if "entities" in parts:
            print("relay manipulation with and without the node's idle entities", flush=True)
            results["entities"] = relay_entities(control, args.out, cpu_s=args.cpu_s, quiet=quiet)
            print(json.dumps(results["entities"], indent=1), flush=True)
        if "profile" in parts:
            print("py-spy profiles of the hand nodes at 100 Hz", flush=True)
            wait_quiet(*quiet)
            results["profile"] = profile_hand(control, args.out)
            print(json.dumps(results["profile"], indent=1), flush=True)
    finally:
        control.close()
        if hosts is not None:
            hosts.delete()
        if not args.keep_bags:
            for bag in [*args.out.glob("*/probe"), *args.out.glob("*/link_*")]:
                if bag.is_dir():
                    shutil.rmtree(bag, ignore_errors=True)
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    results["machine"]["loadavg_at_end"] = [round(x, 2) for x in os.getloadavg()]
    path = args.out / "results.json"
    if path.is_file() and args.parts != parser.get_default("parts"):
        # a partial run (--parts) updates what it measured and keeps the rest
        results = {**json.loads(path.read_text()), **{k: v for k, v in results.items() if k not in ("machine",)},
                   "machine": results["machine"]}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(results, indent=1))
    tmp.replace(path)  # whole or not at all
    print(markdown(results))
    if args.plots:
        for path in plot(results, args.plots):
            print(f"wrote {path}")
    print(f"wrote {args.out / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
