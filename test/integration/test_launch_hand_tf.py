"""launch_testing: the hand as ROS sees a robot. `hand.launch.py sim:=true` beside a second hand under
`namespace:=left`, each with robot_state_publisher and the description from prisma_description.

- Every frame id on the graph's messages (per-finger and per-hand taxels, wrench, contact) has a
  transform from its hand's base through tf2: prisma_<finger>_pad from prisma_hand_base, and
  left/prisma_<finger>_pad from left/prisma_hand_base; /joint_states names only joints of the
  description.
- Two trees, no clash: every frame of /tf and /tf_static has one parent, the left hand's frames all
  start with left/, the two bases are not connected, and each hand has its own /robot_description.
- During a pinch Grasp the thumb pad moves as the coupling says: its transform at each joint state
  stamp is the description's forward kinematics at the full joint state tendon_stretch gives
  robot_state_publisher (prisma/model_joint_states), and before it touches the ball it travels the
  simulator's 8 mm per rad of thumb flexion. /joint_states stays the three motors.
- The fingers rest on the ball: once the pinch ends force_reached the thumb and index pad frames are
  one ball diameter apart (the sim world's, within 5 mm: the pads press into the foam), not through
  it (1.8 mm apart with the rigid coupling); each hand's tactile_driver draws the ball
  (prisma/sim/object) in its own base frame, between the pads.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import unittest

import numpy as np
import pytest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, graph_under_test, include_launch
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

import launch_testing  # noqa: E402
import launch_testing.actions  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from prisma_msgs.action import Grasp  # noqa: E402
from prisma_msgs.msg import ContactState, HandContact, HandTaxels, HandWrench, TaxelArray  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from rclpy.time import Time  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402
from tf2_ros import Buffer, TransformListener  # noqa: E402
from urdf_parser_py.urdf import URDF  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

from prisma_common.hand import FINGERS, MOTOR_NAMES  # noqa: E402
from prisma_hand_sim.hand_world import HandWorldParams  # noqa: E402
from prisma_hand_sim.sim_objects import OBJECTS  # noqa: E402
from prisma_testing.urdf_kinematics import link_poses  # noqa: E402

HANDS = {"": "", "/left": "left/"}  # namespace -> frame prefix
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


@pytest.mark.launch_test
def generate_test_description():
    # the second hand at the default priority: two control paths at real-time priority would leave
    # this test's own process too little of the two cores to see their messages (below it, at nice
    # 10, beside the load harness's hogs its force estimator never finished loading within a minute)
    return graph_under_test(include_launch("hand.launch.py", sim="true"),
                            include_launch("hand.launch.py", sim="true", namespace="left",
                                           rt_priority="0", nice="0"))


def stamp_ns_of(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def translation(transform) -> np.ndarray:
    t = transform.transform.translation
    return np.array([t.x, t.y, t.z])


class TestHandTf(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.buffer = Buffer(cache_time=Duration(seconds=60))
        # a node and thread of its own: /tf of two hands (200 messages/s) on the probe would crowd the
        # test's own subscriptions out of its executor
        cls.tf_node = ros.rclpy.create_node("test_tf_listener")
        cls.listener = TransformListener(cls.buffer, cls.tf_node, spin_thread=True)

    @classmethod
    def tearDownClass(cls):
        # the listener's spin thread first: left spinning, it raises ExternalShutdownException when
        # rclpy shuts down (tf2_ros stops it only in __del__)
        cls.listener.executor.shutdown()
        cls.listener.dedicated_listener_thread.join()
        cls.listener.unregister()
        cls.tf_node.destroy_node()
        super().tearDownClass()

    def description(self, namespace: str) -> URDF:
        received = []
        self.ros.probe.create_subscription(String, f"{namespace}/robot_description", received.append, LATCHED)
        self.assertTrue(self.ros.spin_until(lambda: received, 60.0), f"no {namespace}/robot_description")
        return URDF.from_xml_string(received[0].data)

    def lookup(self, target: str, source: str, stamp: Time | None = None, timeout_sec: float = 10.0):
        stamp = stamp or Time()
        ok = self.ros.spin_until(lambda: self.buffer.can_transform(target, source, stamp), timeout_sec)
        self.assertTrue(ok, f"no transform {target} <- {source} at {stamp.nanoseconds}")
        return self.buffer.lookup_transform(target, source, stamp)

    def first_messages(self, msg_type, topic: str, count: int = 3) -> list:
        """The first `count` messages on a topic, read one topic at a time: the probe taking all the
        per-finger streams of two hands at once (2000 messages/s) would not keep up with them."""
        received = self.ros.collect(msg_type, topic)
        try:
            self.assertTrue(self.ros.spin_until(lambda: len(received) >= count, 60.0), f"{topic} is silent")
        finally:
            self.ros.stop_collecting(received)
        return received[:count]

    def test_1_every_frame_on_the_hands_messages_has_a_transform_from_its_base(self):
        for namespace, prefix in HANDS.items():
            frames = set()
            for finger in FINGERS:
                for kind, msg_type in (("taxels", TaxelArray), ("wrench", WrenchStamped), ("contact", ContactState)):
                    messages = self.first_messages(msg_type, f"{namespace}/prisma/{finger}/{kind}")
                    frames |= {m.header.frame_id for m in messages}
            frames |= {t.header.frame_id for m in self.first_messages(HandTaxels, f"{namespace}/prisma/hand/taxels")
                       for t in m.samples}
            frames |= {w.header.frame_id for m in self.first_messages(HandWrench, f"{namespace}/prisma/hand/wrench")
                       for w in m.wrenches}
            frames |= {c.header.frame_id for m in self.first_messages(HandContact, f"{namespace}/prisma/hand/contact")
                       for c in m.contacts}
            self.assertEqual(frames, {f"{prefix}prisma_{f}_pad" for f in FINGERS})
            base = f"{prefix}prisma_hand_base"
            for frame in sorted(frames):
                self.lookup(base, frame, timeout_sec=30.0)
            joints = self.first_messages(JointState, f"{namespace}/joint_states")
            moving = {j.name for j in self.description(namespace).joints if j.type != "fixed"}
            self.assertLessEqual({name for m in joints for name in m.name}, moving)

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

    def test_3_during_a_pinch_grasp_the_thumb_pad_moves_as_the_coupling_says(self):
        ros = self.ros
        robot = self.description("")
        client = ros.action_client(Grasp, "/prisma/grasp", wait_sec=60.0)
        joints = ros.collect(JointState, "/joint_states")
        model = ros.collect(JointState, "/prisma/model_joint_states")
        tf = ros.collect(TFMessage, "/tf")
        # the readers matched before the goal: on a busy machine discovery takes longer than a pinch
        self.assertTrue(ros.spin_until(lambda: joints and model and tf, 30.0), "no /joint_states, model or /tf")
        result = ros.result(ros.send_until_started(client, Grasp.Goal(grasp="pinch"), timeout_sec=60.0))
        # everything published up to the result, however late this process receives it: the
        # /joint_states of that instant, and the /tf robot_state_publisher computed from one at most
        # a publish period (50 ms) before it
        ended_ns = stamp_ns(ros.message_at(joints, 0.0))
        self.assertTrue(ros.spin_until(lambda: any(stamp_ns(t) >= ended_ns - 100_000_000
                                                   for m in tf[-3:] for t in m.transforms), 30.0))
        ros.stop_collecting(joints, model, tf)
        self.assertEqual((result.status, result.result.reason), (GoalStatus.STATUS_SUCCEEDED, "force_reached"))
        self.assertEqual({name for m in joints for name in m.name}, set(MOTOR_NAMES))  # the motors, unchanged
        samples = [(m.header.stamp, dict(zip(m.name, m.position))) for m in joints]
        flexing = [(stamp, motors) for stamp, motors in samples if motors["thumb_flexion"] > 0.05]
        self.assertGreater(len(flexing), 20)
        # robot_state_publisher sends the moving frames at most 20 times a second (publish_frequency),
        # each stamped with the joint state it computed them from (tendon_stretch's, one per
        # /joint_states message with its stamp): at those stamps the transform is the description's
        # kinematics at that full joint state
        published = {stamp_ns(t) for m in tf for t in m.transforms if t.child_frame_id == "prisma_thumb_distal"}
        states = {stamp_ns(m): dict(zip(m.name, m.position)) for m in model}
        compared = [(stamp, states[stamp_ns_of(stamp)]) for stamp, motors in flexing
                    if stamp_ns_of(stamp) in published and stamp_ns_of(stamp) in states]
        # the listener has its own subscription to /tf, which a busy machine may have dropped a message
        # of (its lookup then interpolates between the neighbours): give it every one collected here
        for message in tf:
            for transform in message.transforms:
                self.buffer.set_transform(transform, "test_launch_hand_tf")
        self.assertGreater(len(compared), 5)
        for stamp, positions in compared:
            measured = translation(self.lookup("prisma_hand_base", "prisma_thumb_pad", Time.from_msg(stamp)))
            expected = link_poses(robot, positions)["prisma_thumb_pad"][:3, 3]
            np.testing.assert_allclose(measured, expected, atol=1e-6)
        # closing toward the ball, before it touches, the pad travels the simulator's mm per rad of the
        # thumb's tendon angle as drawn: the motor's less the stretch tendon_stretch gives the pad's force
        # (read back from a coupled joint through its mimic; a force estimate lagging on a busy machine
        # still stretches the first samples, and a small estimate before contact stretches every one)
        contact_rad = OBJECTS["pinch_ball"].thumb_contact_rad
        coupled = next(j for j in robot.joints if j.mimic is not None and j.mimic.joint == "thumb_flexion"
                       and j.name.startswith("thumb"))

        def tendon_rad(stamp) -> float:
            drawn = states[stamp_ns_of(stamp)]
            return (drawn[coupled.name] - (coupled.mimic.offset or 0.0)) / coupled.mimic.multiplier

        # at stamps /tf was published for: between two, tf2 interpolates the pad along the chord, and on
        # a busy machine robot_state_publisher's samples can be far apart (7.6 mm/rad measured so)
        near = [(stamp, tendon_rad(stamp)) for stamp, _ in flexing
                if stamp_ns_of(stamp) in states and stamp_ns_of(stamp) in published
                and contact_rad - 1.5 < tendon_rad(stamp) < contact_rad - 0.1]
        self.assertGreaterEqual(len(near), 2, "no /joint_states sample before the thumb's contact angle")
        (first_stamp, first_rad), (last_stamp, last_rad) = near[0], near[-1]
        moved_mm = 1e3 * np.linalg.norm(
            translation(self.lookup("prisma_hand_base", "prisma_thumb_pad", Time.from_msg(last_stamp)))
            - translation(self.lookup("prisma_hand_base", "prisma_thumb_pad", Time.from_msg(first_stamp))))
        turned_rad = last_rad - first_rad
        self.assertGreater(turned_rad, 0.2)
        self.assertAlmostEqual(moved_mm / turned_rad, HandWorldParams().thumb_travel_mm_per_rad,
                               delta=0.05 * HandWorldParams().thumb_travel_mm_per_rad)

    def test_4_after_the_pinch_the_pads_rest_on_the_ball_drawn_between_them(self):
        """Runs on the pinch test_3 ended with (force_reached, the hand holding the ball)."""
        ball_mm = OBJECTS["pinch_ball"].size_mm[2]
        pads = {f: translation(self.lookup("prisma_hand_base", f"prisma_{f}_pad")) for f in ("thumb", "index")}
        apart_mm = 1e3 * np.linalg.norm(pads["thumb"] - pads["index"])
        self.assertAlmostEqual(apart_mm, ball_mm, delta=5.0)
        for namespace, prefix in HANDS.items():
            markers = self.first_messages(Marker, f"{namespace}/prisma/sim/object", count=1)
            self.assertEqual((markers[0].header.frame_id, markers[0].type),
                             (f"{prefix}prisma_hand_base", Marker.SPHERE))
            self.assertAlmostEqual(markers[0].scale.x * 1e3, ball_mm)
        # the root hand's ball: its centre between the two pads (within a few mm: the world's
        # object position is its own, the pads are drawn from the estimated forces)
        p = self.first_messages(Marker, "/prisma/sim/object", count=1)[0].pose.position
        centre = np.array([p.x, p.y, p.z])
        self.assertLess(1e3 * np.linalg.norm(centre - (pads["thumb"] + pads["index"]) / 2), 3.0)


@launch_testing.post_shutdown_test()
class TestHandTfShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
