"""launch_testing: the Grasp and Manipulate actions of `hand.launch.py sim:=true`, through rclpy
ActionClients on the launched graph over DDS (the tests run in order, on one launch):

1. goals from the moment the action servers appear: each is re-sent only while it is refused
   `not_ready` (the node aborts goals at once, the reason in the result, until every stream they
   need flows); failing goals (a grasp to 3 N at 1 rpm with a 0.3 s timeout, a horizontal
   manipulation with a 0.1 s timeout: both end ABORTED `timeout`) alternate with succeeding ones
   (Grasp pinch: SUCCEEDED `force_reached`; then Manipulate horizontal: SUCCEEDED `edge_lost`), twice
   over; every goal gets its result and the manipulation process is still running at the end;
2. a cancel during a Grasp ends CANCELED and the motors stop (rule below);
3. a Manipulate and a Grasp sent while a slow Grasp runs are both aborted at once `busy: a grasp
   goal ...` (the reason in the result), the running one goes on until its cancel; the node then
   serves them;
4. goals beyond the configured limits are aborted at once, the result's reason (and the log)
   naming the value;
5. `ros2 param set /manipulation k 0.7` shows in every ContactState stamped after it, `k 2.0` is
   refused by rclpy's range check and changes nothing.
After the launch is stopped (SIGINT to every node, as Ctrl-C on `ros2 launch`): every node exits 0
with no traceback, the motor driver logging that it turned the torque off.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import subprocess
import time
import unittest

import numpy as np

from prisma_testing.goals import goal_outcome, gripper_goal
from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test, output_of
from prisma_testing.ros_harness import closing_at_10_rpm, require_ros, stamp_ns, stamped_after, stopped

require_ros()

import launch_testing  # noqa: E402
from control_msgs.action import GripperCommand  # noqa: E402
from launch.events.process import ProcessExited  # noqa: E402
from prisma_msgs.action import Grasp, Manipulate  # noqa: E402
from prisma_msgs.msg import ContactState  # noqa: E402
from rcl_interfaces.srv import GetParameters  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

# stopped(): every joint below one velocity unit of an X-series Dynamixel (0.229 rpm), which reads 0
# there. The sim motors' velocity follows the command with a 10 ms time constant: from 10 rpm it is
# below that 38 ms after the stop.
CANCEL_STOP_S = 0.05
K = 0.8  # config/manipulation.yaml
TORQUE_OFF = "torque off: fingers, thumb_flexion, thumb_rotation"

FAILING_GRASP = Grasp.Goal(grasp="pinch", finger_force=3.0, thumb_force=3.0, speed_rpm=1.0, timeout=0.3)
PINCH = Grasp.Goal(grasp="pinch")
# at 1 rpm neither can get anywhere before its timeout, and they leave the hand where it was (a
# horizontal goal that times out does not turn back: at 20 rpm the next one would start at the edge)
FAILING_HORIZONTAL = Manipulate.Goal(motion="horizontal", speed_rpm=1.0, timeout=0.1)
HORIZONTAL = Manipulate.Goal(motion="horizontal")
# a force the ball never reaches at 2 rpm: the fingers close for seconds, until the cancel
SLOW_GRASP = Grasp.Goal(grasp="pinch", finger_force=3.0, thumb_force=3.0, speed_rpm=2.0)


generate_test_description = launch_test("hand.launch.py", sim="true")


class TestHandActions(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.contacts = ros.collect(ContactState, "/prisma/thumb/contact")
        # made before the servers exist: test 1 sends its first goals the moment they appear
        cls.grasp = ros.action_client(Grasp, "/prisma/grasp", wait_sec=None)
        cls.manipulate = ros.action_client(Manipulate, "/prisma/manipulate", wait_sec=None)
        cls.gripper = ros.action_client(GripperCommand, "/prisma/gripper_cmd", wait_sec=None)

    def client(self, goal):
        return self.grasp if isinstance(goal, Grasp.Goal) else self.manipulate

    def run_goal(self, goal, timeout_sec: float = 60.0):
        """`goal`'s result, the goal sent again only while it is refused not_ready (send_until_started):
        a goal stopped sensor_stale by the watchdog is a failure (the control path runs at real-time
        priority, hand.launch.py)."""
        return self.ros.result(self.ros.send_until_started(self.client(goal), goal, timeout_sec), timeout_sec=30.0)

    def open_hand(self) -> None:
        """The fingers back at 0 (GripperCommand position 0) and the ball back between them (the sim
        world's ~/replace_object): a slow grasp has seconds of travel before the ball, wherever the
        test before left the fingers (at the joint limit around it) and the ball."""
        opened = self.ros.result(self.ros.send_until_started(self.gripper, gripper_goal(0.0)), timeout_sec=30.0)
        self.assertEqual(goal_outcome(opened), ("SUCCEEDED", "reached_goal"))
        replaced = self.ros.call(Trigger, "/tactile_driver/replace_object", Trigger.Request())
        self.assertTrue(replaced.success, replaced.message)

    def test_1_goals_from_the_moment_the_servers_appear(self, proc_info):
        ros = self.ros
        start = time.monotonic()
        servers = (self.grasp, self.manipulate)
        self.assertTrue(ros.spin_until(lambda: all(s.server_is_ready() for s in servers), 90.0))
        print(f"action servers up {time.monotonic() - start:.1f} s after the launch")
        expected = [(FAILING_GRASP, ("ABORTED", "timeout")), (PINCH, ("SUCCEEDED", "force_reached")),
                    (FAILING_HORIZONTAL, ("ABORTED", "timeout")), (HORIZONTAL, ("SUCCEEDED", "edge_lost"))] * 2
        outcomes = []
        for goal, _ in expected:
            # the first two goals meet the graph just started: the node must refuse them until it is
            # ready, then carry them out
            outcomes.append(goal_outcome(self.run_goal(goal)))
            print(f"{type(goal).__name__} {goal.grasp if hasattr(goal, 'grasp') else goal.motion} "
                  f"timeout {goal.timeout:g}: {outcomes[-1]} at {time.monotonic() - start:.1f} s")
        refused = ros.logs(name="manipulation", contains="goal refused")
        print(f"refusals logged: {sorted(set(refused))}")
        self.assertEqual(outcomes, [want for _, want in expected])
        # the node lived through it: its process runs and it still answers
        self.assertNotIsInstance(proc_info["manipulation"], ProcessExited)
        response = ros.call(GetParameters, "/manipulation/get_parameters", GetParameters.Request(names=["k"]))
        self.assertAlmostEqual(response.values[0].double_value, K)

    def test_2_cancel_during_a_grasp_stops_the_motors(self):
        """Rule: t_result = the wall clock when the CANCELED result reached this client (the nodes stamp
        /joint_states with the same system clock). The fingers were moving at 10 rpm when the cancel
        was sent; every /joint_states stamped later than t_result + 50 ms has every velocity 0
        (below one Dynamixel velocity unit, 0.024 rad/s), and there are such messages."""
        ros = self.ros
        # from the open hand, a slow grasp to a force the ball never reaches: the fingers close at
        # 10 rpm for seconds
        self.open_hand()
        goal = Grasp.Goal(grasp="pinch", finger_force=3.0, thumb_force=3.0, speed_rpm=10.0)
        handle = ros.send_until_started(self.grasp, goal)
        result = handle.get_result_async()
        accepted = len(self.joints)
        ros.spin_until(lambda: result.done() or closing_at_10_rpm(self.joints[accepted:]), 10.0)
        self.assertFalse(result.done(), "the grasp ended before the cancel")
        moving = len(self.joints)
        cancel = handle.cancel_goal_async()
        self.assertTrue(ros.spin_until(result, 10.0), "no result after the cancel")
        result_ns = time.time_ns()
        ros.spin_until(cancel, 5.0)
        # /joint_states up to 300 ms after the result: waited for by its stamp (this process may
        # receive the stream late on a loaded machine; in CI 0.3 s of its own time was not enough)
        ros.message_stamped(self.joints, result_ns + 300_000_000)
        self.assertEqual(goal_outcome(result.result()), ("CANCELED", "canceled"))

        after = self.joints[moving:]
        first_stop = next((m for m in after if stopped(m)), None)
        self.assertIsNotNone(first_stop, f"still moving: {list(after[-1].velocity)}")
        print(f"cancel: every velocity 0 at {(stamp_ns(first_stop) - result_ns) * 1e-6:+.0f} ms from the result")
        late = [m for m in after if stamp_ns(m) > result_ns + CANCEL_STOP_S * 1e9]
        self.assertGreater(len(late), 10)
        self.assertEqual([list(m.velocity) for m in late if not stopped(m)], [])

    def test_3_goals_sent_while_a_grasp_runs_are_refused_busy(self):
        """One goal at a time: a Manipulate and a Grasp sent while a slow Grasp runs (its feedback
        came, its result has not) are aborted at once `busy: a grasp goal ...`, the reason in the
        result and the log, and the running grasp goes on to its cancel. Then the node serves both."""
        ros = self.ros
        self.open_hand()
        running = ros.send_until_started(self.grasp, SLOW_GRASP, timeout_sec=60.0)
        running_result = running.get_result_async()
        for goal in (HORIZONTAL, PINCH):
            status, reason = goal_outcome(ros.result(ros.send_goal(self.client(goal), goal), timeout_sec=10.0))
            print(f"{type(goal).__name__} sent while the slow grasp runs: {status} {reason}")
            self.assertFalse(running_result.done(), f"the slow grasp ended first: {running_result.result()}")
            self.assertEqual(status, "ABORTED")
            self.assertTrue(reason.startswith("busy: a grasp goal"), reason)
            action = type(goal).__name__.split("_")[0]
            refused = f"{action} goal refused: busy: a grasp goal"
            self.assertTrue(ros.wait_for_log(name="manipulation", contains=refused), ros.logs(name="manipulation")[-5:])
        cancel = running.cancel_goal_async()
        self.assertTrue(ros.spin_until(running_result, 10.0), "no result after the cancel")
        ros.spin_until(cancel, 5.0)
        self.assertEqual(goal_outcome(running_result.result()), ("CANCELED", "canceled"))
        # the node serves them now: the pinch holds the ball, the horizontal motion runs to the edge
        self.assertEqual(goal_outcome(self.run_goal(PINCH)), ("SUCCEEDED", "force_reached"))
        self.assertEqual(goal_outcome(self.run_goal(HORIZONTAL)), ("SUCCEEDED", "edge_lost"))

    def test_4_goals_beyond_the_limits_are_refused_with_the_reason(self):
        ros = self.ros
        beyond = [
            (Grasp.Goal(grasp="pinch", finger_force=3.5), "invalid: finger_force 3.5 above the configured limit 3.0"),
            (Grasp.Goal(grasp="pinch", thumb_force=4.0), "invalid: thumb_force 4.0 above the configured limit 3.0"),
            (Grasp.Goal(grasp="pinch", speed_rpm=80.0), "invalid: speed_rpm 80.0 above the configured limit 70.0"),
            (Grasp.Goal(grasp="fist"), "invalid: grasp 'fist' is not one of ['lateral', 'pinch', 'power']"),
            (Manipulate.Goal(motion="horizontal", speed_rpm=71.0),
             "invalid: speed_rpm 71.0 above the configured limit 70.0"),
            (Manipulate.Goal(motion="horizontal", k=2.0), "invalid: k 2.0 outside (0.0, 1.5]"),
            (Manipulate.Goal(motion="diagonal"),
             "invalid: motion 'diagonal' is not one of ['horizontal', 'vertical', 'hold']"),
        ]
        for goal, reason in beyond:
            result = ros.result(ros.send_goal(self.client(goal), goal), timeout_sec=10.0)
            self.assertEqual(goal_outcome(result), ("ABORTED", reason))
            action = type(goal).__name__.split("_")[0]
            self.assertTrue(ros.wait_for_log(name="manipulation", contains=f"{action} goal refused: {reason}"), reason)

    def param_set(self, value: str) -> str:
        """`ros2 param set /manipulation k <value>` as an operator types it; its output."""
        done = subprocess.run(["ros2", "param", "set", "--no-daemon", "/manipulation", "k", value],
                              capture_output=True, text=True, timeout=60)
        return (done.stdout + done.stderr).strip()

    def contacts_after(self, t_ns: int, count: int = 20) -> list:
        """ContactStates stamped after `t_ns`: at least `count` of them."""
        # this process may receive the stream seconds late on a busy machine
        self.assertTrue(self.ros.spin_until(lambda: len(stamped_after(self.contacts, t_ns)) >= count, 30.0),
                        f"{len(stamped_after(self.contacts, t_ns))} ContactStates stamped after {t_ns}")
        return stamped_after(self.contacts, t_ns)

    def test_5_k_at_run_time(self):
        ros = self.ros
        before = self.contacts_after(time.time_ns() - 10**9)
        self.assertEqual({round(m.k, 6) for m in before}, {K})
        self.assertEqual(self.param_set("0.7"), "Set parameter successful")
        changed_ns = time.time_ns()
        after = self.contacts_after(changed_ns)
        self.assertEqual({round(m.k, 6) for m in after}, {0.7})
        for m in after:  # Algorithm 1 with the new k: v_t = k * mean voltage
            self.assertAlmostEqual(m.threshold, np.float32(0.7) * m.mean_voltage, places=5)

        # refused by rclpy's range check: k's descriptor advertises [0.0, 1.5]
        self.assertEqual(self.param_set("2.0"),
                         "Setting parameter failed: Parameter k out of range Min: 0.0, Max: 1.5, value: 2.0")
        refused_ns = time.time_ns()
        self.assertEqual({round(m.k, 6) for m in self.contacts_after(refused_ns)}, {0.7})
        self.assertTrue(ros.set_parameters("/manipulation", k=K)[0].successful)
        self.assertEqual({round(m.k, 6) for m in self.contacts_after(time.time_ns())}, {K})


@launch_testing.post_shutdown_test()
class TestHandActionsShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)

    def test_motor_driver_turns_the_torque_off(self, proc_output):
        self.assertIn(TORQUE_OFF, output_of(proc_output, "motor_driver"))
