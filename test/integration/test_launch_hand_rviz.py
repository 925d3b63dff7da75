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
import shutil
import subprocess
import tempfile
import time
import unittest
from pathlib import Path

import pytest

from ros_harness import RosHarness, assert_clean_shutdown, include_launch, output_of, require_ros

require_ros()

if shutil.which("Xvfb") is None or shutil.which("rviz2") is None:
    if os.environ.get("PRISMA_ROS_GUI") == "1":
        raise RuntimeError("PRISMA_ROS_GUI=1 but Xvfb or rviz2 is missing: RViz cannot start")
    pytest.skip("RViz needs Xvfb and rviz2: PRISMA_ROS_GUI=1 source ../shared/ros2/setup.sh", allow_module_level=True)

import launch  # noqa: E402
import launch_testing  # noqa: E402
import launch_testing.actions  # noqa: E402
from prisma_msgs.action import Grasp  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

FINGERS = ("thumb", "index", "middle", "ring", "little")
SUCCEEDED = 4
DISPLAY_FILE = Path(tempfile.gettempdir()) / f"prisma_rviz_display_{os.getpid()}"
XVFB: list[subprocess.Popen] = []


def start_display() -> str:
    """A virtual X server of this test's own (Xvfb picks a free display number)."""
    with DISPLAY_FILE.open("w") as out:
        XVFB.append(subprocess.Popen(["Xvfb", "-displayfd", str(out.fileno()), "-screen", "0", "1280x800x24",
                                      "-nolisten", "tcp"], pass_fds=(out.fileno(),), stderr=subprocess.DEVNULL))
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and not DISPLAY_FILE.read_text().strip():
        time.sleep(0.1)
    number = DISPLAY_FILE.read_text().strip()
    assert number, "Xvfb did not start"
    return f":{number}"


@pytest.mark.launch_test
def generate_test_description():
    # RViz, started by the launch, inherits the display from this process
    os.environ["DISPLAY"] = start_display()
    os.environ["LIBGL_ALWAYS_SOFTWARE"] = "1"  # Mesa's software renderer: no GPU here
    return launch.LaunchDescription([include_launch("hand.launch.py", sim="true", rviz="true"),
                                     launch_testing.actions.ReadyToTest()])


class TestHandRviz(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.ros = RosHarness()

    @classmethod
    def tearDownClass(cls):
        cls.ros.shutdown()

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
        result = self.ros.result(self.ros.send_until_accepted(client, Grasp.Goal(grasp="pinch"), timeout_sec=60.0))
        self.assertEqual((result.status, result.result.reason), (SUCCEEDED, "force_reached"))
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
            xvfb.terminate()
            xvfb.wait(timeout=10)
        DISPLAY_FILE.unlink(missing_ok=True)
        assert_clean_shutdown(proc_info, proc_output)
