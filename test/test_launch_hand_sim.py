"""launch_testing: `hand.launch.py sim:=true` brings every hand topic up.

Runs where ROS 2 (rclpy, launch, launch_testing) is installed, e.g. after `colcon build` with
`colcon test` or `launch_test test/test_launch_hand_sim.py`; skips cleanly elsewhere.
"""
from __future__ import annotations

import time
import unittest

import pytest

pytest.importorskip("launch_testing", reason="launch_testing needs ROS 2")
rclpy = pytest.importorskip("rclpy", reason="rclpy needs ROS 2")

import launch  # noqa: E402
import launch_testing.actions  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402
from launch.substitutions import PathJoinSubstitution  # noqa: E402
from launch_ros.substitutions import FindPackageShare  # noqa: E402

FINGERS = ("thumb", "index", "middle", "ring", "little")
TOPICS = (
    [f"/prisma/{f}/taxels" for f in FINGERS]
    + [f"/prisma/{f}/wrench" for f in FINGERS]
    + [f"/prisma/{f}/contact" for f in FINGERS]
    + ["/joint_states", "/diagnostics"]
)


@pytest.mark.launch_test
def generate_test_description():
    hand = launch.actions.IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution(
            [FindPackageShare("prisma_bringup"), "launch", "hand.launch.py"])),
        launch_arguments={"sim": "true"}.items(),
    )
    return launch.LaunchDescription([hand, launch_testing.actions.ReadyToTest()])


class TestHandSimTopics(unittest.TestCase):
    def test_every_topic_publishes(self):
        from rosidl_runtime_py.utilities import get_message

        rclpy.init()
        node = rclpy.create_node("hand_launch_probe")
        seen: set[str] = set()
        try:
            deadline = time.monotonic() + 30.0
            subscribed: set[str] = set()
            while time.monotonic() < deadline and seen != set(TOPICS):
                for name, type_names in node.get_topic_names_and_types():
                    if name in TOPICS and name not in subscribed:
                        node.create_subscription(get_message(type_names[0]), name,
                                                 lambda _msg, n=name: seen.add(n), 10)
                        subscribed.add(name)
                rclpy.spin_once(node, timeout_sec=0.1)
            self.assertEqual(set(TOPICS) - seen, set())
        finally:
            node.destroy_node()
            rclpy.shutdown()
