"""Running nodes under test on real rclpy over DDS.

`require_ros()` at the top of a test module skips it (with the reason) where ROS 2 or the built
workspace is not sourced; with PRISMA_REQUIRE_ROS=1 (set by CI when it sources ROS) it fails instead,
so a broken build can never pass as "skipped".

`RosHarness` (the `ros` fixture of conftest.py) owns one initialised rclpy context per test, a
single-threaded executor spinning every node of the test and a probe node for the test's own
publishers, subscriptions, service and action clients. Time: nodes made with `sim_time=True` run on
a /clock the harness publishes (`set_time`, `advance`), so stamps and timer instants are exact;
everything else runs on wall time and is awaited with `spin_until`.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pytest

ROS_SKIP_REASON = (
    "needs ROS 2 and the built workspace: source ../shared/ros2/setup.sh (or /opt/ros/jazzy), "
    "colcon build, source install/setup.bash"
)


def _ros_import_error() -> str | None:
    try:
        import rclpy  # noqa: F401
    except ImportError as exc:
        return f"rclpy not importable ({exc})"
    try:
        import prisma_msgs.msg  # noqa: F401
    except ImportError as exc:
        return f"prisma_msgs not importable ({exc}): build and source the workspace"
    return None


ROS_IMPORT_ERROR = _ros_import_error()
ROS_AVAILABLE = ROS_IMPORT_ERROR is None


def require_ros() -> None:
    """Skip the calling test module where ROS is absent (fail instead under PRISMA_REQUIRE_ROS=1)."""
    if ROS_AVAILABLE:
        return
    if os.environ.get("PRISMA_REQUIRE_ROS") == "1":
        raise RuntimeError(f"PRISMA_REQUIRE_ROS=1 but {ROS_IMPORT_ERROR}")
    pytest.skip(f"{ROS_SKIP_REASON} [{ROS_IMPORT_ERROR}]", allow_module_level=True)


def process_domain_id() -> int:
    """A DDS domain of this test process: concurrent test runs on one machine do not see each other.

    setup.sh hands shells domains 1-100; tests take 101-230 by process id (Cyclone allows 0-232).
    """
    return 101 + os.getpid() % 130




def stamp_ns(msg: Any) -> int:
    """Nanoseconds of a message's header stamp."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class RosHarness:
    """One test's ROS world: context, executor, probe node, sim clock, /rosout log capture."""

    START_NS = 1_700_000_000 * 10**9  # where sim time starts: far from 0 like a real clock

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.rclpy = rclpy
        rclpy.init()
        self.executor = SingleThreadedExecutor()
        self.nodes: list = []
        self.sim_nodes: list = []
        self._sim_now: int | None = None
        self._probe = None
        self._clock_pub = None
        self._publishers: dict = {}
        self._clients: dict = {}
        self._log: list | None = None

    # ---- nodes -----------------------------------------------------------------------------
    def node(self, cls: Callable[..., Any], params: dict[str, Any] | None = None,
             params_files: Iterable[str | Path] = (), sim_time: bool = False, **kwargs):
        """Construct a node as `ros2 run` would (params files, then overrides) and spin it.

        Raises what the node's constructor raises (a ParameterError for a bad parameter).
        """
        from rclpy.parameter import Parameter

        overrides = [Parameter(name, value=value) for name, value in (params or {}).items()]
        if sim_time:
            overrides.append(Parameter("use_sim_time", value=True))
        cli_args = []
        for path in params_files:
            cli_args += ["--params-file", str(path)]
        if cli_args:
            kwargs["cli_args"] = ["--ros-args", *cli_args]
        node = cls(parameter_overrides=overrides, **kwargs)
        self.executor.add_node(node)
        self.nodes.append(node)
        if sim_time:
            self.sim_nodes.append(node)
            if self._sim_now is None:
                self.set_time(self.START_NS)
            else:
                self._wait_for_clock(node, self._sim_now)
        return node

    @property
    def probe(self):
        """The test's own node (wall time): its publishers, subscriptions and clients."""
        if self._probe is None:
            self._probe = self.rclpy.create_node("test_probe")
            self.executor.add_node(self._probe)
        return self._probe

    # ---- spinning --------------------------------------------------------------------------
    def spin_once(self, timeout_sec: float = 0.01) -> None:
        self.executor.spin_once(timeout_sec=timeout_sec)

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for `seconds` of wall time."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            self.executor.spin_once(timeout_sec=min(0.01, left))

    def spin_until(self, condition: Any, timeout_sec: float = 10.0) -> bool:
        """Process callbacks until `condition()` (or a Future) is true; False after the timeout."""
        done = condition.done if hasattr(condition, "done") else condition
        end = time.monotonic() + timeout_sec
        while not done() and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)
        return bool(done())

    # ---- sim time --------------------------------------------------------------------------
    def now_ns(self) -> int:
        """Sim time once a sim-time node exists, else wall time."""
        return self._sim_now if self._sim_now is not None else time.time_ns()

    def set_time(self, stamp_ns: int) -> None:
        """Publish /clock = stamp_ns and wait until every sim-time node's clock reads it."""
        from rosgraph_msgs.msg import Clock

        from builtin_interfaces.msg import Time

        if self._clock_pub is None:
            from rclpy.qos import QoSProfile

            self._clock_pub = self.probe.create_publisher(Clock, "/clock", QoSProfile(depth=10))
        self._sim_now = stamp_ns
        msg = Clock(clock=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9))
        deadline = time.monotonic() + 10.0
        for node in self.sim_nodes:
            while node.get_clock().now().nanoseconds < stamp_ns:
                if time.monotonic() > deadline:
                    raise TimeoutError(f"{node.get_name()} never saw /clock = {stamp_ns}")
                self._clock_pub.publish(msg)  # again: the first may precede discovery
                self.executor.spin_once(timeout_sec=0.005)
        # let the timers that became due at this instant run before time moves on
        for _ in range(3):
            self.executor.spin_once(timeout_sec=0.0)

    def _wait_for_clock(self, node, stamp_ns: int) -> None:
        self.set_time(stamp_ns)

    def advance(self, seconds: float, step: float = 0.001,
                until: Callable[[], bool] | None = None) -> None:
        """Move sim time forward by `seconds` in `step`s, letting due timers run at each step."""
        target = self.now_ns() + round(seconds * 1e9)
        step_ns = round(step * 1e9)
        while self._sim_now < target:
            self.set_time(min(self._sim_now + step_ns, target))
            if until is not None and until():
                return

    # ---- topics, services, actions ---------------------------------------------------------
    def collect(self, msg_type: type, topic: str, qos_profile: Any = None) -> list:
        """A list that fills with every message received on `topic` (depth 1000: bursts fit)."""
        from rclpy.qos import QoSProfile

        received: list = []
        self.probe.create_subscription(msg_type, topic, received.append, qos_profile or QoSProfile(depth=1000))
        return received

    def publisher(self, msg_type: type, topic: str, qos_profile: Any = 10):
        return self.probe.create_publisher(msg_type, topic, qos_profile)

    def publish(self, topic: str, msg: Any, wait_for_subscribers: int = 1) -> None:
        """Publish on `topic` from the probe, first waiting until that many subscribers matched."""
        key = (topic, type(msg))
        if key not in self._publishers:
            self._publishers[key] = self.publisher(type(msg), topic, 1000)
        pub = self._publishers[key]
        if not self.spin_until(lambda: pub.get_subscription_count() >= wait_for_subscribers, 10.0):
            raise TimeoutError(f"no subscriber on {topic}")
        pub.publish(msg)

    def call(self, srv_type: type, name: str, request: Any, timeout_sec: float = 10.0):
        """Call a service and return its response (TimeoutError when none comes)."""
        key = (name, srv_type)
        if key not in self._clients:
            self._clients[key] = self.probe.create_client(srv_type, name)
        client = self._clients[key]
        if not self.spin_until(client.service_is_ready, timeout_sec):
            raise TimeoutError(f"service {name} not available")
        future = client.call_async(request)
        if not self.spin_until(future, timeout_sec):
            raise TimeoutError(f"service {name} did not answer within {timeout_sec} s")
        return future.result()

    def set_parameters(self, node_name: str, **values: Any):
        """Set parameters through the node's ~/set_parameters service, as `ros2 param set` does."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg() for name, value in values.items()])
        return self.call(SetParameters, f"{node_name}/set_parameters", request).results

    def action_client(self, action_type: type, name: str, wait_sec: float = 10.0):
        from rclpy.action import ActionClient

        client = ActionClient(self.probe, action_type, name)
        if not self.spin_until(client.server_is_ready, wait_sec):
            raise TimeoutError(f"action server {name} not available")
        return client

    def send_goal(self, client: Any, goal: Any, feedback: list | None = None, timeout_sec: float = 10.0):
        """Send a goal and return its ClientGoalHandle once the server answered (accepted or not)."""
        future = client.send_goal_async(goal, feedback_callback=feedback.append if feedback is not None else None)
        if not self.spin_until(future, timeout_sec):
            raise TimeoutError("no answer to the goal request")
        return future.result()

    def result(self, handle: Any, timeout_sec: float = 30.0, sim_step: float | None = None):
        """Wait for an accepted goal's result (advancing sim time by `sim_step` if given)."""
        future = handle.get_result_async()
        if sim_step is not None:
            deadline = time.monotonic() + timeout_sec
            while not future.done() and time.monotonic() < deadline:
                self.advance(sim_step)
        elif not self.spin_until(future, timeout_sec):
            pass
        if not future.done():
            raise TimeoutError(f"no result within {timeout_sec} s")
        return future.result()

    # ---- logs ------------------------------------------------------------------------------
    def capture_logs(self) -> None:
        """Start collecting /rosout (call before the nodes log what the test wants to see)."""
        if self._log is None:
            from rcl_interfaces.msg import Log
            from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

            qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self._log = self.collect(Log, "/rosout", qos)

    def logs(self, severity: str | None = None, name: str | None = None, contains: str | None = None) -> list[str]:
        """Messages logged so far (after `capture_logs`), filtered by severity, logger name, text."""
        from rcl_interfaces.msg import Log

        if self._log is None:
            raise RuntimeError("call ros.capture_logs() before the nodes log")
        levels = {"debug": Log.DEBUG, "info": Log.INFO, "warn": Log.WARN, "warning": Log.WARN,
                  "error": Log.ERROR, "fatal": Log.FATAL}
        out = []
        for entry in self._log:
            if severity is not None and entry.level != levels[severity.lower()]:
                continue
            if name is not None and not entry.name.endswith(name):
                continue
            if contains is not None and contains not in entry.msg:
                continue
            out.append(entry.msg)
        return out

    def wait_for_log(self, timeout_sec: float = 5.0, **filters: Any) -> list[str]:
        self.spin_until(lambda: bool(self.logs(**filters)), timeout_sec)
        return self.logs(**filters)

    # ---- teardown --------------------------------------------------------------------------
    def shutdown(self) -> None:
        for node in list(self.executor.get_nodes()):
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()
        self.rclpy.try_shutdown()
