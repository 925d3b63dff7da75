"""launch_testing: `teleop.launch.py glove:=none` (hand-pose input, the sim hand with the pinch ball,
the teleop node engaged at start), the test wearing the glove: the operator's joint angles on
/glove/joint_states at 60 Hz from a process on the control path's rung (test/support/prisma_testing/operator_glove.py).
The tests run in order, on one launch:

1. the operator closes to a fist: the teleop node's Teleoperate goal runs, the hand closes on the
   ball and stops there touch-limited, no pad's estimated force (/prisma/<finger>/wrench Fz) more
   than 0.15 N above max_pad_force (2 N) while it closes and holds, thumb and index both at the limit;
2. the operator opens: the hand opens (fingers and thumb within 0.05 rad of 0);
3. the glove falls silent mid-closing (the fingers closing faster than 2 rad/s): every /joint_states
   velocity 0 (below one velocity unit of an X-series Dynamixel) within 0.3 s of the last glove
   sample's publication, the goal ended `input_stale` (the teleop node's log);
4. the glove back: the teleop node sends a new goal by itself and the hand follows the operator again:
   the thumb's opposition sweeps thumb_rotation to its opposed end (1.5 rad), the open hand back to 0.
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import time
import unittest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test, touch_limited_peaks
from prisma_testing.operator_glove import FIST, OPEN, OperatorGlove, WearingTheGlove
from prisma_testing.ros_harness import STOPPED_RAD_S, joint, require_ros, stamp_ns, stopped

require_ros()

import launch_testing  # noqa: E402
from prisma_msgs.action import Teleoperate  # noqa: E402
from prisma_msgs.msg import HandWrench  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import MOTOR_NAMES  # noqa: E402
from prisma_teleop.synthetic_glove_core import Synergies  # noqa: E402

STOP_WITHIN_S = 0.3
OPPOSED = Synergies(0.0, 0.0, 1.0)


generate_test_description = launch_test("teleop.launch.py", glove="none")


class TestTeleop(WearingTheGlove, GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.targets = ros.collect(JointState, "/prisma/teleop/motor_targets")
        cls.wrenches = ros.collect(HandWrench, "/prisma/hand/wrench")  # the five pads in one stream
        cls.feedback = ros.collect(Teleoperate.Impl.FeedbackMessage, "/prisma/teleoperate/_action/feedback")
        cls.glove = OperatorGlove()

    def following_after(self, count: int) -> bool:
        """A Teleoperate goal's feedback received after the first `count` says it follows or holds."""
        return any(m.feedback.phase in ("following", "holding") for m in self.feedback[count:])

    def test_1_the_operator_closes_and_the_hand_stops_on_the_ball_at_the_touch_limit(self):
        ros, glove = self.ros, self.glove
        ros.wait_until_keeping_up(self.joints, self.wrenches, lag_sec=0.05, checks=10, timeout_sec=90.0)
        glove.move(OPEN)
        # the teleop node sends its goal once the targets flow (again after a refusal while the graph comes up)
        self.assertTrue(ros.spin_until(lambda: self.following_after(0), 60.0), ros.logs(name="teleop")[-5:])
        closing_ns = time.time_ns()
        glove.move(FIST, 1.5)

        def held() -> bool:
            fb = self.feedback[-1].feedback if self.feedback else None
            return fb is not None and fb.phase == "holding" and set(fb.force_limited) == {"fingers", "thumb_flexion"}

        self.assertTrue(ros.spin_until(held, 20.0), self.feedback[-1].feedback if self.feedback else None)
        ros.spin_for(2.0)  # holding: nothing creeps on
        at = self.positions()
        target = self.targets[-1]
        print(f"operator's fist: targets {[round(v, 3) for v in target.position]} rad, the hand stopped at "
              f"{ {m: round(v, 3) for m, v in at.items()} }")
        self.assertEqual(list(target.position), [9.0, 7.0, 0.0])  # the fist: the closed limits exactly
        touch_limited_peaks(self.wrenches, closing_ns)  # the ball is held by both pads, at the limit
        self.assertGreater(at["fingers"], 3.0)  # past first touch (3 rad)
        self.assertLess(at["fingers"], 8.5)  # stopped on the ball, short of the operator's fist
        self.assertTrue(stopped(self.ros.message_at(self.joints, 0.0, timeout_sec=30.0)))
        # the pads' 100 Hz wrench stream is this test's only use of it: without it this process
        # (default priority, beside the graph at real-time priority) keeps up with the rest
        self.ros.stop_collecting(self.wrenches)

    def test_2_the_operator_opens_and_the_hand_opens(self):
        self.glove.move(OPEN, 1.5)
        at = self.assert_reaches({"fingers": 0.0, "thumb_flexion": 0.0}, 0.05, 15.0)
        print(f"opened: { {m: round(v, 3) for m, v in at.items()} }")
        self.assertEqual(list(self.targets[-1].position), [0.0, 0.0, 0.0])

    def test_3_the_glove_falling_silent_mid_closing_stops_the_motors_within_0_3_s(self):
        ros, glove = self.ros, self.glove
        # silent mid-closing, 0.35 s into the operator's 1.5 s fist: the fingers close at their speed
        # cap toward the ball (first touch at 3 rad, about 0.8 s in). Timed by the glove's process,
        # not by when this one sees the fingers move: /joint_states reached it late enough in CI
        # that the glove fell silent after the fingers had stopped on the ball
        last_ns = glove.move_and_fall_silent(FIST, 1.5, silent_after_s=0.35)
        self.assertTrue(ros.wait_for_log(name="teleop", contains="goal ended: input_stale", timeout_sec=10.0))
        # every /joint_states up to 1 s after the glove's last sample: this process may receive them
        # late on a loaded machine, so wait for one stamped then, not for a time
        ros.message_stamped(self.joints, last_ns + 1_000_000_000, 30.0)
        after = [m for m in self.joints if stamp_ns(m) >= last_ns]
        moving = [i for i, m in enumerate(after) if not stopped(m)]
        before = [round(joint(m, "fingers", "velocity"), 2) for m in self.joints
                  if last_ns - 500_000_000 <= stamp_ns(m) < last_ns]
        self.assertTrue(moving and moving[-1] < len(after) - 1,
                        f"not moving when the glove fell silent, or still moving at the end: fingers at "
                        f"{[round(joint(m, 'fingers', 'velocity'), 2) for m in after[:3]]} ... "
                        f"{[round(joint(m, 'fingers', 'velocity'), 2) for m in after[-2:]]} rad/s after, "
                        f"every 5th of the 0.5 s before: {before[::5]}; {len(self.joints)} /joint_states in all, "
                        f"the last stamped {(stamp_ns(self.joints[-1]) - last_ns) * 1e-9:+.3f} s from the "
                        f"glove's last sample, now {(time.time_ns() - last_ns) * 1e-9:+.3f} s")
        stop_s = (stamp_ns(after[moving[-1] + 1]) - last_ns) * 1e-9
        speed = abs(joint(after[0], "fingers", "velocity"))
        (ended,) = ros.logs(name="teleop", contains="goal ended: input_stale")[-1:]
        print(f"glove silent at fingers {joint(after[0], 'fingers'):.2f} rad, {speed:.2f} rad/s: every velocity below "
              f"{STOPPED_RAD_S:.4f} rad/s {stop_s * 1e3:.0f} ms after the last glove sample; teleop: {ended}")
        self.assertGreater(speed, 1.0)  # it was closing when the glove fell silent
        self.assertLess(stop_s, STOP_WITHIN_S)
        self.assertRegex(ended, r"^goal ended: input_stale: prisma/teleop/motor_targets ")

    def test_4_the_glove_back_the_hand_follows_again(self):
        ros, glove = self.ros, self.glove
        sent = len(ros.logs(name="teleop", contains="sending Teleoperate"))
        feedback = len(self.feedback)
        glove.move(OPEN, 1.0)
        # the teleop node sends a new goal by itself once the glove is back
        self.assertTrue(ros.spin_until(lambda: len(ros.logs(name="teleop", contains="sending Teleoperate")) > sent,
                                       20.0))
        self.assertTrue(ros.spin_until(lambda: self.following_after(feedback), 20.0))
        glove.move(OPPOSED, 1.5)  # the thumb's opposition sweep: thumb_rotation to its opposed end
        at = self.assert_reaches({"thumb_rotation": 1.5}, 0.05, 15.0)
        print(f"thumb opposed: { {m: round(v, 3) for m, v in at.items()} }")
        glove.move(OPEN, 1.0)
        self.assert_reaches(dict.fromkeys(MOTOR_NAMES, 0.0), 0.05, 15.0)
        glove.stop()


@launch_testing.post_shutdown_test()
class TestTeleopShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
