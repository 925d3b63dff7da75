"""launch_testing: `hand.launch.py namespace:=left` (sim) over DDS: config/<node>.yaml still applies.

A parameter file keyed by the bare node name (`tactile_driver:`) only matches the node at the root
namespace: under `namespace:=left` ROS skips it silently and the node runs on its declared defaults.
config/*.yaml are keyed `/**/<node>:`, which matches the node in any namespace. The YAML values equal
the declared defaults, so reading them back alone proves nothing; the launch therefore first gives
every node, through a `/**:` parameter file of its own (launch_ros SetParametersFromFile: it comes
before the node's parameter files on the command line), one or two values that differ from
config/*.yaml. A node whose YAML applied reads the YAML's value (the later file wins); a node whose
YAML was skipped would read this file's.

Checked through /left/<node>/get_parameters: every parameter of config/<node>.yaml, except those the
launch file sets inline; then the topics are /left/prisma/<finger>/taxels|wrench|contact and
/left/joint_states (/diagnostics stays absolute), the actions /left/prisma/grasp|manipulate and
/left/prisma/motors/move, no other topic of the hand's nodes outside /left; every /diagnostics status
name and hardware ID starts with left/ (a second hand's would not be merged with it); and a pinch Grasp on
/left/prisma/grasp runs through the namespaced graph to force_reached. Every node exits 0 on SIGINT,
no traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os
import tempfile
import unittest
from pathlib import Path

import pytest
import yaml

from prisma_testing.launch_case import (
    GraphTestCase,
    assert_clean_shutdown,
    graph_under_test,
    include_launch,
    installed_parameters,
)
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from launch_ros.actions import SetParametersFromFile  # noqa: E402
from prisma_msgs.action import Grasp  # noqa: E402
from prisma_msgs.msg import TaxelArray  # noqa: E402
from rcl_interfaces.srv import GetParameters  # noqa: E402
from rclpy.action import get_action_server_names_and_types_by_node  # noqa: E402
from rclpy.parameter import parameter_value_to_python  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402

NS = "/left"
NODES = ("tactile_driver", "force_estimator", "motor_driver", "manipulation")
# set by hand.launch.py sim:=true itself, after the parameter files
INLINE = {"tactile_driver": {"backend", "contact_source", "sim_object", "frame_id_format", "object_frame_id"},
          "motor_driver": {"backend", "hand_config"}, "force_estimator": {"model_bundle", "hand_config"},
          "manipulation": {"frame_id_format"}}
# values unlike config/*.yaml, for every node (a node ignores those it does not declare)
DECOYS = {"sim_seed": 7, "rate_hz": 50.0, "batch_window": 0.001, "torch_threads": 2,
          "max_force_n": 2.0, "stale_timeout": 0.25, "position_tolerance": 0.05}
DECOY_FILE = Path(tempfile.gettempdir()) / f"prisma_namespace_decoys_{os.getpid()}.yaml"


@pytest.mark.launch_test
def generate_test_description():
    DECOY_FILE.write_text(yaml.safe_dump({"/**": {"ros__parameters": DECOYS}}))
    return graph_under_test(SetParametersFromFile(str(DECOY_FILE)),
                            include_launch("hand.launch.py", sim="true", namespace="left"))


class TestHandNamespace(GraphTestCase):
    def test_1_yaml_parameters_apply_under_the_namespace(self):
        ros = self.ros
        decoyed = set()
        for node in NODES:
            expected = {k: v for k, v in installed_parameters(node).items() if k not in INLINE[node]}
            request = GetParameters.Request(names=list(expected))
            response = ros.call(GetParameters, f"{NS}/{node}/get_parameters", request, timeout_sec=60.0)
            got = {name: parameter_value_to_python(value) for name, value in zip(expected, response.values)}
            self.assertEqual(got, expected, node)
            decoyed |= set(expected) & set(DECOYS)
        self.assertEqual(decoyed, set(DECOYS))  # every decoy was declared by a node and lost to its YAML

    def test_2_topics_and_actions_follow_the_namespace(self):
        ros = self.ros
        taxels = {f: ros.collect(TaxelArray, f"{NS}/prisma/{f}/taxels") for f in FINGERS}
        self.assertTrue(ros.spin_until(lambda: all(taxels.values()), 60.0),
                        [f for f, msgs in taxels.items() if not msgs])
        expected = ({f"{NS}/prisma/{f}/{kind}" for f in FINGERS for kind in ("taxels", "wrench", "contact")}
                    | {f"{NS}/joint_states", "/diagnostics"})
        self.assertTrue(ros.spin_until(lambda: expected <= {n for n, _ in ros.probe.get_topic_names_and_types()},
                                       30.0))
        # what the hand's nodes publish and subscribe: everything under /left but /diagnostics (and
        # rclpy's own /rosout and /parameter_events)
        outside = set()
        for node in NODES:
            for name, _ in (ros.probe.get_publisher_names_and_types_by_node(node, NS)
                            + ros.probe.get_subscriber_names_and_types_by_node(node, NS)):
                if not name.startswith(f"{NS}/"):
                    outside.add(name)
        self.assertEqual(outside, {"/diagnostics", "/rosout", "/parameter_events"})
        actions = {name for node in NODES
                   for name, _ in get_action_server_names_and_types_by_node(ros.probe, node, NS)}
        self.assertEqual(actions, {f"{NS}/prisma/grasp", f"{NS}/prisma/manipulate", f"{NS}/prisma/gripper_cmd",
                                   f"{NS}/prisma/teleoperate", f"{NS}/prisma/motors/move", f"{NS}/prisma/motors/home"})

    def test_2b_diagnostics_say_which_hand(self):
        """/diagnostics is one topic for every hand: each status name and non-empty hardware ID starts
        with left/ (manipulation's status names no hardware)."""
        ros = self.ros
        diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        drivers = {f"left/{d}" for d in ("tactile_driver", "motor_driver", "force_estimator", "manipulation")}

        def reported() -> dict[str, str]:
            return {s.name: s.hardware_id for m in diagnostics for s in m.status}
        self.assertTrue(ros.spin_until(lambda: {n.split(":")[0] for n in reported()} == drivers, 30.0), reported())
        self.assertEqual(reported()["left/motor_driver: fingers"], "left/sim#1")
        self.assertEqual(reported()["left/tactile_driver: hub"], "left/sim/hand_world/pinch_ball")
        self.assertTrue(all(hw.startswith("left/") for hw in reported().values() if hw), reported())

    def test_3_a_grasp_runs_through_the_namespaced_graph(self):
        ros = self.ros
        client = ros.action_client(Grasp, f"{NS}/prisma/grasp", wait_sec=60.0)
        # once the estimator keeps pace with the motors (the readiness of a just started graph is
        # test_launch_hand_actions' subject, not this one's)
        joints = ros.collect(JointState, f"{NS}/joint_states")
        wrenches = ros.collect(WrenchStamped, f"{NS}/prisma/thumb/wrench")
        ros.wait_until_keeping_up(joints, wrenches, lag_sec=0.05, checks=10, timeout_sec=90.0)
        result = ros.result(ros.send_until_started(client, Grasp.Goal(grasp="pinch"), timeout_sec=60.0))
        self.assertEqual((result.status, result.result.reason), (GoalStatus.STATUS_SUCCEEDED, "force_reached"))


@launch_testing.post_shutdown_test()
class TestHandNamespaceShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        DECOY_FILE.unlink(missing_ok=True)
        assert_clean_shutdown(proc_info, proc_output)
