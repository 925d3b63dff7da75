"""A launch test's class that reads the hand's frames through tf2 as a ROS tool does: a
TransformListener on a node and thread of its own, the description from robot_description, the first
messages of a topic, and the frames of a hand's messages with their transforms (test_launch_hand_tf,
test_launch_two_hands_tf)."""
from __future__ import annotations

from typing import Any

from prisma_common.hand import FINGERS
from prisma_testing.launch_case import GraphTestCase
from prisma_testing.ros_harness import RosHarness


class TfTestCase(GraphTestCase):
    buffer: Any
    listener: Any
    tf_node: Any

    @classmethod
    def subscribe(cls, ros: RosHarness) -> None:
        from rclpy.duration import Duration
        from tf2_ros import Buffer, TransformListener

        cls.buffer = Buffer(cache_time=Duration(seconds=60))
        # a node and thread of its own: /tf on the probe would crowd the test's own subscriptions out
        # of its executor
        cls.tf_node = ros.rclpy.create_node("test_tf_listener")
        cls.listener = TransformListener(cls.buffer, cls.tf_node, spin_thread=True)

    @classmethod
    def tearDownClass(cls) -> None:
        # the listener's spin thread first: left spinning, it raises ExternalShutdownException when
        # rclpy shuts down (tf2_ros stops it only in __del__)
        cls.listener.executor.shutdown()
        cls.listener.dedicated_listener_thread.join()
        cls.listener.unregister()
        cls.tf_node.destroy_node()
        super().tearDownClass()

    def description(self, namespace: str) -> Any:
        """The URDF a hand's robot_state_publisher latches on <namespace>/robot_description."""
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import String
        from urdf_parser_py.urdf import URDF

        received: list = []
        self.ros.probe.create_subscription(String, f"{namespace}/robot_description", received.append,
                                           QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.assertTrue(self.ros.spin_until(lambda: received, 60.0), f"no {namespace}/robot_description")
        return URDF.from_xml_string(received[0].data)

    def lookup(self, target: str, source: str, stamp: Any = None, timeout_sec: float = 10.0) -> Any:
        from rclpy.time import Time

        stamp = stamp or Time()
        ok = self.ros.spin_until(lambda: self.buffer.can_transform(target, source, stamp), timeout_sec)
        self.assertTrue(ok, f"no transform {target} <- {source} at {stamp.nanoseconds}")
        return self.buffer.lookup_transform(target, source, stamp)

    def first_messages(self, msg_type: type, topic: str, count: int = 3) -> list:
        """The first `count` messages on a topic, read one topic at a time: the probe taking all the
        per-finger streams at once (1000 messages/s a hand) would not keep up with them."""
        received = self.ros.collect(msg_type, topic)
        try:
            self.assertTrue(self.ros.spin_until(lambda: len(received) >= count, 60.0), f"{topic} is silent")
        finally:
            self.ros.stop_collecting(received)
        return received[:count]

    def frames_with_a_transform(self, namespace: str, prefix: str) -> set[str]:
        """The frame ids on a hand's messages (per-finger and per-hand taxels, wrench, contact), each
        looked up from `prefix`prisma_hand_base through tf2; asserts that its /joint_states name only
        moving joints of its description."""
        from geometry_msgs.msg import WrenchStamped
        from prisma_msgs.msg import ContactState, HandContact, HandTaxels, HandWrench, TaxelArray
        from sensor_msgs.msg import JointState

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
        base = f"{prefix}prisma_hand_base"
        for frame in sorted(frames):
            self.lookup(base, frame, timeout_sec=30.0)
        joints = self.first_messages(JointState, f"{namespace}/joint_states")
        moving = {j.name for j in self.description(namespace).joints if j.type != "fixed"}
        self.assertLessEqual({name for m in joints for name in m.name}, moving)
        return frames
