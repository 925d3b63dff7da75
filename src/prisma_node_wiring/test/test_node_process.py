"""run_node: a node is built at the niceness and takes its real-time rung once built (every thread);
it spins on the executor PRISMA_EXECUTOR and the running rclpy allow, said in one log line, and a
PRISMA_EXECUTOR naming no executor stops it before it starts; settle_garbage_collector: what a node
holds from its start is left out of later collections.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys
import time

import pytest

from prisma_testing.ros_harness import require_ros

require_ros()

from prisma_node_wiring.executor_choice import PROVEN_RCLPY_VERSIONS, rclpy_version  # noqa: E402
from prisma_node_wiring.node_process import settle_garbage_collector  # noqa: E402


def test_objects_alive_at_start_are_frozen_and_new_ones_still_collected():
    gc.unfreeze()
    try:
        kept = [[i] for i in range(10_000)]  # what a node builds at start and keeps
        settle_garbage_collector()
        assert gc.get_freeze_count() >= len(kept)
        cycle: list = []
        cycle.append(cycle)  # garbage made after the start: still the collector's
        del cycle
        assert gc.collect() >= 1
    finally:
        gc.unfreeze()


NODE = """
import os, rclpy
from rclpy.node import Node
from prisma_node_wiring.node_process import run_node

def policy():
    return os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0)

def make_node():
    node = Node("rung_probe")
    print("building", *policy(), flush=True)  # where a model would load

    def built():
        threads = sorted(int(t) for t in os.listdir("/proc/self/task"))
        print("built", *sorted({os.sched_getscheduler(t) for t in threads}), len(threads) > 1, flush=True)
        rclpy.shutdown()
    node.create_timer(0.05, built)
    return node

run_node(make_node, "rung_probe", ())
"""


@pytest.mark.skipif(os.geteuid() != 0, reason="real-time scheduling needs root (or an rtprio limit) to be granted")
def test_a_node_is_built_at_its_niceness_and_runs_on_the_real_time_rung():
    env = {**os.environ, "PRISMA_RT_PRIORITY": "20", "PRISMA_NICE": "-5", "ROS_DOMAIN_ID": "231"}
    out = subprocess.run([sys.executable, "-c", NODE], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = [line for line in out.stdout.splitlines() if line.startswith(("building", "built"))]
    # built time-shared at nice -5; then every thread (DDS's, the executor's) at SCHED_FIFO
    assert lines == [f"building {os.SCHED_OTHER} -5", f"built {os.SCHED_FIFO} True"]
    assert "scheduling: real-time scheduling (SCHED_FIFO 20)" in out.stderr


QUIET_NODE = """
from rclpy.node import Node
from prisma_node_wiring.node_process import run_node

class Quiet(Node):
    def __init__(self):
        super().__init__("sigint_burst")
        print("built", flush=True)

run_node(Quiet, "sigint_burst", ())
"""


def test_ctrl_c_again_and_again_while_the_node_exits_still_ends_it_with_0():
    """A terminal's Ctrl-C reaches every process of a launch, and launch forwards one more: a node
    gets SIGINT twice or more, the later ones while it exits. One that lands as Python finalises
    (its handlers back at the default) used to kill the node by the signal (exit -2, `process has
    died` in the launch's log)."""
    env = {**os.environ, "ROS_DOMAIN_ID": "232"}
    node = subprocess.Popen([sys.executable, "-c", QUIET_NODE], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert node.stdout.readline().strip() == "built"
        deadline = time.monotonic() + 20.0
        while node.poll() is None and time.monotonic() < deadline:
            node.send_signal(signal.SIGINT)
            time.sleep(0.001)
        assert node.wait(timeout=5.0) == 0, node.stderr.read()
    finally:
        if node.poll() is None:
            node.kill()
            node.wait()


SPUN_NODE = """
import rclpy
from rclpy.node import Node
from prisma_node_wiring.node_process import run_node

def make_node():
    node = Node("executor_probe")
    node.create_timer(0.05, rclpy.shutdown)  # spun once: the executor runs its timers
    return node

run_node(make_node, "executor_probe", ())
"""


@pytest.mark.parametrize(("requested", "kind"), [
    ("stock", "stock, rclpy's SingleThreadedExecutor: PRISMA_EXECUTOR=stock"),
    ("", "fast, SingleWaitExecutor (prisma_node_wiring.executor): PRISMA_EXECUTOR=auto: rclpy "
         f"{rclpy_version()} is proven and the self-test passed"),
])
def test_a_node_process_says_once_which_executor_spins_it_and_why(requested, kind):
    if requested == "" and rclpy_version() not in PROVEN_RCLPY_VERSIONS:
        pytest.skip(f"the fast executor is not proven on rclpy {rclpy_version()}")
    env = {**os.environ, "PRISMA_EXECUTOR": requested}  # the test process's domain (conftest.py)
    out = subprocess.run([sys.executable, "-c", SPUN_NODE], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    logged = [line for line in out.stderr.splitlines() if "executor:" in line]
    assert len(logged) == 1 and logged[0].endswith(f"[prisma_executor]: executor: {kind}"), out.stderr


EXECUTOR_FROM_THREADS = """
import threading
import rclpy
from prisma_node_wiring.executor import process_executor

rclpy.init()
start = threading.Barrier(8)
made = []

def ask():
    start.wait()
    made.append(process_executor())

threads = [threading.Thread(target=ask) for _ in range(8)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
print(len(made), len({id(executor) for executor in made}))
rclpy.shutdown()
"""


def test_threads_asking_at_once_get_the_one_process_executor_said_once():
    # the node's main and a thread that waits for its executor (external_shutdown_command) ask at
    # once: each made and logged its own executor before, and the thread watched an empty one
    out = subprocess.run([sys.executable, "-c", EXECUTOR_FROM_THREADS], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["8", "1"], out.stdout
    assert len([line for line in out.stderr.splitlines() if "executor:" in line]) == 1, out.stderr


EXECUTOR_AFTER_SHUTDOWN = """
import rclpy
from rclpy.executors import ExternalShutdownException
from prisma_node_wiring.executor import process_executor

rclpy.init()
rclpy.get_default_context().handle.shutdown()  # rcl only, as rclpy's signal handler does
try:
    process_executor()
except ExternalShutdownException:
    print("stopped")
"""


def test_a_process_stopped_before_its_executor_is_made_stops_without_choosing_one():
    # a launch stopping whole while this node started: the self-test failed on the shut-down context
    # ("the fast executor's self-test failed"), the stock executor was made on it half-built and
    # rclpy printed its __del__'s traceback as the process ended
    for requested in ("", "stock"):
        env = {**os.environ, "PRISMA_EXECUTOR": requested}
        out = subprocess.run([sys.executable, "-c", EXECUTOR_AFTER_SHUTDOWN], env=env, capture_output=True,
                             text=True, timeout=60)
        assert (out.returncode, out.stdout) == (0, "stopped\n"), out.stderr
        assert "Traceback" not in out.stderr and "executor:" not in out.stderr, out.stderr


def test_a_prisma_executor_naming_no_executor_stops_the_node_with_one_line_naming_it():
    env = {**os.environ, "PRISMA_EXECUTOR": "single_wait"}
    out = subprocess.run([sys.executable, "-c", SPUN_NODE], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    assert out.stderr.strip().endswith("[executor_probe]: PRISMA_EXECUTOR='single_wait' is not an executor: set it "
                                       "to one of auto, fast, stock, events (or leave it unset for auto)"), out.stderr
