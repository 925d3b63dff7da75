"""The process around a node: every node's `main()` runs it through `run_node`.

A node process ends one of three ways, and the exit status says which:
- ctrl-C, SIGTERM or `ros2 launch` shutting down: exit 0, no traceback, whatever the node was doing
  at that instant (rclpy's signal handler shuts the context down under a running callback, so a
  publish raises RCLError and a constructor still starting up raises other errors);
- a configuration error the operator fixes (a parameter value, a model bundle, PRISMA_EXECUTOR or
  the priority variables): logged as fatal with the message that names the value, exit 1;
- anything else while the context is still up: a bug, re-raised with its traceback.
"""
from __future__ import annotations

import gc
import signal
from collections.abc import Callable

import rclpy
import rclpy.logging
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from prisma_common.scheduling import apply_priority, priority_from_env
from prisma_node_wiring.executor import process_executor
from prisma_node_wiring.executor_choice import requested_executor

SHUTDOWN_CHECK_PERIOD_S = 0.25  # the longest a stop request can wait when rclpy's wake-up comes too early


def settle_garbage_collector() -> None:
    """Collect once, then exempt everything alive from later collections (gc.freeze).

    A node starts with 30-40 thousand objects (rclpy, numpy, its modules) that live as long as it
    does, and every full collection walks them all: 10-25 ms on the project's 2-core development
    machine when idle, longer beside a memory-bandwidth hog, a pause the 100 ms stale rule counts
    against the stream. Frozen, a full collection walks only what the node allocated since.
    """
    gc.collect()
    gc.freeze()


def run_node(make_node: Callable[[], Node], logger_name: str,
             config_errors: tuple[type[Exception], ...], args: list[str] | None = None) -> None:
    """Start the node `make_node()` builds and spin it until the process is told to stop."""
    # ctrl-C is rclpy's: its handler shuts the context down and spin() ends with
    # ExternalShutdownException. Python's KeyboardInterrupt on top would land wherever the main thread
    # is, inside rclpy's message conversion too, where it turns into a RuntimeError.
    signal.signal(signal.SIGINT, lambda signum, frame: None)
    try:
        priority = priority_from_env()
        requested_executor()  # a PRISMA_EXECUTOR that names no executor stops the node before it starts
    except ValueError as exc:
        rclpy.logging.get_logger(logger_name).fatal(str(exc))
        raise SystemExit(1) from None
    if priority is not None:
        apply_priority(None, priority[1])  # the start time-shared, at the niceness (scheduling.py)
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        if priority is not None:
            # every thread, DDS's and the executor's included, onto the rung once the node is built
            node.get_logger().info(f"scheduling: {apply_priority(*priority)}")
        # rclpy's SIGINT handler wakes the executor by a guard condition and shuts the context down
        # from its own thread; when the executor wakes first (seen under load) it goes back to
        # waiting, and a node with no timer of its own (glove_perception) then never sees the
        # shutdown. A steady-clock timer bounds that to one period, whatever the node's clock.
        node.create_timer(SHUTDOWN_CHECK_PERIOD_S, lambda: None, clock=Clock(clock_type=ClockType.STEADY_TIME))
        settle_garbage_collector()
        # the executor PRISMA_EXECUTOR and the running rclpy allow, logged once (executor.py); a node
        # stopped while it started (a launch that stops whole when another node failed at start) gets
        # ExternalShutdownException from it instead, before or during the choice's self-test
        rclpy.spin(node, executor=process_executor())
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except config_errors as exc:
        rclpy.logging.get_logger(logger_name).fatal(str(exc))
        raise SystemExit(1) from None
    except Exception:
        if rclpy.ok():
            raise
        # the context was shut down under the node by a stop request: a normal stop
    finally:
        if node is not None:
            try:
                node.destroy_node()
            except Exception:
                if rclpy.ok():
                    raise
        rclpy.try_shutdown()
        # stopping now: a terminal's Ctrl-C reaches every process of a launch and launch forwards one
        # more, and a SIGINT that lands while Python finalises (which puts a handler back to the
        # default, never an ignored signal) would kill the node by the signal (exit -2)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
