"""The /clock a test drives: nodes made with `sim_time=True` (RosHarness.node) run on the sim time
RosHarness publishes (`set_time`, `advance`), so stamps and timer instants are exact, and with
`settle` each instant is complete before the clock moves on."""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


class SimClock:
    """RosHarness's sim time (a mixin: RosHarness owns the probe, the executor and `settle`)."""

    START_NS = 1_700_000_000 * 10**9  # where sim time starts: far from 0 like a real clock
    SPIN_SEC: float
    probe: Any
    executor: Any
    settle: Callable[[], None]

    def __init__(self) -> None:
        super().__init__()
        self.sim_nodes: list = []
        self._sim_now: int | None = None
        self._clock_pub: Any = None

    def follow_clock(self, node: Any) -> None:
        """Run `node` (made with use_sim_time) on this clock, from now (START_NS for the first)."""
        self.sim_nodes.append(node)
        self.set_time(self._sim_now if self._sim_now is not None else self.START_NS)

    def now_ns(self) -> int:
        """Sim time once a sim-time node exists, else wall time."""
        return self._sim_now if self._sim_now is not None else time.time_ns()

    def set_time(self, stamp_ns: int, settle: bool = False) -> None:
        """Publish /clock = stamp_ns and wait until every sim-time node's clock reads it (then,
        with `settle`, until the callbacks of that instant are all done)."""
        from builtin_interfaces.msg import Time
        from rclpy.qos import QoSProfile
        from rosgraph_msgs.msg import Clock

        if self._clock_pub is None:
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

    def advance(self, seconds: float, step: float = 0.001, settle: bool = False) -> None:
        """Move sim time forward by `seconds` in `step`s, letting due timers run at each step (with
        `settle`, everything each step set off; see RosHarness.settle)."""
        target = self.now_ns() + round(seconds * 1e9)
        step_ns = round(step * 1e9)
        while self.now_ns() < target:
            self.set_time(min(self.now_ns() + step_ns, target), settle=settle)
