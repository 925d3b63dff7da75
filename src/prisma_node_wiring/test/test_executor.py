"""SingleWaitExecutor: one wait per message where rclpy's own executor waits twice (woken the second
time by its own guard condition), and what another thread hands it still wakes it; plain callbacks
run without a Task (their exceptions still reach spin_once), async ones and busy callback groups as
rclpy runs them."""
from __future__ import annotations

import threading
import time
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="prisma_node_wiring needs rclpy (source ROS 2)")

import rclpy  # noqa: E402
import rclpy.executors  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from std_msgs.msg import Int32  # noqa: E402

from prisma_node_wiring.executor import SingleWaitExecutor  # noqa: E402


@pytest.fixture
def context():
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture
def spun(context):
    """A SingleWaitExecutor spinning one node of `context`; both destroyed after the test."""
    executor = SingleWaitExecutor(context=context)
    node = rclpy.create_node("executor_probe", context=context)
    executor.add_node(node)
    yield executor, node
    executor.remove_node(node)
    node.destroy_node()
    executor.shutdown()


class CountedWaitSets:
    """rclpy's executor module with its WaitSet counted: the executor builds one per wait."""

    def __init__(self, real: Any) -> None:
        self.real = real
        self.built = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self.real, name)

    def WaitSet(self, *args: Any) -> Any:  # noqa: N802 - stands in for the pybind class
        self.built += 1
        return self.real.WaitSet(*args)


def waits_per_message(executor, context, monkeypatch, messages: int = 10) -> float:
    """Wait sets `executor` built per message, each published from another thread 50 ms after the
    last was received."""
    counted = CountedWaitSets(rclpy.executors._rclpy)
    monkeypatch.setattr(rclpy.executors, "_rclpy", counted)
    node = rclpy.create_node("executor_probe", context=context)
    try:
        received: list = []
        node.create_subscription(Int32, "executor_probe", received.append, 10)
        publisher = node.create_publisher(Int32, "executor_probe", 10)
        executor.add_node(node)
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
    finally:
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown()


def test_one_wait_per_message(context, monkeypatch):
    assert waits_per_message(SingleWaitExecutor(context=context), context, monkeypatch) <= 1.2


def test_rclpy_executor_waits_twice_per_message(context, monkeypatch):
    # what SingleWaitExecutor saves: after each callback rclpy's next wait returns at once, woken by
    # the executor's own guard condition, and the wait set is built again
    assert waits_per_message(SingleThreadedExecutor(context=context), context, monkeypatch) >= 1.5


def test_a_task_from_another_thread_wakes_the_wait(spun):
    executor, node = spun
    ran: list[float] = []
    timer = threading.Timer(0.2, lambda: executor.create_task(lambda: ran.append(time.monotonic())))
    start = time.monotonic()
    timer.start()
    while not ran and time.monotonic() - start < 5.0:
        executor.spin_once(timeout_sec=5.0)
    assert ran and ran[0] - start < 1.0


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
    deadline = time.monotonic() + 5.0
    while not task.done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert done == [42]


def test_a_callback_that_shuts_the_context_down_ends_its_spin_quietly(context, spun):
    # as rclpy's signal handler does under a running callback: the guard condition the executor
    # would clear is then invalid
    executor, node = spun
    node.create_timer(0.01, context.shutdown)
    executor.spin_once(timeout_sec=5.0)
    assert not context.ok()


def test_a_plain_callbacks_exception_reaches_spin_once_and_the_timer_runs_again(spun):
    executor, node = spun
    calls: list[int] = []

    def fails() -> None:
        calls.append(1)
        if len(calls) == 1:
            raise ValueError("bad sample 7")

    node.create_timer(0.01, fails)
    with pytest.raises(ValueError, match="bad sample 7"):
        executor.spin_once(timeout_sec=5.0)
    deadline = time.monotonic() + 5.0
    while len(calls) < 3 and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.5)
    assert len(calls) >= 3  # not left out of the wait set by the failed call
    assert not executor._tasks  # no Task kept for a plain callback


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
    deadline = time.monotonic() + 5.0
    while "async started" not in log and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    holder.cancel()
    publisher.publish(Int32(data=5))
    for _ in range(20):  # the group is held: the subscription's turn is refused, the message kept
        executor.spin_once(timeout_sec=0.01)
    assert received == []
    gate.set_result(None)
    deadline = time.monotonic() + 5.0
    while not received and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert log == ["async started", "async ended"]
    assert [m.data for m in received] == [5]
