"""Running nodes under test on real rclpy over DDS.

`require_ros()` at the top of a test module skips it (with the reason) where ROS 2 or the built
workspace is not sourced; with PRISMA_REQUIRE_ROS=1 (set by CI when it sources ROS) it fails instead,
so a broken build can never pass as "skipped".

`RosHarness` (the `ros` fixture of conftest.py) owns one initialised rclpy context per test, a
single-threaded executor spinning every node of the test and a probe node for the test's own
publishers, subscriptions, service and action clients. Time: nodes made with `sim_time=True` run on
a /clock the harness publishes (sim_clock.SimClock); everything else runs on wall time and is
awaited with `spin_until`. Its waits on a stream's stamps are stream_waits.Streams, its goals to
the hand's servers goals.HandGoals; commands in their own process are node_process's.
"""
from __future__ import annotations

import contextlib
import math
import os
import threading
import time
import weakref
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY, try_rt_priority

from .goals import HandGoals
from .priorities import TEST_DDS_NICE
from .sim_clock import SimClock
from .streams import Streams
from .streams import stamp_ns as stamp_ns
from .streams import stamped_after as stamped_after

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


def _never() -> bool:
    """The executor's wait condition for `RosHarness.settle` (one object: the same arguments keep
    rclpy's list of ready callbacks), and spin_for's."""
    return False

@contextlib.contextmanager
def _this_thread_at_nice(nice: int) -> Iterator[None]:
    """This thread at niceness `nice` inside the block (Linux keeps niceness per thread), where
    permitted; unchanged where not."""
    before = os.getpriority(os.PRIO_PROCESS, 0)
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except PermissionError:
        yield
        return
    try:
        yield
    finally:
        os.setpriority(os.PRIO_PROCESS, 0, before)


class RosHarness(HandGoals, SimClock, Streams):
    """One test's ROS world: context, executor, probe node, sim clock, /rosout log capture."""

    # One timeout for every spin_once: rclpy's executor drops its list of ready callbacks whenever
    # spin_once's arguments change, and the next list starts again at the first node's first
    # subscription. Alternating timeouts would serve that one again and again (starving the others
    # until their queues overflow) and take messages of one scan out of order across topics.
    SPIN_SEC = 0.005
    # A harness whose collections a collector process takes (collect_apart) is woken by none of their
    # messages: its waits look at them every APART_SPIN_SEC. 200 empty spins a second cost 9% of a core
    # on a 2-core VM (bench_collector's holder), most of what a busy machine leaves a test's process.
    APART_SPIN_SEC = 0.02

    def __init__(self, collect_apart: bool = False) -> None:
        """collect_apart: `collect` through a collector process (prisma_testing.collector), for a
        launch test beside a graph of other processes; in-process (the default) where the test's own
        nodes publish and `settle` must find their messages collected."""
        import rclpy

        from prisma_node_wiring.executor import new_executor

        super().__init__()
        self.rclpy = rclpy
        rclpy.init()
        from prisma_node_wiring import single_instance

        # this process's nodes share its DDS participant and see each other at once: the wait for
        # other processes' nodes would only add 0.5 s to every node a test builds
        single_instance.DISCOVERY_WAIT_S = 0.0
        self.executor = new_executor()  # the nodes' own (PRISMA_EXECUTOR): as their processes spin them
        self._publishers: dict = {}
        self._clients: dict = {}
        self._log: Sequence | None = None
        self._collect_apart = collect_apart
        self._wait_spin_sec = self.APART_SPIN_SEC if collect_apart else self.SPIN_SEC  # spin_for, spin_until
        # DDS starts its threads with the first node of the process: the probe (the test's own node,
        # wall time), made now with this thread on their rung (they inherit it; TEST_DDS_NICE)
        with _this_thread_at_nice(TEST_DDS_NICE):
            self.probe = rclpy.create_node("test_probe")
        self.executor.add_node(self.probe)

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
        if params_files:
            kwargs["cli_args"] = ["--ros-args", *(a for path in params_files for a in ("--params-file", str(path)))]
        node = cls(parameter_overrides=overrides, **kwargs)
        self.executor.add_node(node)
        if sim_time:
            self.follow_clock(node)
        return node

    def destroy_node(self, node) -> None:
        """Stop spinning `node` and destroy it, as if its process had died (its publishers,
        subscriptions and action clients go with it)."""
        self.executor.remove_node(node)
        if node in self.sim_nodes:
            self.sim_nodes.remove(node)
        node.destroy_node()

    # ---- spinning --------------------------------------------------------------------------
    def spin_once(self, timeout_sec: float = SPIN_SEC) -> None:
        self.executor.spin_once(timeout_sec=timeout_sec)

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for `seconds` of wall time."""
        self.spin_until(_never, seconds)

    def spin_until(self, condition: Any, timeout_sec: float = 10.0) -> bool:
        """Process callbacks until `condition()` (or a Future) is true; False after the timeout."""
        done = condition.done if hasattr(condition, "done") else condition
        end = time.monotonic() + timeout_sec
        while not done() and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=self._wait_spin_sec)
        return bool(done())

    def settle(self, quiet_sec: float = SPIN_SEC, timeout_sec: float = 10.0) -> None:
        """Run callbacks until none has become ready for `quiet_sec`: what the test's nodes sent one
        another (messages, goals, results, and what those set off) has arrived and been handled.
        `advance(..., settle=True)` does this at every sim instant, so each instant is complete
        before the clock moves on, as on a robot whose nodes keep up with their inputs."""
        from rclpy.executors import TimeoutException

        end = time.monotonic() + timeout_sec
        # rclpy starts a pass's quiet_sec timer when the pass starts, not when it waits: on a busy
        # machine the timer has run out before the wait, which then returns at once with whatever is
        # ready, and the pass ends "timed out" right after running callbacks that may have set off
        # more. So quiet is a timed-out pass that ran nothing, polling a coroutine that still awaits
        # (a goal's execute callback, yielded by every pass) not counted: its first run is.
        awaiting: weakref.WeakSet = weakref.WeakSet()
        ran = False
        while time.monotonic() < end:
            try:
                # what rclpy's spin_once does, telling whether anything was ready
                handler, _, _ = self.executor.wait_for_ready_callbacks(quiet_sec, None, _never)
            except TimeoutException:
                if not ran:
                    return
                ran = False
                continue
            polled_again = handler in awaiting
            handler()
            if handler.exception() is not None:
                raise handler.exception()
            if handler.done():
                ran = True
            else:
                ran = ran or not polled_again
                awaiting.add(handler)
        raise TimeoutError(f"callbacks still ready after {timeout_sec} s of settling")

    # ---- topics, services, actions ---------------------------------------------------------
    @contextlib.contextmanager
    def publishing(self, msg_type: type, topic: str, message: Callable[[int], Any], rate_hz: float,
                   qos_profile: Any = 10, wait_for_subscribers: int = 0) -> Iterator[list[int]]:
        """Inside the block, `message(i)` (stamped now) published on `topic` at `rate_hz` as another
        process on the robot would: from a thread of its own at the control path's real-time
        priority where permitted, so that the stream keeps its rate however busy this process's
        executor is (a probe timer beside the load harness ran at a fifth of its rate). Yields the
        send instants (time_ns), growing while the block runs. With `wait_for_subscribers`, the first
        message waits until that many subscriptions matched (up to 10 s, then TimeoutError): DDS
        drops what a volatile writer sends before discovery matched a reader, and a collector in
        another process matched 10 ms after the first send beside the load harness."""
        from builtin_interfaces.msg import Time

        publisher = self.probe.create_publisher(msg_type, topic, qos_profile)
        try:
            self._wait_matched(publisher, wait_for_subscribers, topic)
        except TimeoutError:
            self.probe.destroy_publisher(publisher)
            raise
        sent: list[int] = []
        stop = threading.Event()

        def run() -> None:
            try_rt_priority(CONTROL_PATH_RT_PRIORITY)  # this thread only
            due = time.monotonic()
            while not stop.is_set():
                now = time.time_ns()
                msg = message(len(sent))
                msg.header.stamp = Time(sec=now // 10**9, nanosec=now % 10**9)
                publisher.publish(msg)
                sent.append(now)
                due += 1.0 / rate_hz
                stop.wait(max(0.0, due - time.monotonic()))

        thread = threading.Thread(target=run, name=f"publishing {topic}", daemon=True)
        thread.start()
        try:
            yield sent
        finally:
            stop.set()
            thread.join(timeout=5.0)
            self.probe.destroy_publisher(publisher)

    def publish(self, topic: str, msg: Any) -> None:
        """Publish on `topic` from the probe, first waiting until a subscriber matched."""
        key = (topic, type(msg))
        if key not in self._publishers:
            self._publishers[key] = self.probe.create_publisher(type(msg), topic, 1000)
        self._wait_matched(self._publishers[key], 1, topic)
        self._publishers[key].publish(msg)

    def _wait_matched(self, publisher: Any, subscriptions: int, topic: str) -> None:
        """Wait until that many subscriptions matched a probe publisher (TimeoutError after 10 s)."""
        if not self.spin_until(lambda: publisher.get_subscription_count() >= subscriptions, 10.0):
            raise TimeoutError(f"{topic}: {publisher.get_subscription_count()} of {subscriptions} "
                               f"subscription(s) matched in 10 s")

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

    def action_client(self, action_type: type, name: str, wait_sec: float | None = 10.0):
        """An ActionClient of the probe (destroyed at shutdown); waits up to `wait_sec` for its server
        (None: not at all, for a test that sends goals the moment the server appears)."""
        from rclpy.action import ActionClient

        client = ActionClient(self.probe, action_type, name)
        if wait_sec is not None and not self.spin_until(client.server_is_ready, wait_sec):
            raise TimeoutError(f"action server {name} not available")
        return client

    def send_goal(self, client: Any, goal: Any, feedback: list | None = None, timeout_sec: float = 10.0):
        """Send a goal and return its ClientGoalHandle once the server answered (accepted or not)."""
        future = client.send_goal_async(goal, feedback_callback=feedback.append if feedback is not None else None)
        if not self.spin_until(future, timeout_sec):
            raise TimeoutError("no answer to the goal request")
        return future.result()

    def result(self, handle: Any, timeout_sec: float = 30.0):
        """Wait for an accepted goal's result (TimeoutError when none comes)."""
        future = handle.get_result_async()
        if not self.spin_until(future, timeout_sec):
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
        return [e.msg for e in self._log if (severity is None or e.level == getattr(Log, severity.upper()))
                and (name is None or e.name.endswith(name)) and (contains is None or contains in e.msg)]

    def wait_for_log(self, timeout_sec: float = 5.0, **filters: Any) -> list[str]:
        """The logged messages that pass `filters` (see `logs`), once there is one or after
        `timeout_sec`."""
        self.spin_until(lambda: bool(self.logs(**filters)), timeout_sec)
        return self.logs(**filters)

    # ---- teardown --------------------------------------------------------------------------
    def shutdown(self) -> None:
        from rclpy.action import ActionClient, ActionServer

        self._close_streams()
        # Node.destroy_node leaves a node's action clients and servers, and so the node, in the graph
        # of this process (the nodes under test destroy their own): the probe's go first, the
        # harness's clients and a test's stand-in servers, or the next test finds a second server
        for action in [w for w in self.probe.waitables if isinstance(w, (ActionClient, ActionServer))]:
            action.destroy()
        for node in list(self.executor.get_nodes()):
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()
        self.rclpy.try_shutdown()


# /joint_states "stopped": every joint slower than this. On Dynamixel X-series motors (emulated
# included) the smallest velocity the bus reports is one unit, 0.229 rpm; the sim motors' velocity
# decays exponentially (tau 10 ms) and never reads exactly 0, so their "0" is below SIM_STOPPED_RAD_S.
STOPPED_RAD_S = 0.229 * 2 * math.pi / 60
SIM_STOPPED_RAD_S = 1e-3


def stopped(msg: Any, below_rad_s: float = STOPPED_RAD_S) -> bool:
    """No joint of this /joint_states message moves at `below_rad_s` or faster."""
    return all(abs(v) < below_rad_s for v in msg.velocity)


def joint(msg: Any, motor: str, field: str = "position") -> float:
    """One motor's position (or `field`: velocity, effort) in a /joint_states message."""
    return float(getattr(msg, field)[list(msg.name).index(motor)])


def closing_at_10_rpm(joints: list) -> bool:
    """The latest 5 /joint_states show the fingers motor closing steadily at 10 rpm (1.05 rad/s),
    not passing through that speed while it stops from a faster command."""
    return len(joints) >= 5 and all(0.95 < m.velocity[list(m.name).index("fingers")] < 1.15 for m in joints[-5:])
