"""RosHarness.settle(): the barrier the sim-time node tests advance the clock behind.

settle() must not return while a callback it ran has set off another. rclpy starts a pass's quiet
timer when the pass starts; a pass that first resumes a slow coroutine (a goal's execute callback
on a busy machine) finds the timer run out when it waits, gets back what is ready at once, runs it,
and ends "timed out". Beside the load harness that ended a test's sim instant before the abort its
stale sample set off.
"""
from __future__ import annotations

import time

from prisma_testing.ros_harness import RosHarness, require_ros

require_ros()

from rclpy.node import Node  # noqa: E402
from std_msgs.msg import String  # noqa: E402


class Relay(Node):
    """What a node does with a message: another message, here on `second`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("relay", **kwargs)
        self.out = self.create_publisher(String, "second", 10)
        self.create_subscription(String, "first", self.out.publish, 10)


class _Yield:
    def __await__(self):
        yield


async def slow_coroutine(done: list[bool]) -> None:
    """A coroutine task that takes longer than settle's quiet window each time it is resumed."""
    while not done:
        time.sleep(2 * RosHarness.SPIN_SEC)  # settle's default quiet window
        await _Yield()


def test_settle_runs_what_a_callback_set_off_when_the_quiet_timer_ran_out_before_the_wait(ros):
    relay = ros.node(Relay)
    second = ros.collect(String, "second")
    assert ros.spin_until(lambda: relay.out.get_subscription_count() >= 1, 10.0)
    done: list[bool] = []
    ros.executor.create_task(slow_coroutine(done))
    ros.publish("first", String(data="grasp"))  # in the relay's queue: settle's first pass runs it
    try:
        ros.settle()
        assert [m.data for m in second] == ["grasp"]
    finally:
        done.append(True)
        ros.spin_for(0.05)


def test_settle_returns_while_a_coroutine_still_awaits(ros):
    """A goal's execute callback awaits its end for the whole goal: polling it is not work."""
    done: list[bool] = []
    ros.executor.create_task(slow_coroutine(done))
    start = time.monotonic()
    try:
        ros.settle(timeout_sec=5.0)
    finally:
        done.append(True)
        ros.spin_for(0.05)
    assert time.monotonic() - start < 1.0


def test_settle_returns_with_nothing_to_run(ros):
    start = time.monotonic()
    ros.settle()
    assert time.monotonic() - start < 1.0
