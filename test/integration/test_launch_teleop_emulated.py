"""launch_testing: `teleop.launch.py hardware:=emulated glove:=none`: teleoperation over the drivers'
hardware paths (prisma-hand-emulator's servos through dynamixel-sdk, its fingertip hub through
pyserial; the servos homed at start), the test wearing the glove (test/support/prisma_testing/operator_glove.py):

1. the operator closes to a fist: the hand closes on the ball and stops there, no pad's estimated
   force more than 0.15 N above max_pad_force (2 N), thumb and index at the limit; the operator
   opens: the hand opens.
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os
import tempfile
import time
import unittest
from pathlib import Path

from prisma_testing.emulated_launch import wait_until_homed
from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test, touch_limited_peaks
from prisma_testing.operator_glove import FIST, OPEN, OperatorGlove, WearingTheGlove
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.msg import HandWrench  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import MOTOR_NAMES  # noqa: E402

# the same path in both imports of this module (launch_testing imports it twice)
EMULATOR_DIR = Path(tempfile.gettempdir()) / f"prisma_teleop_emulated_{os.getpid()}"


# the emulator makes its folder (and removes it when it stops)
generate_test_description = launch_test("teleop.launch.py", hardware="emulated", glove="none",
                                        emulator_dir=str(EMULATOR_DIR))


class TestTeleopEmulated(WearingTheGlove, GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        cls.wrenches = ros.collect(HandWrench, "/prisma/hand/wrench")  # the five pads in one stream
        cls.glove = OperatorGlove()

    def test_1_the_operator_closes_on_the_ball_and_opens(self):
        ros, glove = self.ros, self.glove
        wait_until_homed(ros, self.diagnostics, MOTOR_NAMES)
        ros.wait_until_keeping_up(self.joints, self.wrenches, lag_sec=0.05, checks=10, timeout_sec=90.0)
        glove.move(OPEN)
        self.assertTrue(ros.wait_for_log(name="manipulation", contains="teleop goal started", timeout_sec=60.0))
        closing_ns = time.time_ns()
        glove.move(FIST, 1.5)
        ros.spin_for(6.0)  # closes at up to 40 rpm (4.2 rad/s) onto the ball, then holds
        held = self.positions()
        print(f"emulated: the hand stopped at { {m: round(v, 3) for m, v in held.items()} }")
        touch_limited_peaks(self.wrenches, closing_ns)
        self.assertTrue(3.0 < held["fingers"] < 8.5, held)  # on the ball, short of the operator's fist
        glove.move(OPEN, 1.5)
        opened = self.assert_reaches(dict.fromkeys(MOTOR_NAMES, 0.0), 0.05, timeout_sec=15.0)
        print(f"emulated: opened to { {m: round(v, 3) for m, v in opened.items()} }")
        glove.stop()


@launch_testing.post_shutdown_test()
class TestTeleopEmulatedShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
