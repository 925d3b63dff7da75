"""What several launch files build alike, in one place they import (launch/*.launch.py run with the
workspace sourced, as they import prisma_common): a node of the control path, and the checks that
make a launch start whole or not at all (launch_refusals.py decides and words them).

Every launch file returns checked_launch_description(declared_arguments, actions): its first action
refuses an argument the (top) launch file does not declare and watches the launch's processes; a
node of the control path (control_path_node, and each action given to required()) that exits on
its own, with a code above 0, shuts the whole launch down, and the launch's last line names it and
its reason (the launch then exits 1). A node killed by a signal from outside (kill -9, the OOM
killer) or stopped with exit 0 does not: the others handle its loss as designed (the servos stop on
their own, goals end sensor_stale), the launch log says `process has died`. Display nodes (RViz,
tactile_markers, tendon_stretch, robot_state_publisher) are not required: one of them dying leaves
the hand running. hand.launch.py also refuses to start beside a hand of its namespace
(refuse_a_second_hand).

The control path (the drivers, the force estimator, manipulation, the emulator with
hardware:=emulated; the glove and the teleop node in teleop.launch.py) runs on one rung of
prisma_common.scheduling's ladder, set by the launch file's rt_priority:= and nice:= arguments and
applied by each process at start, before its threads exist. test_static_consistency.py reads a
`control_path_node(...)` call as it reads a `Node(...)`: package, executable and parameters must be
literals there as well."""
from __future__ import annotations

import time
import weakref
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from launch import Action, Condition, LaunchContext, LaunchDescription, LaunchDescriptionEntity
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit, OnProcessIO, OnProcessStart
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from prisma_bringup.launch_refusals import (
    LaunchRefused,
    nodes_already_running,
    reason_in_output,
    second_hand_refusal,
    stopped_because,
    unknown_arguments,
)
from prisma_common.scheduling import NICE_ENV, RT_PRIORITY_ENV
from prisma_node_wiring.single_instance import DISCOVERY_WAIT_S, POLL_S

# the actions whose process exiting on its own stops the launch (required())
_REQUIRED: weakref.WeakSet[Action] = weakref.WeakSet()
# one watch per running launch (its context): the first launch file to run its checks is the top one
_WATCHES: weakref.WeakKeyDictionary[LaunchContext, _LaunchWatch] = weakref.WeakKeyDictionary()
OUTPUT_LINES_KEPT = 50  # per process, for the reason it gave last
# prisma-hand-emulator's first line, printed once its devices exist (emulator_cli.main):
# hand.launch.py starts the drivers on it (test_launch_start_whole.py reads it from the emulator)
EMULATOR_READY = "emulated hand ("


def control_path_env() -> dict[str, Any]:
    """The environment that puts a process on the control path's rung: the launch file's
    rt_priority:= and nice:= arguments (it declares both)."""
    return {RT_PRIORITY_ENV: LaunchConfiguration("rt_priority"), NICE_ENV: LaunchConfiguration("nice")}


def control_path_node(*, package: str, executable: str, namespace: Any, parameters: list[Any],
                      condition: Condition | None = None) -> Node:
    """A node of the control path, named as its executable, in the hand's `namespace`, its output on
    the screen, started where `condition` holds (always without one)."""
    return required(Node(package=package, executable=executable, name=executable, exec_name=executable,
                         namespace=namespace, output="screen", additional_env=control_path_env(),
                         parameters=parameters, condition=condition))


def required(action: Action) -> Any:
    """`action` (a Node or ExecuteProcess) made one the launch cannot run without: its process exiting
    on its own stops the launch (the module says how)."""
    _REQUIRED.add(action)
    return action


class _LaunchWatch:
    """The processes of one launch: the lines each said last, and why the launch stops."""

    def __init__(self, launch_file: str) -> None:
        self.launch_file = launch_file
        self.started_s: dict[int, float] = {}  # pid -> monotonic start
        self.output: dict[int, deque[str]] = {}
        self.cause: str | None = None

    def handlers(self) -> list[Any]:
        return [OnProcessStart(on_start=self.started),
                OnProcessIO(on_stdout=self.heard, on_stderr=self.heard),
                OnProcessExit(on_exit=self.exited)]

    def started(self, event: Any, _context: LaunchContext) -> None:
        self.started_s[event.pid] = time.monotonic()

    def heard(self, event: Any) -> None:
        lines = self.output.setdefault(event.pid, deque(maxlen=OUTPUT_LINES_KEPT))
        lines.extend(event.text.decode(errors="replace").splitlines())

    def exited(self, event: Any, context: LaunchContext) -> list[LaunchDescriptionEntity]:
        started = self.started_s.pop(event.pid, time.monotonic())
        said = list(self.output.pop(event.pid, ()))
        if self.cause is None and not context.is_shutdown and event.action in _REQUIRED and event.returncode > 0:
            self.cause = stopped_because(self.launch_file, _node_name(event), event.returncode,
                                         time.monotonic() - started, reason_in_output(said))
            if self.started_s:
                return [EmitEvent(event=Shutdown(reason=self.cause))]
        if self.cause is not None and not self.started_s:
            # the last process of the launch is gone: this handler runs after every other one of
            # the event (registered last), and launch ends a run whose handler raised with exit 1
            # and this line last
            raise LaunchRefused(self.cause)
        return []


def _node_name(event: Any) -> str:
    """The exited process's node (fully qualified), else its process name without launch's -<n>."""
    try:
        name = event.action.node_name
    except Exception:  # an ExecuteProcess, or a Node launch has not named
        name = None
    if isinstance(name, str) and not name.endswith("<node_name_unspecified>"):
        return name.lstrip("/") if name.count("/") == 1 else name
    return event.process_name.rsplit("-", 1)[0]


def _check_and_watch(context: LaunchContext, declared: Sequence[str]) -> None:
    """The first of a launch's files to run this is the one `ros2 launch` was given: its arguments
    are the launch configurations set so far (ros2 launch sets each `name:=value` before the file's
    first action runs). The launch's processes are watched from here on."""
    if context in _WATCHES:
        return  # an included file: its arguments are the including file's to give
    launch_file = Path(context.locals.current_launch_file_path).name
    refusal = unknown_arguments(launch_file, context.launch_configurations.keys(), declared)
    if refusal is not None:
        raise LaunchRefused(refusal)
    watch = _WATCHES[context] = _LaunchWatch(launch_file)
    for handler in watch.handlers():
        context.register_event_handler(handler, append=True)  # after the processes' own handlers


def checked_launch_description(declared: list[DeclareLaunchArgument], actions: list[Any]) -> LaunchDescription:
    """A launch file's description: its arguments checked (before their defaults are set) and its
    processes watched, then `declared`, then `actions`."""
    names = [argument.name for argument in declared]
    check: Callable[..., None] = _check_and_watch
    return LaunchDescription([OpaqueFunction(function=check, args=[names]), *declared, *actions])


def once_said(process: Action, line_start: str, actions: list[Any], condition: Condition | None = None) -> Action:
    """An action that starts `actions` once `process` prints a line beginning with `line_start` on its
    stdout (a device server saying its devices exist), once; where `condition` holds."""
    said: list[bool] = []

    def heard(event: Any) -> list[Any] | None:
        lines = event.text.decode(errors="replace").splitlines()
        if said or not any(line.startswith(line_start) for line in lines):
            return None
        said.append(True)
        return actions

    return RegisterEventHandler(OnProcessIO(target_action=process, on_stdout=heard), condition=condition)


def refuse_a_second_hand(namespace: Any, node_names: Callable[[LaunchContext], list[str]]) -> OpaqueFunction:
    """An action that refuses the launch, before any node of it starts, when a node of
    `node_names(context)` (the hand's nodes this launch would start) already runs in `namespace`:
    a second tactile_driver would publish on the first hand's topics. It looks as a node of the
    hand looks for another of its kind, in a ROS context of its own that it closes again."""

    def check(context: LaunchContext) -> None:
        import rclpy
        from rclpy.context import Context

        names = node_names(context)
        ns = namespace.perform(context)
        ros = Context()
        rclpy.init(args=[], context=ros)  # not sys.argv: its name:=value would be remap rules
        try:
            node = rclpy.create_node("prisma_launch_second_hand_check", context=ros,
                                     enable_rosout=False, start_parameter_services=False)
            try:
                # as long as a node looks for another of its kind (single_instance says why), the whole
                # time: discovery shows the running hand's nodes one by one, and the refusal names all it saw
                deadline = time.monotonic() + DISCOVERY_WAIT_S
                seen: set[str] = set()
                while True:
                    seen.update(f"{n_ns.rstrip('/')}/{n}" for n, n_ns in node.get_node_names_and_namespaces())
                    if time.monotonic() >= deadline:
                        break
                    time.sleep(POLL_S)
                running = nodes_already_running(seen, ns, names)
                if running:
                    launch_file = Path(context.locals.current_launch_file_path).name
                    raise LaunchRefused(second_hand_refusal(launch_file, ns, running))
            finally:
                node.destroy_node()
        finally:
            rclpy.try_shutdown(context=ros)

    return OpaqueFunction(function=check)
