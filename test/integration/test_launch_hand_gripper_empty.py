"""launch_testing: `hand.launch.py sim:=true sim_object:=none`, an empty hand, driven as an arm
stack drives a gripper (the tests run in order, on one launch):

1. Manipulate horizontal with nothing in the hand: aborted at once, `no_contact: ...` in its result,
   nothing moves (it used to sweep the thumb to its joint limit and report success);
2. control_msgs/GripperCommand closed fully as MoveIt sends it (position 9 rad = the `fingers`
   joint's upper limit, max_effort 0 = the node's default force limit): SUCCEEDED reached_goal, the
   fingers at 9 rad and the thumb at its 7 rad end;
3. position 0: SUCCEEDED reached_goal, the hand open;
4. a cancel while the gripper closes: CANCELED, and every /joint_states stamped 0.5 s after the
   cancel request has every velocity 0 (below one Dynamixel velocity unit).
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import time
import unittest

from prisma_testing.goals import gripper_goal
from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test
from prisma_testing.ros_harness import joint, require_ros, stamp_ns, stopped

require_ros()

import launch_testing  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import GripperCommand  # noqa: E402
from prisma_msgs.action import Manipulate  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

CANCEL_STOP_S = 0.5


generate_test_description = launch_test("hand.launch.py", sim="true", sim_object="none")


class TestEmptyHandGripper(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.gripper = ros.action_client(GripperCommand, "/prisma/gripper_cmd", wait_sec=None)
        cls.manipulate = ros.action_client(Manipulate, "/prisma/manipulate", wait_sec=None)

    def run_gripper(self, goal):
        """The goal's result, sent again only while refused not_ready (send_until_started)."""
        return self.ros.result(self.ros.send_until_started(self.gripper, goal, timeout_sec=90.0), timeout_sec=30.0)

    def test_1_manipulate_with_nothing_in_the_hand_is_refused_no_contact(self):
        ros = self.ros
        # open already: the graph is up
        self.assertEqual(self.run_gripper(gripper_goal(0.0)).status, GoalStatus.STATUS_SUCCEEDED)
        before = len(self.joints)
        handle = ros.send_until_started(self.manipulate, Manipulate.Goal(motion="horizontal"), timeout_sec=60.0)
        outcome = ros.result(handle, timeout_sec=10.0)
        print(f"Manipulate horizontal, empty hand: {outcome.result.stop_reason}")
        self.assertEqual(outcome.status, GoalStatus.STATUS_ABORTED)
        self.assertTrue(outcome.result.stop_reason.startswith("no_contact: the thumb pad is not in contact"),
                        outcome.result.stop_reason)
        ros.message_at(self.joints, 0.3, timeout_sec=30.0)  # however late this process takes them
        self.assertTrue(all(stopped(m) for m in self.joints[before:]))  # nothing moved

    def test_2_gripper_closes_fully_on_nothing(self):
        outcome = self.run_gripper(gripper_goal(9.0))
        r = outcome.result
        print(f"close to 9 rad: status {outcome.status}, position {r.position:.3f} rad, effort {r.effort:.3f} N")
        self.assertEqual((outcome.status, r.reached_goal, r.stalled), (GoalStatus.STATUS_SUCCEEDED, True, False))
        self.assertGreater(r.position, 8.85)
        self.assertLess(r.effort, 0.2)  # the estimator's reading of untouched pads
        last = self.ros.message_at(self.joints, 0.3)  # published 0.3 s on, however late it comes here
        self.assertAlmostEqual(joint(last, "fingers"), 9.0, delta=0.05)
        self.assertAlmostEqual(joint(last, "thumb_flexion"), 7.0, delta=0.05)

    def test_3_position_0_opens(self):
        outcome = self.run_gripper(gripper_goal(0.0))
        self.assertEqual((outcome.status, outcome.result.reached_goal), (GoalStatus.STATUS_SUCCEEDED, True))
        self.assertAlmostEqual(joint(self.ros.message_at(self.joints, 0.3), "fingers"), 0.0, delta=0.1)

    def test_4_cancel_while_closing_stops_the_motors_within_half_a_second(self):
        """Rule: cancel_ns = the wall clock when the cancel request was sent (the nodes stamp
        /joint_states with the same system clock); every /joint_states stamped after cancel_ns +
        0.5 s has every velocity 0, and there are such messages."""
        ros = self.ros
        handle = ros.send_until_started(self.gripper, gripper_goal(9.0), timeout_sec=60.0)
        result = handle.get_result_async()
        started = len(self.joints)

        def closing() -> bool:
            return any(joint(m, "fingers", "velocity") > 5.0 for m in self.joints[started:])

        ros.spin_until(lambda: result.done() or closing(), 10.0)
        self.assertFalse(result.done(), "the gripper goal ended before the cancel")
        moving = len(self.joints)
        cancel_ns = time.time_ns()
        handle.cancel_goal_async()
        self.assertTrue(ros.spin_until(result, 10.0), "no result after the cancel")
        self.assertEqual(result.result().status, GoalStatus.STATUS_CANCELED)
        ros.message_stamped(self.joints, cancel_ns + int((CANCEL_STOP_S + 0.3) * 1e9), 30.0)
        after = self.joints[moving:]
        first_stop = next((m for m in after if stamp_ns(m) > cancel_ns and stopped(m)), None)
        self.assertIsNotNone(first_stop, f"still moving: {list(after[-1].velocity)}")
        print(f"cancel: every velocity 0 {(stamp_ns(first_stop) - cancel_ns) * 1e-6:.0f} ms after the request")
        late = [m for m in after if stamp_ns(m) > cancel_ns + CANCEL_STOP_S * 1e9]
        self.assertGreater(len(late), 10)
        self.assertEqual([list(m.velocity) for m in late if not stopped(m)], [])


@launch_testing.post_shutdown_test()
class TestEmptyHandGripperShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
