"""rclpy.executors over the stand-in graph, driven by the test clock.

An executor runs, one callback per step: first a ready task (coroutine callbacks, action goals),
then the due timer with the earliest deadline, then the oldest pending item of the context's work
FIFO (messages, service and action traffic) whose node it holds.

Waiting is simulated: when nothing is ready, spin_once(timeout_sec) moves the test clock to the
next timer deadline of its nodes (or by timeout_sec when no deadline comes sooner), because that
is the time that would have passed. It never blocks: with no timer and no timeout it returns.
spin() runs until nothing is ready and returns (real rclpy would block until shutdown).
MultiThreadedExecutor runs on one thread here, deterministically.
"""
from __future__ import annotations

from typing import Callable

from ros_standin import clock as _test_clock

from .task import Future, Task
from .utilities import get_default_context

_MAX_IDLE_STEPS = 1_000_000


class ExternalShutdownException(Exception):
    pass


class ShutdownException(Exception):
    pass


class TimeoutException(Exception):
    pass


class ConditionReachedException(Exception):
    pass


class Executor:
    def __init__(self, *, context=None) -> None:
        self._context = get_default_context() if context is None else context
        self._nodes: list = []
        self._tasks: list[Task] = []
        self._is_shutdown = False

    @property
    def context(self):
        return self._context

    # -- nodes and tasks ---------------------------------------------------------------------

    def add_node(self, node) -> bool:
        if node in self._nodes:
            return False
        if node._executor is not None and node._executor is not self:
            node._executor.remove_node(node)
        self._nodes.append(node)
        node._executor = self
        return True

    def remove_node(self, node) -> None:
        if node in self._nodes:
            self._nodes.remove(node)
        if node._executor is self:
            node._executor = None

    def get_nodes(self) -> list:
        return list(self._nodes)

    def create_task(self, callback, *args, **kwargs) -> Task:
        task = Task(callback, args, kwargs, executor=self)
        self._tasks.append(task)
        return task

    def wake(self) -> None:
        pass

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        self._is_shutdown = True
        for node in list(self._nodes):
            self.remove_node(node)
        return True

    # -- work selection ----------------------------------------------------------------------

    def _run_task(self, task: Task) -> None:
        task()
        if task.done():
            if task in self._tasks:
                self._tasks.remove(task)
            if task.exception() is not None:
                raise task.exception()

    def _due_timer(self):
        now = _test_clock.now_ns()
        due = [t for node in self._nodes for t in node._timers if not t._canceled and t._next_call_ns <= now]
        return min(due, key=lambda t: (t._next_call_ns, t._order)) if due else None

    def next_timer_deadline_ns(self) -> int | None:
        deadlines = [t._next_call_ns for node in self._nodes for t in node._timers if not t._canceled]
        return min(deadlines) if deadlines else None

    def _step(self) -> bool:
        """Run one ready callback; False when nothing was ready."""
        if self._is_shutdown or not self._context.ok():
            return False
        for task in list(self._tasks):
            if task.done():
                self._tasks.remove(task)
            elif task.ready():
                self._run_task(task)
                return True
        timer = self._due_timer()
        if timer is not None:
            timer._fire()
            return True
        queue = self._context.graph.queue
        while True:
            for index, item in enumerate(queue):
                if item.node in self._nodes:
                    del queue[index]
                    if item.run() is False:
                        break  # a no-op (message dropped by KEEP_LAST): look again
                    return True
            else:
                return False

    def _wait(self, timeout_sec: float | None) -> bool:
        """Let simulated time pass up to the next deadline; True if a timer became due."""
        now = _test_clock.now_ns()
        deadline = self.next_timer_deadline_ns()
        limit = None if timeout_sec is None else now + int(timeout_sec * 1e9)
        if deadline is not None and (limit is None or deadline <= limit):
            _test_clock.TEST_CLOCK.set_ns(max(deadline, now))
            return True
        if limit is not None and limit > now:
            _test_clock.TEST_CLOCK.set_ns(limit)
        return False

    # -- spinning ----------------------------------------------------------------------------

    def spin_once(self, timeout_sec: float | None = None) -> None:
        if self._step():
            return
        if timeout_sec is not None and timeout_sec <= 0:
            return
        if self._wait(timeout_sec):
            self._step()

    def spin_once_until_future_complete(self, future: Future, timeout_sec: float | None = None) -> None:
        self.spin_once(timeout_sec)

    def spin(self) -> None:
        for _ in range(_MAX_IDLE_STEPS):
            if not self._step():
                return
        raise RuntimeError("spin(): callbacks kept producing work; is there a zero-period timer?")

    def spin_until_future_complete(self, future: Future, timeout_sec: float | None = None) -> None:
        """Run callbacks, letting test time pass to each timer deadline, until the future is done
        or timeout_sec of test time passed; returns early when nothing could ever complete it."""
        end = None if timeout_sec is None else _test_clock.now_ns() + int(timeout_sec * 1e9)
        for _ in range(_MAX_IDLE_STEPS):
            if future.done():
                return
            if self._step():
                continue
            remaining = None if end is None else (end - _test_clock.now_ns()) / 1e9
            if remaining is not None and remaining <= 0:
                return
            if not self._wait(remaining):
                return
        raise RuntimeError("spin_until_future_complete(): no progress limit reached")


class SingleThreadedExecutor(Executor):
    pass


class MultiThreadedExecutor(Executor):
    def __init__(self, num_threads: int | None = None, *, context=None) -> None:
        super().__init__(context=context)
        self._num_threads = num_threads or 1


class EventsExecutor(SingleThreadedExecutor):
    pass


__all__ = ["Executor", "SingleThreadedExecutor", "MultiThreadedExecutor", "ExternalShutdownException"]
