"""rclpy.context.Context, which in the stand-in also holds the in-memory ROS graph.

The graph: every node, publisher, subscription, service, client and action endpoint of the
context, and one FIFO of pending work (delivered messages, service requests and responses, action
protocol steps), each item bound to the node whose executor must run it.
"""
from __future__ import annotations

import itertools
from collections import deque
from dataclasses import dataclass, field
from typing import Callable

from ros_standin import arguments as _arguments


@dataclass
class WorkItem:
    node: object
    run: Callable[[], bool]  # returns False when it turned out to be a no-op
    label: str = ""


@dataclass
class Graph:
    nodes: list = field(default_factory=list)
    publishers: list = field(default_factory=list)
    subscriptions: list = field(default_factory=list)
    services: list = field(default_factory=list)
    clients: list = field(default_factory=list)
    action_servers: list = field(default_factory=list)
    action_clients: list = field(default_factory=list)
    queue: deque = field(default_factory=deque)
    node_created_hooks: list = field(default_factory=list)
    sequence: itertools.count = field(default_factory=itertools.count)


class Context:
    def __init__(self) -> None:
        self._ok = False
        self._args: list[str] = []
        self.parameter_overrides: list = []
        self.graph = Graph()
        self._callbacks: list = []

    def init(self, args=None, *, initialize_logging: bool = True, domain_id=None) -> None:
        if self._ok:
            raise RuntimeError("Context.init() must only be called once")
        self._args = list(args) if args is not None else []
        self.parameter_overrides, _ = _arguments.parse_ros_args(self._args)
        self.graph = Graph()
        self._ok = True

    def ok(self) -> bool:
        return self._ok

    def shutdown(self) -> None:
        if not self._ok:
            from ._rclpy_pybind11 import RCLError

            raise RCLError("failed to shutdown: rcl_shutdown already called on the given context")
        self._shutdown_nodes()
        self._ok = False
        for callback in self._callbacks:
            callback()
        self._callbacks = []

    def try_shutdown(self) -> None:
        if self._ok:
            self.shutdown()

    def _shutdown_nodes(self) -> None:
        for node in list(self.graph.nodes):
            node.destroy_node()

    def on_shutdown(self, callback) -> None:
        self._callbacks.append(callback)

    def get_domain_id(self) -> int:
        return 0

    def next_sequence(self) -> int:
        return next(self.graph.sequence)

    def post(self, node, run: Callable[[], bool], label: str = "") -> None:
        self.graph.queue.append(WorkItem(node, run, label))
