"""launch_testing: every parameter of every node of `hand.launch.py` (sim) and `glove.launch.py`,
read back as `ros2 param describe` reads it (the nodes' list_parameters and describe_parameters
services):

- each has a description; each integer or double a range (IntegerRange / FloatingPointRange) that
  holds its value; each string naming one of a fixed set (backend, contact_source, ...) its choices
  in additional_constraints, its value among them; and for the suite's nodes whose config class is
  known here, every descriptor is the one its ParameterSpec says (description and unit, bounds,
  constraints, read_only unless live);
- setting a read-only parameter of any node is refused with rclpy's reason; setting k outside its
  range is refused by rclpy's range check, inside it accepted;
- every node exits 0 on SIGINT, no traceback.

The nodes are those the two launch files start (their `name=` literals), less the third-party
nodes listed in THIRD_PARTY, so a node added to a launch file is checked from then on.
Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import unittest

import pytest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, graph_under_test, include_launch
from prisma_testing.launch_files import launched_nodes
from prisma_testing.repo_paths import LAUNCH
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from rcl_interfaces.msg import ParameterType  # noqa: E402
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters  # noqa: E402
from rclpy.parameter import parameter_value_to_python  # noqa: E402

from prisma_force_estimator.node_config import ForceEstimatorConfig  # noqa: E402
from prisma_manipulation.node_config import ManipulationConfig  # noqa: E402
from prisma_motor_driver.node_config import MotorDriverConfig  # noqa: E402
from prisma_node_wiring.node_parameters import parameter_descriptor  # noqa: E402
from prisma_tactile_driver.node_config import TactileDriverConfig  # noqa: E402
from stag_glove.node_config import GloveDriverConfig, GlovePerceptionConfig  # noqa: E402

LAUNCH_FILES = ("hand.launch.py", "glove.launch.py")
# packages (and node names) of nodes the launch files start that are not this suite's: not checked here
THIRD_PARTY = {"robot_state_publisher", "rviz2"}
RCLPY_OWN = {"use_sim_time", "start_type_description_service"}  # declared by rclpy itself
CONFIGS = {"tactile_driver": TactileDriverConfig, "force_estimator": ForceEstimatorConfig,
           "motor_driver": MotorDriverConfig, "manipulation": ManipulationConfig,
           "glove_driver": GloveDriverConfig, "glove_perception": GlovePerceptionConfig}
# strings that name one of a fixed set: each must list its choices
ENUMS = {"tactile_driver": {"backend", "contact_source"}, "motor_driver": {"backend"},
         "force_estimator": {"network_precision"}, "manipulation": {"monitored_finger"},
         "glove_driver": {"backend"}, "glove_perception": {"selection"}}
CHOICES = "one of: "


def launched_node_names() -> set[str]:
    """The name of every node of this suite the launch files start (a node of a THIRD_PARTY package
    is left out whatever its name)."""
    names = set()
    for launch_file in LAUNCH_FILES:
        for node in launched_nodes(LAUNCH / launch_file):
            if node.package in THIRD_PARTY:
                continue
            assert node.name is not None, f"{launch_file}:{node.line}: Node without a literal name"
            names.add(node.name)
    return names


NODES = sorted(launched_node_names() - THIRD_PARTY)


@pytest.mark.launch_test
def generate_test_description():
    return graph_under_test(include_launch("hand.launch.py", sim="true"), include_launch("glove.launch.py"))


def choices_of(descriptor) -> list[str]:
    """The choices listed in additional_constraints ("one of: a, b; ...")."""
    first = descriptor.additional_constraints.split("; ")[0]
    return first[len(CHOICES):].split(", ") if first.startswith(CHOICES) else []


class TestParameterDescriptions(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.described: dict[str, dict] = {}
        cls.values: dict[str, dict] = {}
        for node in NODES:
            names = ros.call(ListParameters, f"/{node}/list_parameters", ListParameters.Request(),
                             timeout_sec=90.0).result.names
            names = [n for n in names if n not in RCLPY_OWN]
            descriptors = ros.call(DescribeParameters, f"/{node}/describe_parameters",
                                   DescribeParameters.Request(names=names), timeout_sec=30.0).descriptors
            values = ros.call(GetParameters, f"/{node}/get_parameters", GetParameters.Request(names=names),
                              timeout_sec=30.0).values
            cls.described[node] = {d.name: d for d in descriptors}
            cls.values[node] = {n: parameter_value_to_python(v) for n, v in zip(names, values)}

    def test_1_the_suites_nodes_of_both_launch_files_are_checked(self):
        self.assertLessEqual(set(CONFIGS), set(NODES))
        for node in NODES:
            # tendon_stretch has two: its tendon and how old a force may be
            self.assertGreaterEqual(len(self.described[node]), 2 if node == "tendon_stretch" else 6, node)

    def test_2_every_parameter_has_a_description_numbers_a_range_enums_their_choices(self):
        problems = []
        for node in NODES:
            for name, d in self.described[node].items():
                value = self.values[node][name]
                where = f"{node} {name}"
                if not d.description.strip():
                    problems.append(f"{where}: no description")
                if d.type == ParameterType.PARAMETER_DOUBLE:
                    ranges = [(r.from_value, r.to_value) for r in d.floating_point_range]
                    if len(ranges) != 1 or d.integer_range or not ranges[0][0] <= value <= ranges[0][1]:
                        problems.append(f"{where} = {value}: floating_point_range {ranges}")
                elif d.type == ParameterType.PARAMETER_INTEGER:
                    ranges = [(r.from_value, r.to_value) for r in d.integer_range]
                    if len(ranges) != 1 or d.floating_point_range or not ranges[0][0] <= value <= ranges[0][1]:
                        problems.append(f"{where} = {value}: integer_range {ranges}")
                elif d.floating_point_range or d.integer_range:
                    problems.append(f"{where}: a range on a parameter of type {d.type}")
                if name in ENUMS.get(node, ()) and not choices_of(d):
                    problems.append(f"{where}: a string naming one of a fixed set without its choices")
                if choices_of(d) and value not in choices_of(d):
                    problems.append(f"{where} = {value!r}: not one of its choices {choices_of(d)}")
        self.assertEqual(problems, [])

    def test_3_descriptors_are_those_the_config_specs_say(self):
        for node, config_class in CONFIGS.items():
            specs = config_class.parameter_specs()
            defaults = config_class().as_parameters()
            self.assertEqual(set(self.described[node]), set(specs), node)
            for name, d in self.described[node].items():
                expected = parameter_descriptor(name, specs[name], defaults[name])
                got = (d.description, d.additional_constraints, d.read_only,
                       [(r.from_value, r.to_value, r.step) for r in d.floating_point_range],
                       [(r.from_value, r.to_value, r.step) for r in d.integer_range])
                want = (expected.description, expected.additional_constraints, expected.read_only,
                        [(r.from_value, r.to_value, r.step) for r in expected.floating_point_range],
                        [(r.from_value, r.to_value, r.step) for r in expected.integer_range])
                self.assertEqual(got, want, f"{node} {name}")

    def test_4_a_read_only_parameter_is_refused_with_a_reason(self):
        for node in NODES:
            read_only = sorted(name for name, d in self.described[node].items() if d.read_only)
            self.assertTrue(read_only, f"{node} has no read-only parameter")
            name = read_only[0]
            (result,) = self.ros.set_parameters(f"/{node}", **{name: self.values[node][name]})
            self.assertEqual((result.successful, result.reason),
                             (False, f"Trying to set a read-only parameter: {name}."), node)

    def test_5_k_outside_its_range_is_refused_by_rclpy_inside_accepted(self):
        (outside,) = self.ros.set_parameters("/manipulation", k=1.6)
        self.assertEqual((outside.successful, outside.reason),
                         (False, "Parameter k out of range Min: 0.0, Max: 1.5, value: 1.6"))
        (inside,) = self.ros.set_parameters("/manipulation", k=0.75)
        self.assertTrue(inside.successful, inside.reason)
        response = self.ros.call(GetParameters, "/manipulation/get_parameters", GetParameters.Request(names=["k"]))
        self.assertEqual(parameter_value_to_python(response.values[0]), 0.75)


@launch_testing.post_shutdown_test()
class TestParametersShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
