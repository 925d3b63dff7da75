"""launch_testing: the Teleoperate goal of `hand.launch.py sim:=true` (the pinch ball on its stand),
this test publishing the targets on /prisma/teleop/motor_targets itself at 50 Hz from a process of
its own, as a glove's teleop node does (the tests run in order, on one launch):

1. targets at the closed ends (fingers 9 rad, thumb_flexion 7 rad): the hand closes on the ball and
   stops there, every pad's estimated force (its Fz in /prisma/hand/wrench) at most 0.15 N above
   max_pad_force (2 N) while it closes and holds, the feedback `holding` with both motors held back;
2. targets back to 0: the hand opens (every motor within 0.05 rad of 0), the goal still following;
3. the glove stops publishing mid-closing: every /joint_states velocity 0 (below one velocity unit
   of an X-series Dynamixel, as in the other launch tests) within 0.3 s of the last target's
   publication, the goal ABORTED `input_stale: prisma/teleop/motor_targets silent for N ms` (or `N ms
   older than /joint_states`);
4. the glove publishes again and a new goal follows again (the hand opens); a cancel ends it
   CANCELED, the result a success with reason `canceled`.
After the launch is stopped every node exits 0 without a traceback.

A goal is sent again only while it is refused for now (not_ready while the graph comes up).

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import sys
import time
import unittest

from prisma_testing.goals import goal_outcome
from prisma_testing.launch_case import (
    GraphTestCase,
    MotorPositions,
    assert_clean_shutdown,
    launch_test,
    touch_limit_n,
    touch_limited_peaks,
)
from prisma_testing.node_process import NodeProcess
from prisma_testing.ros_harness import SIM_STOPPED_RAD_S, STOPPED_RAD_S, joint, require_ros, stamp_ns, stopped

require_ros()

import launch_testing  # noqa: E402
from prisma_msgs.action import Teleoperate  # noqa: E402
from prisma_msgs.msg import HandWrench  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import MOTOR_NAMES  # noqa: E402

STOP_WITHIN_S = 0.3
GLOVE_PERIOD_S = 0.02  # 50 Hz
OPEN = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
CLOSED = {"fingers": 9.0, "thumb_flexion": 7.0}  # config/motor_driver.yaml max_positions


generate_test_description = launch_test("hand.launch.py", sim="true")


# The glove a teleop node would be: a process of its own on the teleop node's rung (teleop.launch.py
# runs it on the control path's), publishing `positions` every GLOVE_PERIOD_S while `on`, each stamped
# when published; turned off, it prints the stamp of the last one (this process does not take the
# targets: beside the load harness its five streams, 370 messages a second, were more than it took, and
# /joint_states fell 10 s behind). Published from a thread of this test process instead, the targets fell silent for
# 162 ms once on a loaded machine and the goal ended input_stale while the "glove" ran: that thread
# shares Python's lock with the test's executor, busy with its 100 Hz collections at the default
# priority.
GLOVE = f"""
import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import JointState
from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY, try_rt_priority

try_rt_priority(CONTROL_PATH_RT_PRIORITY)  # before rclpy starts its threads: they inherit it
rclpy.init()
node = Node("teleop_test_glove")
names = node.declare_parameter("names", {list(MOTOR_NAMES)!r}).value
node.declare_parameter("positions", [0.0, 0.0, 0.0])
node.declare_parameter("on", False)
publisher = node.create_publisher(JointState, "/prisma/teleop/motor_targets", 10)
last_ns = [0]

def publish():
    if node.get_parameter("on").value:
        msg = JointState(name=names, position=list(node.get_parameter("positions").value))
        msg.header.stamp = node.get_clock().now().to_msg()
        publisher.publish(msg)
        last_ns[0] = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec

def turned_off(params):
    # one thread runs this and the timer: no target is published between this line and the new value
    if any(p.name == "on" and not p.value for p in params):
        print(f"last target {{last_ns[0]}}", flush=True)
    return SetParametersResult(successful=True)

node.add_on_set_parameters_callback(turned_off)

node.create_timer({GLOVE_PERIOD_S}, publish)
print("glove ready", flush=True)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
"""


class TestTeleopGoal(MotorPositions, GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.joints = ros.collect(JointState, "/joint_states")
        # the five pads in one stream, as manipulation takes them: five 100 Hz streams more would be
        # more than this process takes beside the load harness
        cls.wrenches = ros.collect(HandWrench, "/prisma/hand/wrench")
        cls.glove = NodeProcess([sys.executable, "-c", GLOVE])
        if not cls.glove.wait_for_output("glove ready", 60.0):
            raise AssertionError(f"the test's glove did not start:\n{cls.glove.output}")
        cls.client = ros.action_client(Teleoperate, "/prisma/teleoperate", wait_sec=90.0)

    @classmethod
    def tearDownClass(cls) -> None:
        cls.glove.kill()
        super().tearDownClass()

    def glove_sends(self, targets: dict[str, float]) -> None:
        """The glove publishes `targets` from its next sample on."""
        results = self.ros.set_parameters("/teleop_test_glove", positions=[targets.get(m, 0.0) for m in MOTOR_NAMES],
                                          on=True)
        self.assertTrue(all(r.successful for r in results), results)

    def glove_stops(self) -> int:
        """The glove falls silent: when its last target was published (its stamp)."""
        said = self.glove.output.count("last target ")
        results = self.ros.set_parameters("/teleop_test_glove", on=False)
        self.assertTrue(all(r.successful for r in results), results)
        deadline = time.monotonic() + 5.0  # printed before the glove answered: here within ms
        while self.glove.output.count("last target ") == said:
            self.assertLess(time.monotonic(), deadline, f"the glove did not say its last target:\n{self.glove.output}")
            time.sleep(0.01)
        return int(self.glove.output.rsplit("last target ", 1)[1].split()[0])

    def start_goal(self):
        """A Teleoperate goal with the parameters' settings (2 N, 40 rpm, 0.15 s), sent again only while
        it is refused for now; its handle once its first feedback came."""
        return self.ros.send_until_started(self.client, Teleoperate.Goal(), timeout_sec=90.0)

    def latest_feedback(self, handle):
        mine = self.ros.feedback_of(handle)
        return mine[-1].feedback if mine else None

    def test_1_closes_on_the_ball_and_stops_at_the_force_limit(self):
        ros = self.ros
        ros.wait_until_keeping_up(self.joints, self.wrenches, lag_sec=0.05, checks=10, timeout_sec=90.0)
        self.glove_sends(OPEN)
        handle = TestTeleopGoal.handle = self.start_goal()
        closing_ns = time.time_ns()
        self.glove_sends(CLOSED)

        def held() -> bool:
            fb = self.latest_feedback(handle)
            return fb is not None and fb.phase == "holding" and set(fb.force_limited) == {"fingers", "thumb_flexion"}

        self.assertTrue(ros.spin_until(held, 20.0), self.latest_feedback(handle))
        ros.spin_for(2.0)  # holding: nothing creeps on
        fb = self.latest_feedback(handle)
        at = self.positions()
        rounded = {m: round(v, 3) for m, v in at.items()}
        print(f"held after closing: phase {fb.phase}, force_limited {list(fb.force_limited)}, positions {rounded}, "
              f"feedback pad_forces {[round(v, 3) for v in fb.pad_forces]}")
        self.assertEqual((fb.phase, sorted(fb.force_limited)), ("holding", ["fingers", "thumb_flexion"]))
        for target, clamped in zip(fb.targets, (9.0 - 0.02, 7.0 - 0.02, 0.0)):  # inside the limit margin
            self.assertAlmostEqual(target, clamped, places=5)
        # the ball is held by both pads, at the limit
        touch_limited_peaks(self.wrenches, closing_ns, reached_n=touch_limit_n())
        self.assertLess(at["fingers"], 8.5)  # stopped on the ball, short of the closed end
        self.assertTrue(stopped(self.ros.message_at(self.joints, 0.0)))

    def test_2_targets_at_0_open_the_hand(self):
        self.glove_sends(OPEN)
        at = self.assert_reaches(OPEN, 0.05, 15.0)
        print(f"opened: {at}")
        fb = self.latest_feedback(self.handle)
        self.assertEqual((fb.phase, list(fb.force_limited)), ("following", []))
        self.assertFalse(self.handle.get_result_async().done())

    def test_3_the_glove_falling_silent_stops_the_motors_within_0_3_s(self):
        ros = self.ros
        self.glove_sends(CLOSED)
        ros.spin_for(0.3)  # closing freely at 40 rpm (the index touches the ball at 3 rad, after 0.7 s)
        last_ns = self.glove_stops()
        result = ros.result(self.handle, timeout_sec=10.0)
        status, reason = goal_outcome(result)
        ros.message_stamped(self.joints, last_ns + 500_000_000, 30.0)  # however late this process takes them
        after = [m for m in self.joints if stamp_ns(m) >= last_ns]
        stop_s = self.stopped_after(after, last_ns, STOPPED_RAD_S)
        settle_s = self.stopped_after(after, last_ns, SIM_STOPPED_RAD_S)
        speed = abs(joint(after[0], "fingers", "velocity"))
        print(f"glove silent at fingers {joint(after[0], 'fingers'):.2f} rad, {speed:.2f} rad/s: {status} {reason!r}; "
              f"every velocity below {STOPPED_RAD_S:.4f} rad/s (0.229 rpm) {stop_s * 1e3:.0f} ms, below "
              f"{SIM_STOPPED_RAD_S} rad/s {settle_s * 1e3:.0f} ms after the last target's publication")
        self.assertEqual(status, "ABORTED")
        # the watchdog's tick finds them silent, or a /joint_states finds the last one too old: whichever first
        self.assertRegex(reason, r"^input_stale: prisma/teleop/motor_targets "
                                 r"(silent for \d+ ms|\d+ ms older than /joint_states)$")
        self.assertFalse(result.result.success)
        self.assertGreater(speed, 4.0)  # closing at 40 rpm (4.19 rad/s) when the glove fell silent
        self.assertLess(stop_s, STOP_WITHIN_S)

    def stopped_after(self, joints: list, since_ns: int, below_rad_s: float) -> float:
        """Seconds from `since_ns` to the /joint_states from which on every velocity stays below
        `below_rad_s` (AssertionError if the last one collected still moves)."""
        moving = [i for i, m in enumerate(joints) if not stopped(m, below_rad_s)]
        if not moving:
            return 0.0
        self.assertLess(moving[-1], len(joints) - 1, f"still above {below_rad_s} rad/s at the end")
        return (stamp_ns(joints[moving[-1] + 1]) - since_ns) * 1e-9

    def test_4_a_new_goal_follows_again_and_a_cancel_is_its_success(self):
        ros = self.ros
        self.glove_sends(OPEN)
        handle = self.start_goal()
        self.assert_reaches(OPEN, 0.05, 15.0)
        cancel = handle.cancel_goal_async()
        self.assertTrue(ros.spin_until(cancel, 10.0))
        result = ros.result(handle, timeout_sec=10.0)
        print(f"cancel: {goal_outcome(result)}, success {result.result.success}, duration "
              f"{result.result.duration:.2f} s, positions {[round(v, 3) for v in result.result.positions]}")
        self.assertEqual(goal_outcome(result), ("CANCELED", "canceled"))
        self.assertTrue(result.result.success)
        self.assertEqual(list(result.result.motors), list(MOTOR_NAMES))
        self.glove_stops()


@launch_testing.post_shutdown_test()
class TestTeleopGoalShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
