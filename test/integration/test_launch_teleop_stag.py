"""launch_testing: `teleop.launch.py input:=stag glove_backend:=replay` with the STAG pose session
(prisma-teleop-stag-session: empty, pinch, empty, power, empty, lateral, empty, 15 s, looped by
glove_driver) through glove_driver and glove_perception, the sim hand with the pinch ball:

1. the session's held poses start the mapped goals on the manipulation node, in the session's order
   (its log): Grasp pinch, the open GripperCommand, Grasp power, open, Grasp lateral, taken from the
   first pass whose pinch ran for at least half the session's pinch pose (the replay is already running
   when the teleop node engages: a pose it sees only the end of, or one the hand was not ready for,
   starts no grasp, so no grasp is cancelled by the next pose within a second of its start); the
   pinch grasp runs (the fingers close past 3 rad, where the index first touches the ball; a lateral fist earlier
   in the replay may have pushed the sim ball off its place, so whether it ends force_reached or at
   the joint limit is printed, not asserted), and the power pose, pressed harder than the pinch, asks
   for more force.
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import re
import shutil
import tempfile
import unittest
from pathlib import Path

import pytest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, graph_under_test, include_launch
from prisma_testing.ros_harness import joint, require_ros, stamp_ns

require_ros()

import launch_testing  # noqa: E402
from rcl_interfaces.msg import Log  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_teleop.stag_session import SESSION, write_session  # noqa: E402
from stag_glove.node_config import GloveDriverConfig  # noqa: E402

SESSION_DIR = Path(tempfile.mkdtemp(prefix="prisma_stag_session_"))
SESSION_FILE = SESSION_DIR / "poses.h5"
EXPECTED = ["pinch", "open", "power", "open", "lateral"]
# a pinch the teleop node saw whole runs for most of the pose's frames; one it saw only the end of, far less
WHOLE_PINCH_NS = int(0.5 * dict(SESSION)["pinch"] / GloveDriverConfig().frame_rate_hz * 1e9)
STARTED = re.compile(r"^(grasp|gripper) goal started: (?:GraspRequest\(grasp='(\w+)', finger_force=([\d.]+)|"
                     r"GripperRequest\(position=0\.0)")


@pytest.mark.launch_test
def generate_test_description():
    write_session(SESSION_FILE, seed=0)
    return graph_under_test(include_launch("teleop.launch.py", input="stag", glove_backend="replay",
                                           replay_file=str(SESSION_FILE)))


def started_goals(logs: list) -> list[tuple[str, float | None, int]]:
    """(pinch | power | lateral | open, the grasp's finger force, when it started in ns) of each goal the
    manipulation node started, from its /rosout messages."""
    out = []
    for entry in logs:
        m = STARTED.match(entry.msg) if entry.name.endswith("manipulation") else None
        if m:
            force = float(m.group(3)) if m.group(1) == "grasp" else None
            out.append((m.group(2) if m.group(1) == "grasp" else "open", force,
                        entry.stamp.sec * 1_000_000_000 + entry.stamp.nanosec))
    return out


def find_in_order(goals: list[tuple[str, float | None, int]], wanted: list[str]) -> list[int] | None:
    """The indices of the first run of `wanted`, in a row, among `goals`, whose first goal ran for at
    least WHOLE_PINCH_NS before the next one started."""
    names = [g[0] for g in goals]
    for i in range(len(names) - len(wanted) + 1):
        if names[i:i + len(wanted)] == wanted and goals[i + 1][2] - goals[i][2] >= WHOLE_PINCH_NS:
            return list(range(i, i + len(wanted)))
    return None


class TestTeleopStag(GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.joints = ros.collect(JointState, "/joint_states")
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        cls.rosout = ros.collect(Log, "/rosout", qos)  # with their stamps

    @classmethod
    def tearDownClass(cls) -> None:
        shutil.rmtree(SESSION_DIR, ignore_errors=True)
        super().tearDownClass()

    def goals(self) -> list[tuple[str, float | None, int]]:
        return started_goals(self.rosout)

    def test_1_the_sessions_poses_start_the_mapped_grasps(self):
        ros = self.ros
        # the graph comes up during the first pass (goals refused not_ready are sent again); the replay loops
        found = ros.spin_until(lambda: find_in_order(self.goals(), EXPECTED) is not None, 150.0)
        goals = self.goals()
        t0 = goals[0][2] if goals else 0
        print(f"goals started (name, finger force, s): {[(g[0], g[1], round((g[2] - t0) * 1e-9, 2)) for g in goals]}")
        print(f"teleop: {ros.logs(name='teleop', contains='held')[:8]}")
        self.assertTrue(found, goals)
        index = find_in_order(goals, EXPECTED)
        pinch, opened, power, _, _ = (goals[i] for i in index)
        self.assertGreater(power[1], pinch[1])  # the power pose presses harder: a firmer grasp
        pinch_ns, open_ns = pinch[2], opened[2]
        during = [joint(m, "fingers") for m in self.joints if pinch_ns - 0.5e9 <= stamp_ns(m) <= open_ns]
        print(f"fingers during the pinch: up to {max(during):.2f} rad")
        ends = [line for line in ros.logs(name="manipulation", contains="goal ended")]
        print(f"the goals' ends: {ends[-8:]}")
        # no grasp started from a pose's end and cut short by the next pose (it was cancelled 0.4 s after its start)
        self.assertEqual(self.cut_short(), [])
        self.assertGreater(max(during), 3.0)  # the pinch closed the fingers (first touch at 3 rad)

    def cut_short(self) -> list[float]:
        """How long each grasp goal the manipulation node cancelled within 1 s of its start ran (s)."""
        started_ns, short = None, []
        for entry in self.rosout:
            if not entry.name.endswith("manipulation"):
                continue
            t = entry.stamp.sec * 1_000_000_000 + entry.stamp.nanosec
            if entry.msg.startswith("grasp goal started"):
                started_ns = t
            elif entry.msg == "grasp goal ended: canceled" and started_ns is not None and t - started_ns < 1e9:
                short.append(round((t - started_ns) * 1e-9, 2))
        return short


@launch_testing.post_shutdown_test()
class TestTeleopStagShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
