"""launch_testing: `hand.launch.py sim:=true rviz:=true` on a virtual X server: RViz with the shipped
configuration (config/hand.rviz) on the sim graph.

RViz comes up and subscribes to what its displays show (the description, TF, the tactile markers,
the five pads' wrenches); the tactile_markers node, idle until then, starts drawing for it; a pinch
Grasp runs with RViz beside the graph; and RViz's own log has no error, no warning, no "No
transform" and no message its TF filter dropped: every display loaded and found its frames (the
Wrench displays wait for the transform of each wrench's pad frame at the wrench's stamp).

Needs Xvfb and the Qt/GL libraries (`PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh`); skips
without them or ROS 2 (fails under PRISMA_REQUIRE_ROS=1, or PRISMA_ROS_GUI=1 for the display).
"""
from __future__ import annotations

import os
import subprocess
import unittest

import pytest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, graph_under_test, include_launch, output_of
from prisma_testing.ros_harness import require_ros
from prisma_testing.virtual_display import require_rviz, start_display, stop_display

require_ros()
require_rviz()

import launch_testing  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from prisma_msgs.action import Grasp  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402

XVFB: list[subprocess.Popen] = []


@pytest.mark.launch_test
def generate_test_description():
    # RViz, started by the launch, inherits the display from this process
    display, xvfb = start_display()
    XVFB.append(xvfb)
    os.environ["DISPLAY"] = display
    os.environ["LIBGL_ALWAYS_SOFTWARE"] = "1"  # Mesa's software renderer: no GPU here
    return graph_under_test(include_launch("hand.launch.py", sim="true", rviz="true"))


class TestHandRviz(GraphTestCase):
    def rviz_subscriptions(self) -> set[str]:
        nodes = self.ros.probe.get_node_names_and_namespaces()
        return {name for node, namespace in nodes if node == "rviz2"
                for name, _ in self.ros.probe.get_subscriber_names_and_types_by_node(node, namespace)}

    def test_1_rviz_reads_the_model_tf_markers_and_the_wrenches(self):
        wanted = {"/robot_description", "/prisma/tactile_markers"} | {f"/prisma/{f}/wrench" for f in FINGERS}
        self.assertTrue(self.ros.spin_until(lambda: wanted <= self.rviz_subscriptions(), 120.0),
                        sorted(wanted - self.rviz_subscriptions()))
        # RViz's TF listener is a node of its own (transform_listener_impl_<address>); nothing else here reads TF
        tf_readers = {info.node_name for topic in ("/tf", "/tf_static")
                      for info in self.ros.probe.get_subscriptions_info_by_topic(topic)}
        self.assertTrue(any(name.startswith("transform_listener_impl") for name in tf_readers), tf_readers)
        # tactile_markers draws for RViz: MarkerArrays flow (and our probe is not the first watcher)
        markers = self.ros.collect(MarkerArray, "/prisma/tactile_markers")
        self.assertTrue(self.ros.spin_until(lambda: len(markers) >= 10, 30.0))
        self.assertEqual({m.ns for a in markers for m in a.markers}, set(FINGERS))

    def test_2_a_pinch_grasp_with_rviz_beside_the_graph(self):
        client = self.ros.action_client(Grasp, "/prisma/grasp", wait_sec=60.0)
        result = self.ros.result(self.ros.send_until_started(client, Grasp.Goal(grasp="pinch"), timeout_sec=60.0))
        self.assertEqual((result.status, result.result.reason), (GoalStatus.STATUS_SUCCEEDED, "force_reached"))
        self.ros.spin_for(5.0)  # RViz draws the hand holding the ball


@launch_testing.post_shutdown_test()
class TestHandRvizShutdown(unittest.TestCase):
    def test_rviz_logged_no_error_warning_or_missing_transform(self, proc_output):
        log = output_of(proc_output, "rviz2")
        self.assertIn("OpenGl version", log)  # it rendered
        problems = [line for line in log.splitlines()
                    if any(mark in line for mark in ("[ERROR]", "[WARN]", "No transform", "dropping message"))]
        self.assertEqual(problems, [])

    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        for xvfb in XVFB:
            stop_display(xvfb)
        assert_clean_shutdown(proc_info, proc_output)
