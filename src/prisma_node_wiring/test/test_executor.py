"""SingleWaitExecutor: one wait per message where rclpy's own executor waits twice (woken the second
time by its own guard condition), and what another thread hands it still wakes it; plain callbacks
run without a Task (their exceptions still reach spin_once), async ones and busy callback groups as
rclpy runs them. Which executor a process gets: the fast one only on a proven rclpy whose self-test
passes, rclpy's stock one on any other (a faked unknown version here), said in one log line.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1). The fast executor's own tests run where the
running rclpy is one it is proven on.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest

from prisma_testing.ros_harness import require_ros

require_ros()

import rclpy  # noqa: E402
import rclpy.executors  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.impl.implementation_singleton import rclpy_implementation  # noqa: E402
from rclpy.task import Task  # noqa: E402
from std_msgs.msg import Int32  # noqa: E402

from prisma_node_wiring import executor as executor_module  # noqa: E402
from prisma_node_wiring.executor import SingleWaitExecutor, fast_executor_self_test, new_executor  # noqa: E402
from prisma_node_wiring.executor_choice import (  # noqa: E402
    EXECUTOR_ENV,
    PROVEN_RCLPY_VERSIONS,
    rclpy_version,
    requested_executor,
)

RUNNING_RCLPY = rclpy_version()
fast_only = pytest.mark.skipif(RUNNING_RCLPY not in PROVEN_RCLPY_VERSIONS,
                               reason=f"the fast executor is not proven on rclpy {RUNNING_RCLPY}")


@pytest.fixture
def context():
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


@contextmanager
def probe_node(executor, context) -> Iterator:
    """A node of `context` that `executor` spins; the node and the executor destroyed after."""
    node = rclpy.create_node("executor_probe", context=context)
    executor.add_node(node)
    try:
        yield node
    finally:
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown()


def spin_until(executor, done: Callable[[], bool], timeout_s: float = 5.0, step_s: float = 0.5) -> None:
    """spin_once until `done()` or `timeout_s` has passed; the test's assert says which."""
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=step_s)


def timer_calls(executor, node, times: int = 3) -> list[int]:
    """A 10 ms timer on `node`, spun until it ran `times` times: one entry per run."""
    calls: list[int] = []
    node.create_timer(0.01, lambda: calls.append(1))
    spin_until(executor, lambda: len(calls) >= times)
    return calls


@pytest.fixture
def spun(context):
    """A SingleWaitExecutor spinning one node of `context`; both destroyed after the test."""
    executor = SingleWaitExecutor(context=context)
    with probe_node(executor, context) as node:
        yield executor, node


class CountedWaitSets:
    """rclpy's WaitSet, counted: the executor builds one per wait."""

    def __init__(self, real: type) -> None:
        self.real = real
        self.built = 0

    def __call__(self, *args: object) -> object:
        self.built += 1
        return self.real(*args)


class CountedTasks:
    """rclpy's Task as the executor module makes it, counted."""

    def __init__(self) -> None:
        self.made = 0

    def __call__(self, *args: object, **kwargs: object) -> Task:
        self.made += 1
        return Task(*args, **kwargs)


def waits_per_message(executor, context, monkeypatch, messages: int = 10) -> float:
    """Wait sets `executor` built per message, each published from another thread 50 ms after the
    last was received."""
    counted = CountedWaitSets(rclpy_implementation.WaitSet)
    monkeypatch.setattr(rclpy_implementation, "WaitSet", counted)
    with probe_node(executor, context) as node:
        received: list = []
        node.create_subscription(Int32, "executor_probe", received.append, 10)
        publisher = node.create_publisher(Int32, "executor_probe", 10)
        deadline = time.monotonic() + 10.0
        while not received and time.monotonic() < deadline:  # until discovery matched the two
            publisher.publish(Int32(data=0))
            executor.spin_once(timeout_sec=0.05)
        executor.spin_once(timeout_sec=0.2)  # the rest sent while they matched
        received.clear()
        counted.built = 0

        def publish() -> None:  # each message while the executor waits, as from another process
            for i in range(1, messages + 1):
                while len(received) < i - 1 and time.monotonic() < deadline + 10.0:
                    time.sleep(0.001)
                time.sleep(0.05)  # the executor back in its wait once the callback of i - 1 is done
                publisher.publish(Int32(data=i))

        sender = threading.Thread(target=publish)
        sender.start()
        while len(received) < messages and time.monotonic() < deadline + 10.0:
            executor.spin_once(timeout_sec=1.0)
        sender.join()
        assert [m.data for m in received] == list(range(1, messages + 1))
        return counted.built / messages


@fast_only
def test_one_wait_per_message(context, monkeypatch):
    assert waits_per_message(SingleWaitExecutor(context=context), context, monkeypatch) <= 1.2


def test_rclpy_executor_waits_twice_per_message(context, monkeypatch):
    # what SingleWaitExecutor saves: after each callback rclpy's next wait returns at once, woken by
    # the executor's own guard condition, and the wait set is built again
    assert waits_per_message(SingleThreadedExecutor(context=context), context, monkeypatch) >= 1.5


@fast_only
def test_a_task_from_another_thread_wakes_the_wait(spun):
    executor, node = spun
    ran: list[float] = []
    timer = threading.Timer(0.2, lambda: executor.create_task(lambda: ran.append(time.monotonic())))
    start = time.monotonic()
    timer.start()
    while not ran and time.monotonic() - start < 5.0:
        executor.spin_once(timeout_sec=5.0)
    assert ran and ran[0] - start < 1.0


@fast_only
def test_a_coroutine_callback_resumes_when_the_future_it_awaits_is_set(spun):
    executor, node = spun
    future = rclpy.task.Future(executor=executor)
    done: list[int] = []

    async def waits() -> None:
        done.append(await future)

    node.create_timer(0.01, lambda: None)  # keeps the executor turning
    task = executor.create_task(waits)
    executor.spin_once(timeout_sec=0.1)
    assert not task.done()
    threading.Timer(0.1, lambda: future.set_result(42)).start()
    spin_until(executor, task.done, step_s=0.1)
    assert done == [42]


@fast_only
def test_a_callback_that_shuts_the_context_down_ends_its_spin_quietly(context, spun):
    # as rclpy's signal handler does under a running callback: the guard condition the executor
    # would clear is then invalid
    executor, node = spun
    node.create_timer(0.01, context.shutdown)
    executor.spin_once(timeout_sec=5.0)
    assert not context.ok()


@fast_only
def test_a_plain_callbacks_exception_reaches_spin_once_and_the_timer_runs_again(spun, monkeypatch):
    executor, node = spun
    tasks = CountedTasks()
    monkeypatch.setattr(rclpy.executors, "Task", tasks)
    calls: list[int] = []

    def fails() -> None:
        calls.append(1)
        if len(calls) == 1:
            raise ValueError("bad sample 7")

    node.create_timer(0.01, fails)
    with pytest.raises(ValueError, match="bad sample 7"):
        executor.spin_once(timeout_sec=5.0)
    spin_until(executor, lambda: len(calls) >= 3)
    assert len(calls) >= 3  # not left out of the wait set by the failed call
    assert tasks.made == 0  # no Task for a plain callback


def test_rclpy_executor_makes_a_task_per_callback(context, monkeypatch):
    # what the count above would see if the fast executor wrapped plain callbacks as rclpy does
    tasks = CountedTasks()
    monkeypatch.setattr(rclpy.executors, "Task", tasks)
    executor = SingleThreadedExecutor(context=context)
    with probe_node(executor, context) as node:
        calls = timer_calls(executor, node)
        assert len(calls) >= 3 and tasks.made >= len(calls)


@fast_only
def test_an_async_callback_and_a_busy_callback_group_run_as_in_rclpy(spun):
    executor, node = spun
    group = MutuallyExclusiveCallbackGroup()
    gate = rclpy.task.Future(executor=executor)
    log: list[str] = []

    async def holds_the_group() -> None:  # an async timer callback, its Task suspended on the gate
        log.append("async started")
        await gate
        log.append("async ended")

    holder = node.create_timer(0.01, holds_the_group, callback_group=group)
    received: list = []
    node.create_subscription(Int32, "executor_probe", received.append, 10, callback_group=group)
    publisher = node.create_publisher(Int32, "executor_probe", 10)
    spin_until(executor, lambda: "async started" in log, step_s=0.1)
    holder.cancel()
    publisher.publish(Int32(data=5))
    for _ in range(20):  # the group is held: the subscription's turn is refused, the message kept
        executor.spin_once(timeout_sec=0.01)
    assert received == []
    gate.set_result(None)
    spin_until(executor, lambda: bool(received), step_s=0.1)
    assert log == ["async started", "async ended"]
    assert [m.data for m in received] == [5]


# ---- which executor a process gets ---------------------------------------------------------------
@pytest.fixture
def fresh_choice(monkeypatch):
    """This process's executor choice not made yet, and made again by the test (then forgotten)."""
    monkeypatch.setattr(executor_module, "_choice_made", None)


def test_an_unknown_rclpy_version_gets_the_stock_executor_and_says_so(context, fresh_choice, monkeypatch, capfd):
    monkeypatch.setattr(executor_module, "rclpy_version", lambda: "7.1.99")
    monkeypatch.delenv(EXECUTOR_ENV, raising=False)
    self_tests: list[int] = []
    monkeypatch.setattr(executor_module, "fast_executor_self_test", lambda context=None: self_tests.append(1))
    executor = new_executor(context)
    with probe_node(executor, context) as node:
        assert type(executor) is SingleThreadedExecutor
        assert self_tests == []  # an unproven rclpy is not tried
        assert len(timer_calls(executor, node)) >= 3  # and it spins the node
        assert type(new_executor(context)) is SingleThreadedExecutor  # the choice kept for the process
    logged = [line for line in capfd.readouterr().err.splitlines() if "[prisma_executor]" in line]
    assert len(logged) == 1, logged  # once per process, not per executor
    assert logged[0].endswith("executor: stock, rclpy's SingleThreadedExecutor: PRISMA_EXECUTOR=auto: "
                              "rclpy 7.1.99 is not one the fast executor is proven on (7.1.3)")


@fast_only
def test_fast_asked_on_the_proven_rclpy_gets_the_fast_executor_after_its_self_test(context, fresh_choice,
                                                                                    monkeypatch, capfd):
    monkeypatch.setenv(EXECUTOR_ENV, "fast")
    executor = new_executor(context)
    try:
        assert type(executor) is SingleWaitExecutor
    finally:
        executor.shutdown()
    logged = [line for line in capfd.readouterr().err.splitlines() if "[prisma_executor]" in line]
    assert len(logged) == 1 and logged[0].endswith(
        f"executor: fast, SingleWaitExecutor (prisma_node_wiring.executor): PRISMA_EXECUTOR=fast: "
        f"rclpy {RUNNING_RCLPY} is proven and the self-test passed"), logged


@fast_only
def test_the_self_test_passes_here_and_names_a_changed_private_method(context, monkeypatch):
    assert fast_executor_self_test(context) is None
    # as on Humble, whose _make_handler takes a fourth argument: the expectation faked, not rclpy
    humble = dict(executor_module.FAST_EXECUTOR_OVERRIDES)
    humble["_make_handler"] = (*humble["_make_handler"], "call_coroutine")
    monkeypatch.setattr(executor_module, "FAST_EXECUTOR_OVERRIDES", humble)
    assert fast_executor_self_test(context) == ("SingleThreadedExecutor._make_handler takes (self, entity, node, "
                                                "take_from_wait_list), not (self, entity, node, "
                                                "take_from_wait_list, call_coroutine)")


def test_the_self_test_on_a_shut_down_context_fails_with_a_reason_not_an_exception():
    context = rclpy.Context()
    rclpy.init(context=context)
    rclpy.shutdown(context=context)
    failure = fast_executor_self_test(context)
    assert isinstance(failure, str) and failure


def test_the_harness_spins_the_executor_this_process_chose(ros):
    # the node tests run their nodes on what PRISMA_EXECUTOR asks (CI's stock lane: rclpy's)
    requested = requested_executor()
    if requested == "stock" or RUNNING_RCLPY not in PROVEN_RCLPY_VERSIONS:
        assert type(ros.executor) is SingleThreadedExecutor
    elif requested in ("auto", "fast"):
        assert type(ros.executor) is SingleWaitExecutor
