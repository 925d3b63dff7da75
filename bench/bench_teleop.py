"""Teleoperation over DDS beside a bare rclpy relay chain of the same hops (python bench/run.py --only teleop_...).

Needs ROS 2 Jazzy and this workspace's install/ sourced; without them every entry prints
`skipped: needs ROS 2 (...)` and the value nan. Each run is in the calling shell's ROS_DOMAIN_ID and
is driven by bench/teleop_relay.py's step glove (/glove/joint_states at 60 Hz, the fingers stepping
between open and half a fist every 1.5 s):
- real: `teleop.launch.py glove:=none`: the sim hand, the teleop node engaged at start;
- relay: teleop_relay.py's teleop and manipulation roles and ros_relay.py's motor role.
A probe (`ros2 bag record`) takes the MoveMotors status and feedback and the targets. Ratios are
"higher is better":

teleop_latency_p99: relay p99 / graph p99 of glove sample stamp -> MoveMotors goal accepted at the
  motor driver (the motor command on the bus), per glove step: real, the first goal accepted after the
  step's first sample whose motor feedback moves the fingers the step's way; relay, the stamp the goal
  carries. Needed 0.5 (p99 at most 2x the relay chain's).
teleop_cpu_vs_relay: relay CPU / teleop node CPU, the relay handling the same messages: the 60 Hz
  glove in, its targets out, and a Teleoperate goal held (its feedback comes with every manipulation
  step, 100 Hz). Needed 1 / 1.5 (the node at most 1.5x its relay).
"""
from __future__ import annotations

import functools
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from graph_bench.control import measured_with_ros, shared_control
from graph_bench.cpu import measure_cpu, wait_quiet
from graph_bench.facts import MOVE_FEEDBACK, MOVE_STATUS
from graph_bench.probe import Recording, read_probe, start_probe
from graph_bench.processes import Proc, check_alive, launch_nodes, relay_command, start, stop
from graph_bench.stats import percentiles
from prisma_common.topics import TELEOP_TARGETS
from run import Benchmark

TARGETS = TELEOP_TARGETS
STEP_S = 1.5
STEPS = 20
NODES = ("teleop", "manipulation", "motor_driver")
MOVING_RAD_S = 0.05  # a fingers velocity in the motor feedback that is a move, not noise


@functools.cache
def _out() -> Path:
    return Path(tempfile.mkdtemp(prefix="prisma_teleop_bench_"))


def _start_graph(kind: str, logdir: Path) -> tuple[list[Proc], dict[str, int]]:
    if kind == "real":
        launch, pids = launch_nodes("teleop_launch", ["ros2", "launch", "prisma_bringup", "teleop.launch.py",
                                                      "glove:=none"], logdir, NODES)
        return [launch], pids
    procs = {"motor_driver": start("relay_motor", relay_command("ros_relay.py", "motor"), logdir),
             "teleop": start("relay_teleop", relay_command("teleop_relay.py", "teleop"), logdir),
             "manipulation": start("relay_manipulation", relay_command("teleop_relay.py", "manipulation"), logdir)}
    return list(procs.values()), {node: p.popen.pid for node, p in procs.items()}


def _wait_for(log: Path, text: str, timeout_s: float, procs: list[Proc]) -> None:
    deadline = time.monotonic() + timeout_s
    while text.encode() not in log.read_bytes():
        check_alive(procs)
        if time.monotonic() > deadline:
            raise RuntimeError(f"'{text}' not in {log} after {timeout_s:.0f} s")
        time.sleep(0.2)


def run(kind: str, out: Path, settle_s: float = 3.0, cpu_s: float = 12.0) -> dict:
    """One graph driven by the step glove: the teleop node's CPU, then STEPS steps recorded."""
    control = shared_control()
    logdir = out / f"teleop_{kind}_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    result: dict = {"kind": kind, "machine_before": wait_quiet(None, 0.0)}
    procs, pids = _start_graph(kind, logdir)
    glove = probe = None
    try:
        control.wait_publishers(["/joint_states"], 90.0, procs)
        glove = start("glove", relay_command("teleop_relay.py", "glove", "--step-s", str(STEP_S)), logdir)
        control.wait_publishers([TARGETS], 60.0, procs + [glove])
        if kind == "real":  # the teleop node's goal runs once the targets flow
            _wait_for(procs[0].log, "teleop goal started", 90.0, procs)
        time.sleep(settle_s)
        result["cpu"] = measure_cpu(pids, cpu_s)
        probe = start_probe([MOVE_STATUS, MOVE_FEEDBACK, TARGETS], logdir / "probe", logdir, control)
        t_lo = time.time_ns()
        time.sleep(STEPS * STEP_S)
        t_hi = time.time_ns()
        stop([probe])
        rec = read_probe(logdir / "probe")
        check_alive(procs)
    finally:
        stop(([probe] if probe else []) + ([glove] if glove else []) + procs)
    steps = [(int(stamp), float(level)) for line in glove.log.read_text().splitlines()
             if line.startswith("step ") for _, stamp, level in [line.split()] if t_lo <= int(stamp) <= t_hi]
    ms, counts = (_step_latency(rec, steps) if kind == "real" else _relay_latency(rec, t_lo, t_hi))
    result["latency"] = percentiles(ms) | counts
    result["targets_hz"] = round(len(rec.stamps.get(TARGETS, [])) / ((t_hi - t_lo) / 1e9), 1)
    return result


def _step_latency(rec: Recording, steps: list[tuple[int, float]]) -> tuple[np.ndarray, dict]:
    """Per glove step: the first MoveMotors goal accepted after it whose feedback moves the fingers
    motor the step's way (closing to a level > 0, else opening), acceptance - the step's stamp."""
    goals = sorted(rec.goals.items(), key=lambda kv: kv[1])
    out, missed = [], 0
    for i, (stamp, level) in enumerate(steps):
        until = steps[i + 1][0] if i + 1 < len(steps) else math.inf
        way = 1.0 if level > 0 else -1.0
        hit = next((accept for gid, accept in goals if stamp <= accept < until
                    and any(way * fb.velocities[0] > MOVING_RAD_S for fb in rec.feedback.get(gid, []))), None)
        if hit is None:
            missed += 1
        else:
            out.append((hit - stamp) / 1e6)
    return np.array(out), {"steps": len(steps), "steps_without_goal": missed}


def _relay_latency(rec: Recording, t_lo: int, t_hi: int) -> tuple[np.ndarray, dict]:
    """Per goal: acceptance - the stamp of the target that triggered it (in its feedback positions)."""
    out = []
    for gid, accept in rec.goals.items():
        fbs = rec.feedback.get(gid)
        if fbs and len(fbs[0].positions) >= 2:
            trigger = int(fbs[0].positions[0]) * 1_000_000_000 + int(fbs[0].positions[1])
            if t_lo <= trigger <= t_hi:
                out.append((accept - trigger) / 1e6)
    return np.array(out), {"steps": len(out)}


@functools.cache
def _runs() -> dict:
    return {kind: run(kind, _out()) for kind in ("real", "relay")}


def _latency(bench: Benchmark) -> float:
    lat = {kind: r["latency"] for kind, r in _runs().items()}
    for key in ("p50_ms", "p99_ms", "max_ms", "n"):
        bench.notes[f"{key} (relay)"] = f"{lat['real'].get(key)} ({lat['relay'].get(key)})"
    bench.notes["real steps without a goal"] = lat["real"].get("steps_without_goal")
    runs = _runs()
    bench.notes["targets Hz at the probe (relay)"] = f"{runs['real']['targets_hz']} ({runs['relay']['targets_hz']})"
    if not lat["real"].get("n") or not lat["relay"].get("n"):
        bench.notes["no ratio"] = "no step reached the motors in one of the runs"
        return math.nan
    return lat["relay"]["p99_ms"] / lat["real"]["p99_ms"]


def _cpu(bench: Benchmark) -> float:
    cpu = {kind: r["cpu"]["processes"] for kind, r in _runs().items()}
    for node in NODES:
        bench.notes[f"{node} % (relay %)"] = f"{cpu['real'][node]['cpu_pct']} ({cpu['relay'][node]['cpu_pct']})"
    bench.notes["machine: others % (real, relay)"] = (f"{_runs()['real']['cpu']['others_pct']}, "
                                                     f"{_runs()['relay']['cpu']['others_pct']}")
    return cpu["relay"]["teleop"]["cpu_pct"] / cpu["real"]["teleop"]["cpu_pct"]


LATENCY = Benchmark("teleop_latency_p99", lambda: measured_with_ros(LATENCY.notes, _out, lambda: _latency(LATENCY)),
                    "relay/graph", 0.5)
CPU = Benchmark("teleop_cpu_vs_relay", lambda: measured_with_ros(CPU.notes, _out, lambda: _cpu(CPU)),
                "relay/node", 1 / 1.5)
BENCHMARKS = [LATENCY, CPU]
