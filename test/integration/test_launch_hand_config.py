"""hand_config:= in the launch files: what directory motor_driver and force_estimator get as their
`hand_config` parameter (evaluated in-process, no nodes started), and that every launch file that
starts a hand hands the argument on (bimanual.launch.py one per hand).

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import importlib.util

import pytest

from prisma_testing.launch_files import launched_nodes
from prisma_testing.repo_paths import LAUNCH
from prisma_testing.ros_harness import require_ros

require_ros()

from launch import LaunchContext  # noqa: E402
from launch.substitutions import TextSubstitution  # noqa: E402


@pytest.fixture(scope="module")
def hand_launch():
    spec = importlib.util.spec_from_file_location("hand_launch", LAUNCH / "hand.launch.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("given, namespace, simulated, expected", [
    ("auto", "", "False", "{xdg}/prisma_hand/default"),
    ("auto", "left", "False", "{xdg}/prisma_hand/left"),
    ("auto", "left", "True", ""),  # sim:=true or hardware:=emulated: none
    ("none", "left", "False", ""),
    ("{tmp}/pad7", "right", "True", "{tmp}/pad7"),  # given: used in sim as well
])
def test_the_nodes_parameter_follows_the_argument(hand_launch, monkeypatch, tmp_path, given, namespace, simulated,
                                                  expected):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    text = [TextSubstitution(text=t) for t in (given.format(tmp=tmp_path), namespace, simulated)]
    value = hand_launch.HandConfigDir(*text).perform(LaunchContext())
    assert value == expected.format(xdg=tmp_path / "xdg", tmp=tmp_path)


def test_every_motor_driver_and_force_estimator_gets_it():
    nodes = launched_nodes(LAUNCH / "hand.launch.py")
    motor_drivers = [n for n in nodes if n.name == "motor_driver"]
    force_estimators = [n for n in nodes if n.name == "force_estimator"]
    assert len(motor_drivers) == 3  # sim, hardware, emulated
    assert len(force_estimators) == 1
    for node in motor_drivers + force_estimators:
        assert "hand_config" in dict(node.inline_parameters), (node.name, node.line)


@pytest.mark.parametrize("launch_file, declared, handed_on", [
    ("all.launch.py", 'DeclareLaunchArgument("hand_config", default_value="auto"',
     '"hand_config": LaunchConfiguration("hand_config")'),
    # one per hand
    ("bimanual.launch.py", 'DeclareLaunchArgument("left_hand_config", default_value="auto"',
     '"left": LaunchConfiguration("left_hand_config")'),
    ("bimanual.launch.py", 'DeclareLaunchArgument("right_hand_config", default_value="auto"',
     '"right": LaunchConfiguration("right_hand_config")'),
])
def test_the_including_launch_files_hand_it_on(launch_file, declared, handed_on):
    text = (LAUNCH / launch_file).read_text()
    assert declared in text and handed_on in text
