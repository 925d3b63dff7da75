"""A display node's inputs taken at the display's rate, not the sensors'.

rclpy spends 100-200 us of Python on every message a node takes, whatever its callback then does:
a node that draws 100 Hz streams at 25 Hz still paid for all of them. A DisplayGate is a callback
group (rclpy's public CallbackGroup, extended as its docstring asks) whose subscriptions each run at
most once per `open()`: the node's display timer opens it, each input's newest message is taken,
and the gate stays shut until the next tick. A shut subscription is left out of the executor's wait
set, so what arrives meanwhile stays in DDS; with a keep-last depth of 1 (DISPLAY_DEPTH) each new
sample replaces the one before there and the one taken at the tick is the newest. The samples in
between are dropped unread: never deserialised, never seen by Python.

Honoured by rclpy's SingleThreadedExecutor and the nodes' SingleWaitExecutor (both ask the group
before adding an entity to the wait set and before running it); rclpy's EventsExecutor is untested
here.
"""
from __future__ import annotations

from typing import Any

from rclpy.callback_groups import CallbackGroup

DISPLAY_DEPTH = 1  # keep only the newest sample of each gated input: the one taken at a tick


class DisplayGate(CallbackGroup):
    def __init__(self) -> None:
        super().__init__()
        self._ran: set[int] = set()  # ids of the entities that ran (or run) since the last open()

    def open(self) -> None:
        """Let each entity of the group run once more (the display's tick)."""
        self._ran.clear()

    def can_execute(self, entity: Any) -> bool:
        return id(entity) not in self._ran

    def beginning_execution(self, entity: Any) -> bool:
        if id(entity) in self._ran:
            return False
        self._ran.add(id(entity))
        return True

    def ending_execution(self, entity: Any) -> None:
        """Nothing to release: the entity stays shut until the next open()."""
