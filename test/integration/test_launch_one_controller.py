"""One controller per hand, between processes: a second `ros2 run prisma_manipulation manipulation`
beside a running one in the same namespace (docs/recording.md's replay nodes left running, then the hand
launched again) exits 1 with one fatal line naming the node already there and how to stop it, and
leaves the first serving alone; in another namespace (another hand) it starts.

In-process cases (the motor driver, a node of another name serving the same actions) and the
MoveMotors lease are in test_manip_nodes.py.
"""
from __future__ import annotations

import signal
import time

from prisma_testing.node_process import NodeProcess
from prisma_testing.repo_paths import BRINGUP
from prisma_testing.ros_harness import require_ros

require_ros()

CONFIG = BRINGUP / "config" / "manipulation.yaml"


def manipulation(*ros_args: str) -> NodeProcess:
    return NodeProcess(["ros2", "run", "prisma_manipulation", "manipulation", "--ros-args",
                        "--params-file", str(CONFIG), *ros_args])


def test_a_second_manipulation_node_in_the_same_namespace_exits_1_naming_the_first(ros):
    with manipulation() as first, manipulation("-r", "__ns:=/right") as other_hand:
        first.wait_until_spinning(ros, "/manipulation")
        started = time.monotonic()
        with manipulation() as second:
            result = second.wait(timeout_sec=60.0)
        refused_after = time.monotonic() - started
        assert result.returncode == 1, result.output
        fatal = [line for line in result.output.splitlines() if "[FATAL]" in line]
        stop = ("To restart it, stop it first (ctrl-C its launch, or `kill <pid>` of its process: `ps -ef | grep` "
                "its name; a `ros2 run` wrapper killed alone leaves its node running); a process killed with "
                "SIGKILL leaves the graph within 10 s")
        # found by its node's name, or, where DDS has announced the first node's action server before
        # its name (a busy machine), by the server
        assert len(fatal) == 1 and fatal[0].endswith((
            f"/manipulation is already running in this ROS domain: not starting a second one. {stop}",
            f"/manipulation would be a second server of it, not starting. {stop}")), result.output
        assert "Traceback" not in result.output
        print(f"second node refused {refused_after:.2f} s after its start (ros2 run and rclpy start-up included)")
        other_hand.wait_until_spinning(ros, "/right/manipulation")  # another hand's controller starts
        assert first.proc.poll() is None and other_hand.proc.poll() is None
        for proc in (first, other_hand):
            assert proc.interrupt(sig=signal.SIGINT).returncode == 0
