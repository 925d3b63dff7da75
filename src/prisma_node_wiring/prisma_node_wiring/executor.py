"""The executor every node process spins, and the fast one it may be: rclpy's single-threaded one,
one wait per callback, no Task per message.

This is the one module of the suite that touches rclpy's private names (test_rclpy_public_api.py
holds every other to rclpy's public API). SingleWaitExecutor overrides SingleThreadedExecutor's
`_make_handler` and `_spin_once_impl` and reads its private state, as rclpy 7.1.3 lays it out; so
`process_executor` spins it only where executor_choice.choose_executor keeps it (an rclpy it is
proven on, and `fast_executor_self_test` passing there), and rclpy's stock SingleThreadedExecutor
anywhere else, saying which and why in one log line per process.

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
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
import rclpy.logging
from rclpy.context import Context
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription
from rclpy.timer import Timer

from prisma_node_wiring.executor_choice import (
    EVENTS,
    FAST,
    ExecutorChoice,
    choose_executor,
    rclpy_version,
    requested_executor,
)


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


# The private API SingleWaitExecutor builds on, as rclpy 7.1.3 has it: each method's parameters.
# Humble's _make_handler takes a fourth (call_coroutine) and would fail at the first spin.
FAST_EXECUTOR_OVERRIDES = {
    "_make_handler": ("self", "entity", "node", "take_from_wait_list"),
    "_spin_once_impl": ("self", "timeout_sec", "wait_condition"),
}
FAST_EXECUTOR_STATE = ("_is_shutdown", "_guard", "_work_tracker", "_context")  # read by its handlers
SELF_TEST_NODE = "_prisma_executor_self_test"  # hidden (leading underscore) from `ros2 node list`
SELF_TEST_TIMEOUT_S = 2.0  # a round takes milliseconds; a loaded machine's start gets the rest
EXECUTOR_LOGGER = "prisma_executor"


def fast_executor_self_test(context: Context | None = None) -> str | None:
    """Whether SingleWaitExecutor works on the running rclpy: the private methods it overrides have
    the parameters it passes, the private state it reads exists, and one round on a throw-away node
    of `context` (a timer publishes until its own subscription has received a message, both run by
    the direct handlers) completes. None where all holds, else what failed, in one line."""
    for name, expected in FAST_EXECUTOR_OVERRIDES.items():
        method = getattr(SingleThreadedExecutor, name, None)
        if method is None:
            return f"rclpy's SingleThreadedExecutor has no {name}"
        found = tuple(inspect.signature(method).parameters)
        if found != expected:
            return f"SingleThreadedExecutor.{name} takes ({', '.join(found)}), not ({', '.join(expected)})"
    if not callable(getattr(_rclpy, "WaitSet", None)):
        return "rclpy's implementation has no WaitSet"
    try:
        return _self_test_round(context)
    except Exception as exc:  # whatever the running rclpy does differently: the stock executor then
        return f"{type(exc).__name__}: {exc}"


def _self_test_round(context: Context | None) -> str | None:
    # any message will do: one from a package this one depends on anyway (node_parameters' descriptors)
    from rcl_interfaces.msg import IntegerRange

    # no global arguments: a launch's `__node:=` remap or parameter file is the real node's
    node = rclpy.create_node(SELF_TEST_NODE, context=context, use_global_arguments=False,
                             enable_rosout=False, start_parameter_services=False)
    executor = SingleWaitExecutor(context=context)
    try:
        missing = [name for name in FAST_EXECUTOR_STATE if not hasattr(executor, name)]
        if missing:
            return f"SingleThreadedExecutor has none of {', '.join(missing)}"
        received: list = []
        publisher = node.create_publisher(IntegerRange, "~/round", 1)
        subscription = node.create_subscription(IntegerRange, "~/round", received.append, 1)
        timer = node.create_timer(0.005, lambda: publisher.publish(IntegerRange(step=7)))
        if not (hasattr(subscription, "_executor_event") and hasattr(timer, "_executor_event")):
            return "rclpy's subscriptions and timers carry no _executor_event mark"
        executor.add_node(node)
        deadline = time.monotonic() + SELF_TEST_TIMEOUT_S
        while not received and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        if not received or received[0].step != 7:
            return f"a message its timer published never reached its subscription in {SELF_TEST_TIMEOUT_S} s"
        return None
    finally:
        executor.shutdown()
        node.destroy_node()


def events_executor_class() -> type[Executor] | None:
    """rclpy.experimental.EventsExecutor where the running rclpy has it (7.1.4 on), else None."""
    try:
        from rclpy.experimental import EventsExecutor  # type: ignore[import-not-found,unused-ignore]
    except ImportError:
        return None
    return EventsExecutor  # type: ignore[no-any-return,unused-ignore]


_choice_made: ExecutorChoice | None = None  # this process's, made once (process_executor_choice)
# made once even when two threads ask at once (a node's main and a thread of the same process that
# waits for its executor): without it each made and logged its own, and one watched an empty executor
_made_once = threading.RLock()


def _still_running(context: Context | None) -> None:
    """ExternalShutdownException when `context` (default: rclpy's) was shut down, as a stop request
    during a node's start does (a launch stopping whole): an executor made on it fails half-built and
    rclpy prints its __del__'s traceback, and a self-test run on it fails for no fault of the rclpy."""
    if not rclpy.ok(context=context):
        raise ExternalShutdownException()


def process_executor_choice(context: Context | None = None) -> ExecutorChoice:
    """This process's executor choice (PRISMA_EXECUTOR, executor_choice.choose_executor), made on first
    use (after rclpy.init; the self-test runs on `context`, default: rclpy's) and logged then, once.
    ExternalShutdownException when the context is shut down before or during the choice (nothing
    chosen, nothing logged)."""
    global _choice_made
    with _made_once:
        if _choice_made is None:
            _still_running(context)
            choice = choose_executor(requested_executor(), rclpy_version(),
                                     lambda: fast_executor_self_test(context),
                                     events_executor_class() is not None)
            _still_running(context)  # a self-test the shutdown broke says nothing of this rclpy
            _choice_made = choice
            rclpy.logging.get_logger(EXECUTOR_LOGGER).info(choice.log_line())
        return _choice_made


def new_executor(context: Context | None = None) -> Executor:
    """An executor of this process's choice (process_executor_choice) on `context`;
    ExternalShutdownException instead when the context is shut down."""
    kind = process_executor_choice(context).kind
    _still_running(context)
    if kind == FAST:
        return SingleWaitExecutor(context=context)
    events = events_executor_class()
    if kind == EVENTS and events is not None:
        return events(context=context)
    return SingleThreadedExecutor(context=context)


_process_executor: Executor | None = None


def process_executor() -> Executor:
    """The executor `run_node` spins the process's node on: one per process, made on first use (after
    rclpy.init), as rclpy's global executor is for rclpy.spin."""
    global _process_executor
    with _made_once:
        if _process_executor is None:
            _process_executor = new_executor()
        return _process_executor
