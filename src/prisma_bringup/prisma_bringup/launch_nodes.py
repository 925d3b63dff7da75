"""What several launch files build alike, in one place they import (launch/*.launch.py run with the
workspace sourced, as they import prisma_common): a node of the control path.

The control path (the drivers, the force estimator, manipulation, the emulator with
hardware:=emulated; the glove and the teleop node in teleop.launch.py) runs on one rung of
prisma_common.scheduling's ladder, set by the launch file's rt_priority:= and nice:= arguments and
applied by each process at start, before its threads exist. test_static_consistency.py reads a
`control_path_node(...)` call as it reads a `Node(...)`: package, executable and parameters must be
literals there as well."""
from __future__ import annotations

from typing import Any

from launch import Condition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from prisma_common.scheduling import NICE_ENV, RT_PRIORITY_ENV


def control_path_env() -> dict[str, Any]:
    """The environment that puts a process on the control path's rung: the launch file's
    rt_priority:= and nice:= arguments (it declares both)."""
    return {RT_PRIORITY_ENV: LaunchConfiguration("rt_priority"), NICE_ENV: LaunchConfiguration("nice")}


def control_path_node(*, package: str, executable: str, namespace: Any, parameters: list[Any],
                      condition: Condition | None = None) -> Node:
    """A node of the control path, named as its executable, in the hand's `namespace`, its output on
    the screen, started where `condition` holds (always without one)."""
    return Node(package=package, executable=executable, name=executable, exec_name=executable,
                namespace=namespace, output="screen", additional_env=control_path_env(), parameters=parameters,
                condition=condition)
