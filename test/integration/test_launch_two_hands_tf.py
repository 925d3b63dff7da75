"""launch_testing: two hands on one graph as ROS sees two robots. `hand.launch.py sim:=true` beside a
second hand under `namespace:=left`, each with robot_state_publisher and the description from
prisma_description (one hand's frames under a grasp: test_launch_hand_tf.py).

- Every frame id on the left hand's messages (per-finger and per-hand taxels, wrench, contact) has a
  transform from its base through tf2: left/prisma_<finger>_pad from left/prisma_hand_base;
  its /joint_states names only joints of its description.
- Two trees, no clash: every frame of /tf and /tf_static has one parent, the left hand's frames all
  start with left/, the two bases are not connected, and each hand has its own /robot_description.
- Each hand's tactile_driver draws its ball (prisma/sim/object) in its own base frame.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import unittest

import pytest

from prisma_testing.launch_case import assert_clean_shutdown, graph_under_test, include_launch
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from rclpy.time import Time  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402
from prisma_hand_sim.sim_objects import OBJECTS  # noqa: E402
from prisma_testing.tf_case import TfTestCase  # noqa: E402

HANDS = {"": "", "/left": "left/"}  # namespace -> frame prefix


@pytest.mark.launch_test
def generate_test_description():
    # the second hand at the default priority: two control paths at real-time priority would leave
    # this test's own process too little of the two cores to see their messages (below it, at nice
    # 10, beside the load harness's hogs its force estimator never finished loading within a minute)
    return graph_under_test(include_launch("hand.launch.py", sim="true"),
                            include_launch("hand.launch.py", sim="true", namespace="left",
                                           rt_priority="0", nice="0"))


class TestTwoHandsTf(TfTestCase):
    def test_1_the_left_hands_frames_have_transforms_from_its_base(self):
        self.assertEqual(self.frames_with_a_transform("/left", "left/"), {f"left/prisma_{f}_pad" for f in FINGERS})

    def test_2_two_hands_two_trees_no_clash(self):
        ros = self.ros
        tf = ros.collect(TFMessage, "/tf")
        static = ros.collect(TFMessage, "/tf_static",
                             QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        ros.spin_for(2.0)
        ros.stop_collecting(tf, static)
        self.assertTrue(static and tf)
        parents: dict[str, set[str]] = {}
        for message in tf + static:
            for transform in message.transforms:
                parents.setdefault(transform.child_frame_id, set()).add(transform.header.frame_id)
        self.assertEqual({child: p for child, p in parents.items() if len(p) > 1}, {})
        left = {frame for frame in parents if frame.startswith("left/")}
        right = set(parents) - left
        self.assertEqual({frame.removeprefix("left/") for frame in left}, right)  # same robot, own names
        self.assertEqual(len(right), len(self.description("").links) - 1)  # every link but the root
        self.assertTrue(all(parents[f].pop().startswith("left/") for f in left))
        self.assertFalse(self.buffer.can_transform("prisma_hand_base", "left/prisma_hand_base", Time()))
        self.assertEqual(len(self.description("/left").joints), len(self.description("").joints))

    def test_3_each_hand_draws_its_ball_in_its_own_base_frame(self):
        ball_mm = OBJECTS["pinch_ball"].size_mm[2]
        for namespace, prefix in HANDS.items():
            marker = self.first_messages(Marker, f"{namespace}/prisma/sim/object", count=1)[0]
            self.assertEqual((marker.header.frame_id, marker.type), (f"{prefix}prisma_hand_base", Marker.SPHERE))
            self.assertAlmostEqual(marker.scale.x * 1e3, ball_mm)


@launch_testing.post_shutdown_test()
class TestTwoHandsTfShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
