"""launch_testing, issue acceptance on the launched graph (`hand.launch.py sim:=true`) over DDS:
`kill -9` of `manipulation` mid-Grasp stops every motor within 0.5 s.

The manipulation node sends its MoveMotors velocity goals with a 0.3 s timeout and re-sends them
every 0.1 s while the command holds; once it is gone the motor driver's goal times out and the
driver stops the motors by itself (docs/safety.md).

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os
import signal
import time

from prisma_testing.launch_case import GraphTestCase, launch_test
from prisma_testing.ros_harness import SIM_STOPPED_RAD_S, closing_at_10_rpm, require_ros, stamp_ns, stopped

require_ros()

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from prisma_msgs.action import Grasp  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

# the sim motors' velocity loop decays exponentially (tau 10 ms): "0" is below this, in rad/s
KILL_STOP_LIMIT_S = 0.5


generate_test_description = launch_test("hand.launch.py", sim="true")


class TestControllerLost(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.wrenches = ros.collect(WrenchStamped, "/prisma/index/wrench")
        cls.grasp = ros.action_client(Grasp, "/prisma/grasp", wait_sec=60.0)

    def test_kill_manipulation_mid_grasp_stops_the_motors(self, proc_info):
        """Measured from the kill instant (wall clock, read just before the signal; the nodes stamp
        with the same clock) to the header stamp of the first /joint_states stamped after it whose
        every velocity is 0 (below 1e-3 rad/s); no velocity is nonzero after it. The grasp is sent
        again only while refused not_ready: one that ends any other way before the kill fails."""
        ros, joints = self.ros, self.joints
        ros.wait_until_keeping_up(joints, self.wrenches, lag_sec=0.08, checks=10, timeout_sec=90.0)

        # a slow grasp to a force the ball never reaches: the fingers close at 10 rpm for seconds
        goal = Grasp.Goal(grasp="pinch", finger_force=3.0, thumb_force=3.0, speed_rpm=10.0)
        result = ros.send_until_started(self.grasp, goal, timeout_sec=60.0).get_result_async()
        accepted = len(joints)
        ros.spin_until(lambda: result.done() or closing_at_10_rpm(joints[accepted:]), 10.0)
        self.assertFalse(result.done(), f"the grasp ended before the kill: {result.result()}")
        self.assertTrue(closing_at_10_rpm(joints[accepted:]))

        pid = proc_info["manipulation"].pid
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            self.assertIn(b"__node:=manipulation", f.read())
        received_before = len(joints)
        expired = "MoveMotors goal ended: timeout"
        expiries_before = len(ros.logs(name="motor_driver", contains=expired))
        kill_ns = time.time_ns()
        os.kill(pid, signal.SIGKILL)
        proc_info.assertWaitForShutdown(process="manipulation", timeout=10)

        ros.message_stamped(joints, kill_ns + 1_500_000_000, 30.0)  # 1.5 s of them, however late they come
        after = [m for m in joints[received_before:] if stamp_ns(m) > kill_ns]
        self.assertTrue(after, "no /joint_states after the kill")
        self.assertFalse(stopped(after[0], SIM_STOPPED_RAD_S), "the motors were not moving at the kill")
        first_stop = next((i for i, m in enumerate(after) if stopped(m, SIM_STOPPED_RAD_S)), None)
        self.assertIsNotNone(first_stop, f"still moving 1.5 s after the kill: {list(after[-1].velocity)}")
        stop_s = (stamp_ns(after[first_stop]) - kill_ns) * 1e-9
        print(f"kill -9 manipulation mid-grasp: every velocity 0 {stop_s * 1e3:.0f} ms after the kill")
        self.assertLess(stop_s, KILL_STOP_LIMIT_S)
        self.assertEqual([list(m.velocity) for m in after[first_stop:] if not stopped(m, SIM_STOPPED_RAD_S)], [])
        # the motor driver stopped them itself: the goal that was no longer refreshed timed out
        self.assertTrue(ros.spin_until(lambda: len(ros.logs(name="motor_driver", contains=expired)) > expiries_before,
                                       5.0), f"motor_driver logged: {ros.logs(name='motor_driver')[-5:]}")
        self.assertFalse(result.done())  # the client never hears back: its server is gone
