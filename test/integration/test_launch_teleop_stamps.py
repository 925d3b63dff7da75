"""launch_testing: `teleop.launch.py glove:=none` (hand-pose input, the sim hand with the pinch ball,
the teleop node engaged at start), the test wearing the glove (test/support/prisma_testing/
operator_glove.py, 60 Hz) and holding a fist, first with every sample stamped 0 (as `ros2 topic pub`
sends it without `header: auto`) for 5 s, then stamped 5 s before it is published for 5 s:

- over those 10 s at most 2 Teleoperate goals are sent (the teleop node's log) and no motor moves more
  than 0.02 rad from where it stood (every /joint_states);
- the refusal is on /diagnostics (status `teleop`: `input refused: /glove/joint_states stamped 0: ...`,
  then `... stamped 5.0x s before it arrived ...`) and in the teleop node's log at most twice;
- then stamped when taken: the same session closes the hand on the ball (fingers past 3 rad, where
  the index first touches it), and the log says the glove is accepted again.
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import time
import unittest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test
from prisma_testing.operator_glove import FIST, OperatorGlove, WearingTheGlove
from prisma_testing.ros_harness import joint, require_ros, stamp_ns

require_ros()

import launch_testing  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.diagnostics import diagnostics_from_msg  # noqa: E402
from prisma_common.hand import MOTOR_NAMES  # noqa: E402

PHASE_S = 5.0  # each bad stamping, 10 s in all
MAX_GOALS = 2
MAX_MOVE_RAD = 0.02
REFUSED = "/glove/joint_states stamped"


generate_test_description = launch_test("teleop.launch.py", glove="none", engage="true")


class TestTeleopStamps(WearingTheGlove, GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        cls.glove = OperatorGlove()

    def teleop_status(self, since_ns: int) -> list[str]:
        """The messages of the teleop node's /diagnostics statuses stamped from `since_ns` on."""
        return [s.message for m in self.diagnostics if stamp_ns(m) >= since_ns
                for s in diagnostics_from_msg(m) if s.name == "teleop"]

    def test_a_glove_stamped_0_or_5_s_old_moves_nothing_then_stamped_it_closes_the_hand(self):
        ros, glove = self.ros, self.glove
        # the teleop node up (its first status) and the hand's stream flowing before the glove starts
        self.assertTrue(ros.spin_until(lambda: bool(self.teleop_status(0)), 90.0), "no teleop status")
        start = self.positions()
        sent_before = len(ros.logs(name="teleop", contains="sending Teleoperate"))
        glove.stamp(None)
        glove.move(FIST, 0.5)
        zero_ns = time.time_ns()
        self.assertTrue(ros.spin_until(
            lambda: any(m.startswith(f"input refused: {REFUSED} 0") for m in self.teleop_status(zero_ns)), 10.0),
            self.teleop_status(zero_ns))
        ros.spin_for(max(0.0, PHASE_S - (time.time_ns() - zero_ns) * 1e-9))
        glove.stamp(5.0)
        old_ns = time.time_ns()
        self.assertTrue(ros.spin_until(
            lambda: any(m.startswith(f"input refused: {REFUSED} 5.") for m in self.teleop_status(old_ns)), 10.0),
            self.teleop_status(old_ns))
        ros.spin_for(max(0.0, PHASE_S - (time.time_ns() - old_ns) * 1e-9))
        end_ns = time.time_ns()
        ros.message_stamped(self.joints, end_ns, 30.0)  # every /joint_states of the 10 s, however late it came
        during = [m for m in self.joints if zero_ns <= stamp_ns(m) <= end_ns]
        moved = {m: max(abs(joint(js, m) - start[m]) for js in during) for m in MOTOR_NAMES}
        sent = len(ros.logs(name="teleop", contains="sending Teleoperate")) - sent_before
        refused_lines = ros.logs(name="teleop", contains=REFUSED)
        print(f"10 s of a fist stamped 0, then 5 s old: {sent} Teleoperate goals sent, the motors moved at most "
              f"{ {m: round(v, 4) for m, v in moved.items()} } rad over {len(during)} /joint_states; "
              f"logged: {refused_lines}")
        self.assertLessEqual(sent, MAX_GOALS)
        self.assertGreater(len(during), 500)  # 100 Hz for 10 s: the whole window was seen
        for m, v in moved.items():
            self.assertLessEqual(v, MAX_MOVE_RAD, m)
        self.assertLessEqual(len(refused_lines), 2)
        self.assertTrue(refused_lines[0].startswith(f"{REFUSED} 0: publish header.stamp (ros2 topic pub: header: "
                                                    "auto)"), refused_lines)
        # stamped when taken: the same session follows the operator's fist onto the ball
        glove.stamp(0.0)
        self.assertTrue(ros.spin_until(lambda: self.positions()["fingers"] > 3.0, 30.0), self.positions())
        self.assertTrue(ros.wait_for_log(name="teleop", contains="/glove/joint_states accepted again"))
        glove.stop()


@launch_testing.post_shutdown_test()
class TestTeleopStampsShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
