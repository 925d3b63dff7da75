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

import collections
import contextlib
import functools
import inspect
import math
import os
import re
import signal
import subprocess
import threading
import time
import weakref
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import pytest

from prisma_common.goal_refusal import NOT_READY, refusal_code
from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY, try_rt_priority

from .priorities import TEST_DDS_NICE

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
    rclpy's list of ready callbacks)."""
    return False


def result_reason(result: Any) -> str:
    """The text a Grasp (reason), Manipulate (stop_reason) or MoveMotors (reason) result carries;
    "" for a result without one (control_msgs GripperCommand)."""
    return str(getattr(result, "stop_reason", getattr(result, "reason", "")))


def refusal_for_now(result: Any) -> str | None:
    """The reason of a result that refused its goal because the graph is not ready yet (`not_ready:
    ...`: a stream it needs not flowing yet, the motor driver not up): the one refusal a test sends
    the same goal again for. Any other end (busy, sensor_stale, joint_limit, a timeout) is the
    test's outcome, never a reason to send it again. None for those."""
    reason = result_reason(result)
    return reason if refusal_code(reason) == NOT_READY else None


def stamp_ns(msg: Any) -> int:
    """Nanoseconds of a message's header stamp."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def stamped_after(received: Sequence, t_ns: int) -> list:
    """The messages of a `collect` sequence (in stamp order) stamped after `t_ns`, oldest first;
    walked from the newest, so a wait that asks at every spin costs what it finds, not the whole list."""
    found = []
    for m in reversed(received):
        if stamp_ns(m) <= t_ns:
            break
        found.append(m)
    return found[::-1]


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


class _SpinCount:
    """How often a wait ran the executor and its longest gap: a process kept from running shows
    as few spins with a long gap, a stalled subscription as many spins and nothing received."""

    def __init__(self) -> None:
        self.count = 0
        self.longest_gap = 0.0
        self._last = time.monotonic()

    def tick(self) -> None:
        """One more spin (returns None: usable inside a wait's condition)."""
        now = time.monotonic()
        self.longest_gap = max(self.longest_gap, now - self._last)
        self._last = now
        self.count += 1

    def __str__(self) -> str:
        return f"{self.count} spins, longest gap {self.longest_gap:.3f} s"


class RosHarness:
    """One test's ROS world: context, executor, probe node, sim clock, /rosout log capture."""

    START_NS = 1_700_000_000 * 10**9  # where sim time starts: far from 0 like a real clock
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

        self.rclpy = rclpy
        rclpy.init()
        from prisma_node_wiring import single_instance

        # this process's nodes share its DDS participant and see each other at once: the wait for
        # other processes' nodes would only add 0.5 s to every node a test builds
        single_instance.DISCOVERY_WAIT_S = 0.0
        self.executor = new_executor()  # the nodes' own (PRISMA_EXECUTOR): as their processes spin them
        self.nodes: list = []
        self.sim_nodes: list = []
        self._sim_now: int | None = None
        self._probe = None
        self._clock_pub = None
        self._publishers: dict = {}
        self._clients: dict = {}
        self._log: Sequence | None = None
        self._action_clients: list = []  # destroyed at shutdown: destroy_node leaves them in the graph
        self._collecting: dict[int, Any] = {}  # id of a collect() list -> its subscription
        self._feedback: dict[bytes, list] = {}  # goal id of a send_until_started goal -> its feedback messages
        self._goal_ends: Sequence | None = None  # /diagnostics, collected from the first GripperCommand sent
        self._collect_apart = collect_apart
        self._wait_spin_sec = self.APART_SPIN_SEC if collect_apart else self.SPIN_SEC  # spin_for, spin_until
        self._collector: Any = None  # the collector process, started by the first collect
        self._collections: list = []
        # DDS starts its threads with the first node of the process: the probe, made now with this
        # thread on their rung (they inherit it; priorities.TEST_DDS_NICE), then this thread back
        with _this_thread_at_nice(TEST_DDS_NICE):
            _ = self.probe

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

    def destroy_node(self, node) -> None:
        """Stop spinning `node` and destroy it, as if its process had died (its publishers,
        subscriptions and action clients go with it)."""
        self.executor.remove_node(node)
        for nodes in (self.nodes, self.sim_nodes):
            if node in nodes:
                nodes.remove(node)
        node.destroy_node()

    @property
    def probe(self):
        """The test's own node (wall time): its publishers, subscriptions and clients."""
        if self._probe is None:
            self._probe = self.rclpy.create_node("test_probe")
            self.executor.add_node(self._probe)
        return self._probe

    # ---- spinning --------------------------------------------------------------------------
    def spin_once(self, timeout_sec: float = SPIN_SEC) -> None:
        self.executor.spin_once(timeout_sec=timeout_sec)

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for `seconds` of wall time."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=self._wait_spin_sec)

    def spin_until(self, condition: Any, timeout_sec: float = 10.0) -> bool:
        """Process callbacks until `condition()` (or a Future) is true; False after the timeout."""
        done = condition.done if hasattr(condition, "done") else condition
        end = time.monotonic() + timeout_sec
        while not done() and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=self._wait_spin_sec)
        return bool(done())

    # ---- sim time --------------------------------------------------------------------------
    def now_ns(self) -> int:
        """Sim time once a sim-time node exists, else wall time."""
        return self._sim_now if self._sim_now is not None else time.time_ns()

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

    def set_time(self, stamp_ns: int, settle: bool = False) -> None:
        """Publish /clock = stamp_ns and wait until every sim-time node's clock reads it (then,
        with `settle`, until the callbacks of that instant are all done)."""
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock

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
                self.executor.spin_once(timeout_sec=self.SPIN_SEC)
        # let the timers that became due at this instant run before time moves on
        if settle:
            self.settle()
            return
        for _ in range(3):
            self.executor.spin_once(timeout_sec=self.SPIN_SEC)

    def _wait_for_clock(self, node, stamp_ns: int) -> None:
        self.set_time(stamp_ns)

    def advance(self, seconds: float, step: float = 0.001,
                until: Callable[[], bool] | None = None, settle: bool = False) -> None:
        """Move sim time forward by `seconds` in `step`s, letting due timers run at each step (with
        `settle`, everything each step set off; see `settle`)."""
        target = self.now_ns() + round(seconds * 1e9)
        step_ns = round(step * 1e9)
        while self._sim_now < target:
            self.set_time(min(self._sim_now + step_ns, target), settle=settle)
            if until is not None and until():
                return

    # ---- topics, services, actions ---------------------------------------------------------
    def collect(self, msg_type: type, topic: str, qos_profile: Any = None) -> Sequence:
        """A sequence that fills with every message received on `topic` (depth 1000: bursts fit), in
        arrival order; taken by the collector process with `collect_apart`."""
        from rclpy.event_handler import SubscriptionEventCallbacks
        from rclpy.qos import QoSProfile

        if self._collect_apart:
            from prisma_testing.collector import Collector

            if self._collector is None:
                self._collector = Collector()
            collection = self._collector.collect(msg_type, topic, qos_profile)
            self._collections.append(collection)
            return collection
        received: list = []
        # without rclpy's QoS-event waitables, as the nodes' streams: a probe collecting a dozen 100 Hz
        # topics would spend more CPU walking them than the graph it observes
        subscription = self.probe.create_subscription(
            msg_type, topic, received.append, qos_profile or QoSProfile(depth=1000),
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self._collecting[id(received)] = subscription
        return received

    def stop_collecting(self, *lists: list) -> None:
        """Close the subscriptions that fill these `collect` lists: a probe still taking dozens of
        100 Hz topics a test is done with leaves the executor little time for the next test's."""
        for received in lists:
            if any(received is c for c in self._collections):
                self._collector.stop(received)
                self._collections.remove(received)
            else:
                self.probe.destroy_subscription(self._collecting.pop(id(received)))

    def publisher(self, msg_type: type, topic: str, qos_profile: Any = 10):
        return self.probe.create_publisher(msg_type, topic, qos_profile)

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
        if not self.spin_until(lambda: publisher.get_subscription_count() >= wait_for_subscribers, 10.0):
            matched = publisher.get_subscription_count()
            self.probe.destroy_publisher(publisher)
            raise TimeoutError(f"{topic}: {matched} of {wait_for_subscribers} subscription(s) matched in 10 s")
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

    def action_client(self, action_type: type, name: str, wait_sec: float | None = 10.0):
        """An ActionClient of the probe, destroyed at shutdown; waits up to `wait_sec` for its server
        (None: not at all, for a test that sends goals the moment the server appears)."""
        from rclpy.action import ActionClient

        client = ActionClient(self.probe, action_type, name)
        self._action_clients.append(client)
        if wait_sec is not None and not self.spin_until(client.server_is_ready, wait_sec):
            raise TimeoutError(f"action server {name} not available")
        return client

    def send_goal(self, client: Any, goal: Any, feedback: list | None = None, timeout_sec: float = 10.0):
        """Send a goal and return its ClientGoalHandle once the server answered (accepted or not)."""
        future = client.send_goal_async(goal, feedback_callback=feedback.append if feedback is not None else None)
        if not self.spin_until(future, timeout_sec):
            raise TimeoutError("no answer to the goal request")
        return future.result()

    def send_until_started(self, client: Any, goal: Any, timeout_sec: float = 30.0, retry_sec: float = 0.2):
        """The one way a test resends a goal: again every `retry_sec` while the server refuses it
        `not_ready` (the graph coming up; `refusal_for_now`), until `timeout_sec`. The hand's action
        servers accept every goal and abort one they cannot run yet at once, the reason in the
        result (prisma_common.goal_refusal); GripperCommand's result has no text, so its reason is
        the manipulation node's `manipulation: goals` status on /diagnostics naming the goal. Returns
        the ClientGoalHandle of the goal that started (its first feedback came) or ended any other
        way; AssertionError when it is still refused at the timeout."""
        deadline = time.monotonic() + timeout_sec
        # a client made without waiting (action_client(wait_sec=None)): a goal request sent before
        # its server is discovered gets no answer, which is not a refusal
        if not self.spin_until(client.server_is_ready, timeout_sec):
            raise AssertionError(f"{type(goal).__name__}: its action server did not appear in {timeout_sec} s")
        if _has_no_reason(goal) and self._goal_ends is None:
            from diagnostic_msgs.msg import DiagnosticArray

            self._goal_ends = self.collect(DiagnosticArray, "/diagnostics")
        while True:
            feedback: list = []
            handle = self.send_goal(client, goal, feedback)
            self._feedback[bytes(handle.goal_id.uuid)] = feedback
            if not handle.accepted:
                raise AssertionError(f"{type(goal).__name__} rejected: the hand's servers accept every goal")
            result = handle.get_result_async()
            self.spin_until(lambda: bool(feedback) or result.done(), 10.0)  # noqa: B023 - runs now
            reason = self._not_ready(goal, handle, result.result()) if result.done() else None
            if reason is None:
                return handle
            if time.monotonic() > deadline:
                raise AssertionError(f"{type(goal).__name__} still refused after {timeout_sec} s: {reason}")
            self.spin_for(retry_sec)

    def feedback_of(self, handle: Any) -> list:
        """Every feedback message of a goal `send_until_started` sent, in arrival order (filled as the
        executor spins): the action client takes them anyway, so a test need not collect the
        feedback topic a second time."""
        return self._feedback[bytes(handle.goal_id.uuid)]

    def _not_ready(self, goal: Any, handle: Any, result: Any) -> str | None:
        """refusal_for_now of a goal's result; for a GripperCommand, of the reason the manipulation
        node put on /diagnostics for it (its log tells a storm's refusals once)."""
        if not _has_no_reason(goal):
            return refusal_for_now(result.result)
        if goal_status_name(result.status) != "ABORTED":
            return None
        why = self.goal_end_reason(handle)
        return why if why is not None and refusal_code(why) == NOT_READY else None

    def goal_end_reason(self, handle: Any, timeout_sec: float = 3.0) -> str | None:
        """The reason of a goal's end as the manipulation node's `manipulation: goals` status on
        /diagnostics names it (the goal's id in last_goal_id), waiting for it (published at the end
        and every second); None when it did not come. Needs a /diagnostics collection made before the
        goal was sent (send_until_started makes it for a GripperCommand)."""
        from prisma_manipulation.goal_ends import STATUS_NAME

        goal_id = bytes(handle.goal_id.uuid).hex()
        ends = self._goal_ends if self._goal_ends is not None else []

        def found() -> str | None:
            for msg in reversed(ends):
                for status in msg.status:
                    values = {v.key: v.value for v in status.values}
                    if status.name.endswith(STATUS_NAME) and values.get("last_goal_id") == goal_id:
                        return values.get("last_reason", "")
            return None

        self.spin_until(lambda: found() is not None, timeout_sec)
        return found()

    def message_at(self, received: list, seconds_from_now: float, timeout_sec: float = 10.0) -> Any:
        """The first message in `received` (a `collect` list) stamped `seconds_from_now` or later,
        waiting for it. On a loaded machine this process receives a stream late: after a sleep,
        `received[-1]` can still be a message from before it (AssertionError at the timeout)."""
        at_ns = self.now_ns() + int(seconds_from_now * 1e9)
        try:
            return self.message_stamped(received, at_ns, timeout_sec + seconds_from_now)
        except AssertionError as late:
            raise AssertionError(f"no message stamped {seconds_from_now} s from now within {timeout_sec} s "
                                 f"({late})") from None

    def message_stamped(self, received: list, at_ns: int, timeout_sec: float = 10.0) -> Any:
        """The first message in `received` (a `collect` list, in stamp order) stamped `at_ns` or
        later, waiting up to `timeout_sec` for it (AssertionError naming the newest stamp)."""
        def found() -> Any:
            first = None
            for m in reversed(received):  # only the messages from at_ns on are walked
                if stamp_ns(m) < at_ns:
                    break
                first = m
            return first

        spins = _SpinCount()  # spin_until checks its condition once per spin
        if not self.spin_until(lambda: spins.tick() or found() is not None, timeout_sec):
            newest = f"{(stamp_ns(received[-1]) - at_ns) * 1e-9:+.3f} s" if received else "none"
            raise AssertionError(f"newest: {newest}; {spins}; {self._stream_check(received)}")
        return found()

    def _stream_check(self, received: list, seconds: float = 2.0) -> str:
        """Whether the stream a `collect` list stopped receiving is still published: a fresh
        subscription to its topic for `seconds` tells a silent publisher from a stalled reader."""
        subscription = self._collecting.get(id(received))
        if any(received is c for c in self._collections):
            topic, msg_type = received.topic, received.msg_type
            collector = self._collector.proc
            if collector.poll() is not None:
                return (f"{topic}: the collector exited ({collector.returncode}): "
                        f"{self._collector.stderr_tail(1500)}")
        elif subscription is None:
            return "its subscription is closed"
        else:
            topic, msg_type = subscription.topic_name, subscription.msg_type
        reader = "" if subscription is None else f"; {self._reader_state(subscription)}"
        fresh: list = []
        check = self.probe.create_subscription(msg_type, topic, fresh.append, 1000)
        try:
            self.spin_for(seconds)
        finally:
            self.probe.destroy_subscription(check)
        publishers = self.probe.count_publishers(topic)
        if not fresh:
            return f"{topic}: {publishers} publisher(s), a fresh subscription received nothing in {seconds} s"
        newest = (stamp_ns(fresh[-1]) - self.now_ns()) * 1e-9
        return (f"{topic}: {publishers} publisher(s), a fresh subscription received {len(fresh)} in "
                f"{seconds} s (newest {newest:+.3f} s), the collecting one {len(received)} in all{reader}")

    def _reader_state(self, subscription: Any) -> str:
        """Why a collecting subscription's messages stopped: how many callbacks per stream this
        process's executor ran in the next second (a process kept from the CPU serves every stream a
        few times; a stalled subscription none), and how many messages its DDS reader then held
        untaken (taken now, as its handler would; thousands: the executor is behind, none: DDS never
        delivered them). Whether the executor would take it now tells an rclpy stall (a subscription
        marked taken by a handler that never ran is left out of every wait set)."""
        served: collections.Counter = collections.Counter()
        wrapped = [s for node in self.executor.get_nodes() for s in node.subscriptions]
        callbacks = [s.callback for s in wrapped]

        def counted(topic: str, callback: Callable) -> Callable:
            def call(*args: Any) -> Any:
                served[topic] += 1
                return callback(*args)

            async def call_async(*args: Any) -> Any:  # awaited by the executor, as the callback was
                served[topic] += 1
                return await callback(*args)
            return call_async if inspect.iscoroutinefunction(callback) else call

        for s, callback in zip(wrapped, callbacks):
            s.callback = counted(s.topic_name, callback)
        try:
            self.spin_for(1.0)
        finally:
            for s, callback in zip(wrapped, callbacks):
                s.callback = callback
        can_execute = getattr(self.executor, "can_execute", None)  # the events executor has none
        takes = "?" if can_execute is None else can_execute(subscription)
        held = 0
        with subscription.handle:
            while held < 10_000 and subscription.handle.take_message(subscription.msg_type, False):
                held += 1
        return (f"callbacks in the next 1 s: {dict(served)}; its reader then held {held} untaken; "
                f"the executor would take it now: {takes}")

    def wait_until_keeping_up(self, leader: list, follower: list, lag_sec: float, checks: int = 20,
                              timeout_sec: float = 60.0, period_sec: float = 0.1) -> None:
        """Wait until the latest header stamp in `follower` (a `collect` list) is within `lag_sec` of
        the latest in `leader` at `checks` checks in a row, `period_sec` apart: a downstream node
        has warmed up and keeps pace (AssertionError with the last lag at the timeout)."""
        deadline = time.monotonic() + timeout_sec
        good, lag = 0, None
        while good < checks:
            if time.monotonic() > deadline:
                raise AssertionError(f"still {lag} s behind after {timeout_sec} s")
            self.spin_for(period_sec)
            lag = (stamp_ns(leader[-1]) - stamp_ns(follower[-1])) * 1e-9 if leader and follower else None
            good = good + 1 if lag is not None and lag < lag_sec else 0

    def result(self, handle: Any, timeout_sec: float = 30.0, sim_step: float | None = None, settle: bool = False):
        """Wait for an accepted goal's result (advancing sim time by `sim_step` if given, settling
        each step with `settle`)."""
        future = handle.get_result_async()
        if sim_step is not None:
            deadline = time.monotonic() + timeout_sec
            while not future.done() and time.monotonic() < deadline:
                self.advance(sim_step, settle=settle)
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
        """The logged messages that pass `filters` (see `logs`), once there is one or after
        `timeout_sec`."""
        self.spin_until(lambda: bool(self.logs(**filters)), timeout_sec)
        return self.logs(**filters)

    # ---- teardown --------------------------------------------------------------------------
    def shutdown(self) -> None:
        if self._collector is not None:
            self._collector.close()
            self._collector = None
            for collection in self._collections:
                collection.close()
            self._collections.clear()
        for client in self._action_clients:
            client.destroy()
        for node in list(self.executor.get_nodes()):
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()
        self.rclpy.try_shutdown()


# ---- nodes in their own process, as `ros2 run` starts them -----------------------------------------
@dataclass
class ProcessResult:
    returncode: int
    output: str  # stdout and stderr together, in order


class NodeProcess:
    """A command (`ros2 run pkg exe ...`, `python3 -m module`) in its own session, its stdout and
    stderr collected: `wait_for_output` a line it prints, `interrupt` it as Ctrl-C in its terminal
    does (SIGINT to the whole process group: `ros2 run` and the node under it), `wait` for its exit.
    As a context manager it kills whatever still runs at the end. The environment is inherited
    (the test process's ROS_DOMAIN_ID included), with unbuffered Python and uncoloured ROS logs.
    Each one started is kept in `started` (its output for the file a failing test names, launch_case)."""

    started: ClassVar[list[NodeProcess]] = []

    def __init__(self, args: Sequence[str], env: dict[str, str] | None = None, cwd: str | Path | None = None,
                 preexec: Callable[[], None] | None = None) -> None:
        full_env = {**os.environ, "PYTHONUNBUFFERED": "1", "RCUTILS_COLORIZED_OUTPUT": "0", **(env or {})}
        self.args = list(args)
        self.proc = subprocess.Popen(self.args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=full_env, cwd=cwd, start_new_session=True, preexec_fn=preexec)
        self._lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        NodeProcess.started.append(self)

    def _read(self) -> None:
        for line in self.proc.stdout:
            self._lines.append(line)

    @property
    def output(self) -> str:
        return "".join(self._lines)

    def wait_for_output(self, text: str, timeout_sec: float = 60.0) -> bool:
        """True once `text` appears in the output; False at the timeout or when the process exits first."""
        deadline = time.monotonic() + timeout_sec
        while time.monotonic() < deadline:
            if text in self.output:
                return True
            if self.proc.poll() is not None:
                self._reader.join(timeout=5.0)
                return text in self.output
            time.sleep(0.05)
        return False

    def wait_until_spinning(self, ros: RosHarness, node_name: str, timeout_sec: float = 60.0) -> None:
        """Return once `node_name` answers its ~/list_parameters service, i.e. its executor spins.
        (A SIGINT before that lands in rclpy's executor set-up inside rclpy.spin, not in the node.)"""
        from rcl_interfaces.srv import ListParameters

        ros.call(ListParameters, f"{node_name}/list_parameters", ListParameters.Request(), timeout_sec)

    def wait(self, timeout_sec: float = 60.0) -> ProcessResult:
        """Wait for the process to exit by itself; TimeoutError (with its output) if it does not."""
        try:
            self.proc.wait(timeout=timeout_sec)
        except subprocess.TimeoutExpired:
            self.kill()
            raise TimeoutError(f"{' '.join(self.args)} still ran after {timeout_sec} s; "
                               f"output:\n{self.output}") from None
        self._reader.join(timeout=5.0)
        return ProcessResult(self.proc.returncode, self.output)

    def interrupt(self, timeout_sec: float = 30.0, sig: int = signal.SIGINT) -> ProcessResult:
        """Ctrl-C (SIGINT, or `sig`: SIGTERM as `ros2 launch` escalates) to the process group, then
        wait for the exit."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, sig)
        return self.wait(timeout_sec)

    def kill(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self._reader.join(timeout=5.0)

    def __enter__(self) -> NodeProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()


def run_process(args: Sequence[str], timeout_sec: float = 60.0, env: dict[str, str] | None = None) -> ProcessResult:
    """Run a command that should exit by itself (a node refusing its parameters) and collect its output."""
    with NodeProcess(args, env=env) as proc:
        return proc.wait(timeout_sec)


def start_and_interrupt(args: Sequence[str], ready: str, ros: RosHarness | None = None, node_name: str | None = None,
                        sig: int = signal.SIGINT, timeout_sec: float = 60.0) -> ProcessResult:
    """Start a node process, wait until it printed `ready` (and, given `ros` and `node_name`, until
    it spins), send it `sig` as Ctrl-C would, and return its exit status and output."""
    with NodeProcess(args) as proc:
        if not proc.wait_for_output(ready, timeout_sec):
            raise AssertionError(f"{' '.join(args)} never printed {ready!r}; output:\n{proc.output}")
        if ros is not None and node_name is not None:
            proc.wait_until_spinning(ros, node_name, timeout_sec)
        return proc.interrupt(timeout_sec, sig)


_EXTERNAL_SHUTDOWN = """
import importlib, sys, threading, time
import rclpy
from prisma_node_wiring.executor import process_executor
main = importlib.import_module(sys.argv[1]).main
def shut_down_when_spinning():
    while not rclpy.ok():
        time.sleep(0.05)
    executor = process_executor()  # the one run_node spins
    while not executor.get_nodes():
        time.sleep(0.05)
    time.sleep(0.5)
    rclpy.get_default_context().handle.shutdown()  # rcl only, as rclpy's signal handler does
    executor.wake()
threading.Thread(target=shut_down_when_spinning, daemon=True).start()
main([sys.argv[0], *sys.argv[2:]])
"""


def external_shutdown_command(module: str, *args: str) -> list[str]:
    """A command running `module`'s main(args) whose rclpy context is shut down from outside its
    executor once the node spins (as rclpy's SIGINT/SIGTERM handler and `ros2 launch` do): rclpy.spin
    then raises ExternalShutdownException, which main() must take as a normal stop (exit 0)."""
    import sys

    return [sys.executable, "-c", _EXTERNAL_SHUTDOWN, module, *args]


# ---- launch files and long-running ros2 verbs in their own process group ----------------------------
def ros2_launch(package: str, launch_file: str, *arguments: str, env: dict[str, str] | None = None,
                cwd: str | Path | None = None, preexec: Callable[[], None] | None = None) -> NodeProcess:
    """`ros2 launch <package> <launch_file> name:=value ...` in its own process group, as an operator
    starts it in a terminal; stop it with `stop_process` (the environment, ROS_DOMAIN_ID included,
    is the test process's; `cwd` and `preexec` as NodeProcess takes them)."""
    return NodeProcess(["ros2", "launch", package, launch_file, *arguments], env=env, cwd=cwd, preexec=preexec)


def stop_process(proc: NodeProcess, timeout_sec: float = 30.0) -> ProcessResult:
    """Stop a launch or a `ros2 bag record` as Ctrl-C in its terminal does (SIGINT to its process
    group), then SIGTERM (what `ros2 launch` escalates to) and SIGKILL if it is still running after
    `timeout_sec` each; returns the exit status and output. A process that already ended is only
    waited for."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        if proc.proc.poll() is not None:
            break
        os.killpg(proc.proc.pid, sig)
        try:
            proc.proc.wait(timeout=timeout_sec)
        except subprocess.TimeoutExpired:
            continue
    proc.kill()  # SIGKILL only if both signals were ignored; joins the output reader
    return ProcessResult(proc.proc.returncode, proc.output)


# Python 3.11's asyncio child watcher reports 255 for a child that another waitpid reaped first. Ctrl-C
# reaches every node of a launch twice, from the terminal's SIGINT to the process group and from
# launch's own SIGINT; the second goes through Popen.send_signal, whose poll() reaps a node that the first
# had already ended, and the watcher's waitpid then finds no child. The node's own exit status is lost.
_EXIT_LOST = re.compile(r"Unknown child process pid (\d+), will report returncode 255")
_DIED = re.compile(r"process has died \[pid (\d+), exit code (-?\d+)")


def process_deaths(output: str) -> list[str]:
    """The `process has died` lines of a launch's output, less those whose exit code 255 asyncio's
    child watcher made up for a pid it found already reaped (its warning names the pid)."""
    lost = set(_EXIT_LOST.findall(output))
    return [line for line in output.splitlines()
            if (died := _DIED.search(line)) and not (died[2] == "255" and died[1] in lost)]


def stamp_rate_hz(msgs: Iterable[Any], start_ns: int, end_ns: int) -> float:
    """Messages per second whose header stamp lies in [start_ns, end_ns)."""
    return sum(start_ns <= stamp_ns(m) < end_ns for m in msgs) / ((end_ns - start_ns) * 1e-9)


def diagnostic_values(diagnostics: Sequence[Any], name_end: str, since_ns: int = 0) -> dict[str, str] | None:
    """The key/values of the newest /diagnostics status named `...<name_end>` in a `collect` list,
    None if there is none stamped at or after `since_ns`."""
    for msg in reversed(diagnostics):
        if stamp_ns(msg) < since_ns:
            return None
        for status in msg.status:
            if status.name.endswith(name_end):
                return {v.key: v.value for v in status.values}
    return None


def wait_until_homed(ros: RosHarness, diagnostics: Sequence[Any], motors: Sequence[str],
                     timeout_sec: float = 60.0) -> None:
    """Spin until the motor driver's newest /diagnostics say every one of `motors` is homed (a launch
    with home:=true homes at start; goals before that are refused not_homed)."""
    def homed() -> bool:
        return all((diagnostic_values(diagnostics, f"motor_driver: {m}") or {}).get("homed") == "True" for m in motors)

    if not ros.spin_until(homed, timeout_sec):
        raise AssertionError(f"not homed within {timeout_sec} s: "
                             f"{[diagnostic_values(diagnostics, f'motor_driver: {m}') for m in motors]}")


def _fault_cli_priority() -> None:
    # the fault CLI acts when the test says, not when a busy machine gets round to starting it (the
    # ladder in prisma_common/scheduling.py): a default-priority start took 4-15 s on a loaded 2-core
    # machine, longer than the slow goal a fault is meant to interrupt
    from prisma_common.scheduling import try_rt_priority

    from .priorities import FAULT_CLI_RT_PRIORITY

    try_rt_priority(FAULT_CLI_RT_PRIORITY)


def console_script(name: str) -> str:
    """This interpreter's own console script `name` where it has one, else `name` from PATH: a version
    manager's shim on PATH forks a chain of shells first, seconds on a loaded machine."""
    import sys

    script = Path(sys.executable).with_name(name)
    return str(script) if script.exists() else name


def run_hand_fault(emulator_dir: str | Path, *args: str) -> subprocess.CompletedProcess:
    """Run `prisma-hand-fault --dir <emulator_dir> <args>` (the emulated hand's fault CLI, its
    `console_script`) at FAULT_CLI_RT_PRIORITY."""
    command = [console_script("prisma-hand-fault"), "--dir", str(emulator_dir), *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=30, preexec_fn=_fault_cli_priority)


def hand_fault(emulator_dir: str | Path, *args: str) -> str:
    """What `prisma-hand-fault --dir <emulator_dir> <args>` prints, sent from this process (the CLI's
    parser and request, prisma_hand_emulator.emulator_cli.fault_request): a CLI process started per
    fault took seconds on a 2-core machine whose control path runs at real-time priority, and a push
    meant for 0.5 s into a 3 s hold came after the hold ended. AssertionError naming the command
    when the emulator refuses it or cannot be reached."""
    from prisma_common.cli_args import UserError
    from prisma_hand_emulator.emulator_cli import fault_request

    try:
        return fault_request(["--dir", str(emulator_dir), *args])
    except UserError as exc:
        raise AssertionError(f"prisma-hand-fault {' '.join(args)}: {exc}") from None


@functools.cache
def goal_status_names() -> dict[int, str]:
    """action_msgs/GoalStatus's numbers -> names (4: "SUCCEEDED"), read from the message's own
    STATUS_* constants; imported here, not with the module, which tests without ROS import too."""
    from action_msgs.msg import GoalStatus

    return {getattr(GoalStatus, n): n.removeprefix("STATUS_") for n in dir(GoalStatus) if n.startswith("STATUS_")}


def goal_status_name(status: int) -> str:
    """The name of a GoalStatus number ("SUCCEEDED"); the number itself, as text, for one it lacks."""
    return goal_status_names().get(status, str(status))


def goal_outcome(result: Any) -> tuple[str, str]:
    """(status name, reason) of an action's result: Grasp's reason, Manipulate's stop_reason, or for
    GripperCommand (no text) reached_goal, stalled or neither."""
    r = result.result
    if hasattr(r, "reason"):
        reason = r.reason
    elif hasattr(r, "stop_reason"):
        reason = r.stop_reason
    else:
        reason = "reached_goal" if r.reached_goal else ("stalled" if r.stalled else "neither")
    return goal_status_name(result.status), reason


def gripper_goal(position: float, max_effort: float = 0.0) -> Any:
    """control_msgs/GripperCommand goal: `position` = the fingers motor angle in rad (0 = open)."""
    from control_msgs.action import GripperCommand

    goal = GripperCommand.Goal()
    goal.command.position, goal.command.max_effort = float(position), float(max_effort)
    return goal


def _has_no_reason(goal: Any) -> bool:
    """A goal whose result carries no reason text (control_msgs GripperCommand)."""
    return type(goal).__name__.startswith("GripperCommand")


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
