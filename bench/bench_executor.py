"""The nodes' executor (prisma_node_wiring.executor.SingleWaitExecutor) beside rclpy's
SingleThreadedExecutor, on the same node (python bench/run.py --only executor_cpu).

Needs ROS 2 Jazzy and this workspace's install/ sourced; without them the entry prints
`skipped: needs ROS 2 (...)` and the value nan. The streams: ros_relay.py's sensor, force and motor
roles (five TaxelArray and five WrenchStamped topics at 100 Hz, /joint_states at 100 Hz); the node
measured: its manipulation role with the real node's idle entities (`--like-node`: two action
servers, a 50 Hz timer) and no goals, spun by one executor, then by the other, each over CPU_S once
past its start. Everything at the default priority, so run it on a quiet machine.

executor_cpu: the node's CPU on rclpy's executor / on the nodes' own ("higher is better"): how much
  less CPU the same callbacks take without the second wait per callback. Needed 1 (no worse).
"""
from __future__ import annotations

import functools
import tempfile
import time
from pathlib import Path

from graph_bench.control import measured_with_ros, shared_control
from graph_bench.cpu import measure_cpu, wait_quiet
from graph_bench.processes import relay_command, start, stop
from prisma_common.hand import FINGERS
from run import Benchmark

STREAMS = [f"/prisma/{f}/{kind}" for f in FINGERS for kind in ("taxels", "wrench")] + ["/joint_states"]
EXECUTORS = ("rclpy", "single_wait")
WARM_S = 5.0
CPU_S = 20.0


@functools.cache
def _out() -> Path:
    return Path(tempfile.mkdtemp(prefix="prisma_executor_bench_"))


@functools.cache
def _runs() -> dict:
    """The streams' relays, then the measured node on each executor in turn: its CPU over CPU_S."""
    control = shared_control()
    logdir = _out() / f"executor_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    results: dict = {"machine_before": wait_quiet(None, 0.0)}
    relays = [start("relay_sensor", relay_command("ros_relay.py", "sensor", "--rate-hz", "100"), logdir),
              start("relay_force", relay_command("ros_relay.py", "force"), logdir),
              start("relay_motor", relay_command("ros_relay.py", "motor"), logdir)]
    try:
        control.wait_publishers(STREAMS, 60.0, relays)
        for executor in EXECUTORS:
            node = start(f"manipulation_{executor}",
                         relay_command("ros_relay.py", "manipulation", "--like-node", "--goal-every", "0",
                                       "--executor", executor), logdir)
            try:
                time.sleep(WARM_S)  # past the start: imports, discovery
                results[executor] = measure_cpu({"node": node.popen.pid}, CPU_S)
            finally:
                stop([node])
    finally:
        stop(relays)
    return results


def _ratio(bench: Benchmark) -> float:
    runs = _runs()
    cpu = {executor: runs[executor]["processes"]["node"]["cpu_pct"] for executor in EXECUTORS}
    for executor, pct in cpu.items():
        bench.notes[f"{executor} executor: % of a core"] = pct
    bench.notes["logs"] = str(_out())
    return cpu["rclpy"] / cpu["single_wait"]


EXECUTOR_CPU = Benchmark("executor_cpu",
                         lambda: measured_with_ros(EXECUTOR_CPU.notes, _out, lambda: _ratio(EXECUTOR_CPU)),
                         "rclpy/single_wait", 1.0)
BENCHMARKS = [EXECUTOR_CPU]
