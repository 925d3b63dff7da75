"""launch_testing: `all.launch.py` (defaults: simulated hand and glove) over DDS.

Both halves start: the six nodes (tactile_driver, force_estimator, motor_driver, manipulation,
glove_driver, glove_perception) are in the graph, every hand topic (taxels, wrench and contact of
each finger, /joint_states) and every glove topic (/stag/frame, /stag/image, /stag/hand_pose,
/stag/weight, /stag/object) delivers messages, and /diagnostics comes from all four drivers.
Every node exits 0 on SIGINT, no traceback; the motor driver logs that it turned the torque off.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import unittest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test, output_of
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from prisma_msgs.msg import ContactState, GloveFrame, ObjectEstimate, TaxelArray, WeightEstimate  # noqa: E402
from sensor_msgs.msg import Image, JointState  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402

NODES = {"tactile_driver", "force_estimator", "motor_driver", "manipulation", "glove_driver", "glove_perception"}
TOPICS = ({f"/prisma/{f}/taxels": TaxelArray for f in FINGERS}
          | {f"/prisma/{f}/wrench": WrenchStamped for f in FINGERS}
          | {f"/prisma/{f}/contact": ContactState for f in FINGERS}
          | {"/joint_states": JointState, "/stag/frame": GloveFrame, "/stag/image": Image,
             "/stag/hand_pose": ObjectEstimate, "/stag/weight": WeightEstimate, "/stag/object": ObjectEstimate})
DRIVERS = {"tactile_driver", "force_estimator", "motor_driver", "manipulation", "glove_driver"}


generate_test_description = launch_test("all.launch.py")


class TestAll(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.received = {topic: ros.collect(msg_type, topic) for topic, msg_type in TOPICS.items()}
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")

    def test_hand_and_glove_nodes_and_topics(self):
        ros, received = self.ros, self.received

        def drivers() -> set[str]:
            return {s.name.split(":")[0] for m in self.diagnostics for s in m.status}

        ros.spin_until(lambda: all(received.values()) and drivers() == DRIVERS, 90.0)
        self.assertEqual([topic for topic, msgs in received.items() if not msgs], [])
        self.assertEqual(drivers(), DRIVERS)
        nodes = {(name, namespace) for name, namespace in ros.probe.get_node_names_and_namespaces()}
        self.assertLessEqual({(name, "/") for name in NODES}, nodes)


@launch_testing.post_shutdown_test()
class TestAllShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
        # and robot_state_publisher, tendon_stretch and tactile_markers beside the hand's nodes
        self.assertEqual(len(proc_info.process_names()), len(NODES) + 3)
        torque_off = "torque off: fingers, thumb_flexion, thumb_rotation"
        self.assertIn(torque_off, output_of(proc_output, "motor_driver"))
