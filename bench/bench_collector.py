"""A launch test's collections apart (prisma_testing.collector) beside the same collections in the
test's own process (python bench/run.py --only collector_...).

Needs ROS 2 Jazzy and this workspace's install/ sourced; without them every entry prints
`skipped: needs ROS 2 (...)` and the value nan. The streams: ros_relay.py's sensor role (five
TaxelArray topics at 100 Hz) and motor role (/joint_states at 100 Hz), 600 messages a second, about
what test_launch_teleop_goal took. The holder (this file run as `hold`) is a test's process: a
RosHarness collecting the six topics and looking at each collection's length every 0.1 s, as a wait
does; `in_process` takes them in its own executor, `apart` through the collector process. Both run at
the default priority on a quiet machine, the collector at its own rung. Ratios are "higher is better":

collector_test_process_cpu: the in-process holder's CPU / the apart holder's: how much less CPU the
  test's own process needs, which is what a busy machine leaves it. Needed 5.
collector_total_cpu: the in-process holder's CPU / the apart holder's and the collector's together:
  the price of the second process. Needed 1 / 1.5 (at most 1.5x the CPU in all).
"""
from __future__ import annotations

import argparse
import functools
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from graph_bench.control import measured_with_ros, shared_control
from graph_bench.cpu import measure_cpu, wait_quiet
from graph_bench.processes import relay_command, start, stop
from prisma_common.hand import FINGERS
from run import Benchmark

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "support"))  # prisma_testing: not installed

TOPICS = [(f"/prisma/{f}/taxels", "TaxelArray") for f in FINGERS] + [("/joint_states", "JointState")]
HOLD_S = 40.0
CPU_S = 20.0


@functools.cache
def _out() -> Path:
    return Path(tempfile.mkdtemp(prefix="prisma_collector_bench_"))


def hold(mode: str, seconds: float) -> None:
    """The test's side: collect TOPICS (`apart` or `in_process`), look every 0.1 s for `seconds`;
    prints `ready <pid> <collector pid or 0>` once collecting and `counts <n> ...` at the end."""
    from prisma_msgs.msg import TaxelArray
    from sensor_msgs.msg import JointState

    from prisma_testing.ros_harness import RosHarness

    types = {"TaxelArray": TaxelArray, "JointState": JointState}
    ros = RosHarness(collect_apart=mode == "apart")
    try:
        collections = [ros.collect(types[name], topic) for topic, name in TOPICS]
        collector = ros._collector.proc.pid if ros._collector is not None else 0
        print(f"ready {os.getpid()} {collector}", flush=True)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            ros.spin_for(0.1)
            _ = [len(c) for c in collections]
        print("counts " + " ".join(str(len(c)) for c in collections), flush=True)
    finally:
        ros.shutdown()


def run(mode: str, out: Path) -> dict:
    """The relays, then one holder in `mode`: its CPU (and its collector's) over CPU_S."""
    control = shared_control()
    logdir = out / f"collector_{mode}_{time.strftime('%H%M%S')}"
    logdir.mkdir(parents=True, exist_ok=True)
    result: dict = {"mode": mode, "machine_before": wait_quiet(None, 0.0)}
    relays = [start("relay_sensor", relay_command("ros_relay.py", "sensor", "--rate-hz", "100"), logdir),
              start("relay_motor", relay_command("ros_relay.py", "motor"), logdir)]
    holder: subprocess.Popen | None = None
    try:
        control.wait_publishers([topic for topic, _ in TOPICS], 60.0, relays)
        holder = subprocess.Popen([sys.executable, __file__, "hold", mode, "--seconds", str(HOLD_S)],
                                  stdout=subprocess.PIPE, text=True, start_new_session=True)
        _, pid, collector = holder.stdout.readline().split()
        pids = {"holder": int(pid)} | ({"collector": int(collector)} if int(collector) else {})
        time.sleep(5.0)  # past the start: imports, discovery
        result["cpu"] = measure_cpu(pids, CPU_S)
        result["counts"] = [int(n) for n in holder.stdout.read().split()[1:]]
        holder.wait(timeout=60)
    finally:
        if holder is not None and holder.poll() is None:
            holder.kill()
        stop(relays)
    return result


@functools.cache
def _runs() -> dict:
    return {mode: run(mode, _out()) for mode in ("in_process", "apart")}


def _cpu_of(mode: str, names: tuple[str, ...]) -> float:
    processes = _runs()[mode]["cpu"]["processes"]
    return sum(processes[n]["cpu_pct"] for n in names if n in processes)


def _notes(bench: Benchmark) -> None:
    runs = _runs()
    for mode, r in runs.items():
        for name, p in r["cpu"]["processes"].items():
            bench.notes[f"{mode} {name} % of a core ({p['rung']})"] = p["cpu_pct"]
        bench.notes[f"{mode} messages collected"] = sum(r["counts"])


def _test_process(bench: Benchmark) -> float:
    _notes(bench)
    apart = _cpu_of("apart", ("holder",))
    return _cpu_of("in_process", ("holder",)) / apart if apart > 0 else math.inf


def _total(bench: Benchmark) -> float:
    _notes(bench)
    return _cpu_of("in_process", ("holder",)) / _cpu_of("apart", ("holder", "collector"))


TEST_PROCESS = Benchmark("collector_test_process_cpu",
                         lambda: measured_with_ros(TEST_PROCESS.notes, _out, lambda: _test_process(TEST_PROCESS)),
                         "x less CPU", 5.0)
TOTAL = Benchmark("collector_total_cpu", lambda: measured_with_ros(TOTAL.notes, _out, lambda: _total(TOTAL)),
                  "in-process/apart", 1 / 1.5)
BENCHMARKS = [TEST_PROCESS, TOTAL]

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="the test's side of bench_collector (started by it)")
    parser.add_argument("hold", choices=["hold"])
    parser.add_argument("mode", choices=["in_process", "apart"])
    parser.add_argument("--seconds", type=float, default=HOLD_S)
    arguments = parser.parse_args()
    hold(arguments.mode, arguments.seconds)
