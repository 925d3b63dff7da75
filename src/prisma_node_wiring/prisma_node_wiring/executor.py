"""The executor every node process spins: rclpy's single-threaded one, one wait per callback, no Task per message.

rclpy's executor wakes itself: a callback's handler triggers the executor's guard condition once the
message is taken and again when the callback returns, so the wait after every callback returns at
once with nothing but that guard, and the whole wait set (each subscription, timer, service, action
server and client of the node) is built and walked twice per message. At the suite's 100 Hz streams
that second pass is a fifth of a node's CPU (bench/bench_executor.py measures it side by side).

The trigger tells the executor that something it reads when it builds a wait set has changed (an
entity taken and free again, a callback group released, a task or a node added). Taken back right
after the callback, before the next wait set is built from that state, it can tell nothing the next
pass would not read anyway; a trigger from another thread after that still wakes the wait.

A subscription's or timer's plain (not async) callback is run by a direct handler: rclpy wraps each
one in a Task around a coroutine around the callback's own coroutine, kept in the executor's task
list, which every later pass then walks. The direct handler does what that Task does (the callback
group's turn, the take, the callback, its exception handed to spin_once) when spin_once calls it,
and nothing after. Async callbacks, services, clients, guard conditions and action servers keep
rclpy's Task. Together: 694 -> 422 us of CPU per message for a bare subscriber at 400 Hz, 884 -> 594
with parameter services and five action endpoints on the node.
"""
from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from rclpy.executors import SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription
from rclpy.timer import Timer


class _DirectHandler:
    """The handler of one ready subscription or timer with a plain callback, run once by spin_once:
    the answers spin_once and the executor's pass ask of rclpy's Task (done, executing, exception,
    result) without the Task."""

    # weakly referable, as a Task is (RosHarness.settle keeps the handlers it polls in a WeakSet)
    __slots__ = ("_executor", "_entity", "_take", "_done", "_exception", "__weakref__")

    def __init__(self, executor: SingleThreadedExecutor, entity: Any, take: Callable[[Any], Any]) -> None:
        self._executor, self._entity, self._take = executor, entity, take
        self._done = False
        self._exception: BaseException | None = None

    def done(self) -> bool:
        return self._done

    def executing(self) -> bool:
        return False

    def exception(self) -> BaseException | None:
        return self._exception

    def result(self) -> None:
        if self._exception is not None:
            raise self._exception

    def __call__(self) -> None:
        if self._done:
            return
        self._done = True
        executor, entity = self._executor, self._entity
        group = entity.callback_group
        if executor._is_shutdown or not group.beginning_execution(entity):
            entity._executor_event = False  # back into the next wait set, as rclpy's Task does
            executor._guard.trigger()
            return
        try:
            with executor._work_tracker:  # what shutdown() waits for
                execute = self._take(entity)  # rclpy's take: the message (or the timer's call)
                entity._executor_event = False
                if execute is not None:
                    coroutine = execute()
                    try:
                        coroutine.send(None)  # a plain callback runs to its end in one step
                    except StopIteration:
                        pass
                    else:
                        coroutine.close()
                        raise RuntimeError(f"{entity!r}: its callback awaited, and a direct handler runs plain "
                                           "callbacks only")
        except Exception as exc:  # handed to spin_once, which raises it, as rclpy's Task does
            self._exception = exc
        finally:
            entity._executor_event = False
            group.ending_execution(entity)


class SingleWaitExecutor(SingleThreadedExecutor):
    """SingleThreadedExecutor that takes back its own wake-up after each spin, so one wait serves
    one round of ready callbacks, and runs plain subscription and timer callbacks without a Task."""

    def __init__(self, *, context: Any = None) -> None:
        super().__init__(context=context)
        self._own_wake: Any = None  # a wait set holding only the executor's guard condition

    def _make_handler(self, entity: Any, node: Any, take_from_wait_list: Callable[[Any], Any]) -> Any:
        if isinstance(entity, (Subscription, Timer)) and not inspect.iscoroutinefunction(entity.callback):
            entity._executor_event = True  # out of the wait sets until taken, as rclpy marks it
            return _DirectHandler(self, entity, take_from_wait_list)
        return super()._make_handler(entity, node, take_from_wait_list)

    def _spin_once_impl(self, timeout_sec: Any = None, wait_condition: Any = lambda: False) -> None:
        super()._spin_once_impl(timeout_sec, wait_condition)
        self._take_own_wake()

    def _take_own_wake(self) -> None:
        """Clear the executor's guard condition (a zero-timeout wait on it alone takes its trigger)."""
        if self._is_shutdown or not self._context.ok():
            return  # its guard condition is destroyed or about to be; nothing waits again
        with self._guard.handle, self._context.handle:
            if self._own_wake is None:
                self._own_wake = _rclpy.WaitSet(0, 1, 0, 0, 0, 0, self._context.handle)
            self._own_wake.clear_entities()
            self._own_wake.add_guard_condition(self._guard.handle)
            self._own_wake.wait(0)


_process_executor: SingleWaitExecutor | None = None


def process_executor() -> SingleWaitExecutor:
    """The executor `run_node` spins the process's node on: one per process, made on first use (after
    rclpy.init), as rclpy's global executor is for rclpy.spin."""
    global _process_executor
    if _process_executor is None:
        _process_executor = SingleWaitExecutor()
    return _process_executor
