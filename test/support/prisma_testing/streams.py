"""The streams a test collects: each topic's messages in a sequence (`collect`: by the test's probe,
or by a collector process with `collect_apart`), waits on them by header stamp (the message stamped
at an instant, a follower keeping pace with its leader), and why a stream stopped arriving, said
when such a wait fails: how often this process ran its executor meanwhile, whether the topic is still
published (a fresh subscription), and where an in-process subscription's messages went (its
callbacks served or not, its DDS reader holding them untaken)."""
from __future__ import annotations

import collections
import inspect
import time
from collections.abc import Callable, Sequence
from typing import Any


def stamp_ns(msg: Any) -> int:
    """Nanoseconds of a message's header stamp."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def stamped_after(received: Sequence, t_ns: int) -> list:
    """The messages of a `collect` sequence (in stamp order) stamped after `t_ns`, oldest first;
    walked from the newest, so a wait that asks at every spin costs what it finds, not the whole list."""
    found = []
    for m in reversed(received):
        if stamp_ns(m) <= t_ns:
            break
        found.append(m)
    return found[::-1]


class SpinCount:
    """How often a wait ran the executor and its longest gap: a process kept from running shows
    as few spins with a long gap, a stalled subscription as many spins and nothing received."""

    def __init__(self) -> None:
        self.count = 0
        self.longest_gap = 0.0
        self._last = time.monotonic()

    def tick(self) -> None:
        """One more spin (returns None: usable inside a wait's condition)."""
        now = time.monotonic()
        self.longest_gap = max(self.longest_gap, now - self._last)
        self._last = now
        self.count += 1

    def __str__(self) -> str:
        return f"{self.count} spins, longest gap {self.longest_gap:.3f} s"


class Streams:
    """RosHarness's collections (a mixin: RosHarness owns the probe, spins and keeps the clock)."""

    probe: Any
    executor: Any
    spin_until: Callable[..., bool]
    spin_for: Callable[[float], None]
    now_ns: Callable[[], int]

    def __init__(self) -> None:
        super().__init__()
        self._collect_apart = False  # RosHarness(collect_apart=True) sets it
        self._collecting: dict[int, Any] = {}  # id of an in-process collect() list -> its subscription
        self._collector: Any = None  # the collector process, started by the first collect apart
        self._collections: list = []  # the collector's

    def collect(self, msg_type: type, topic: str, qos_profile: Any = None) -> Sequence:
        """A sequence that fills with every message received on `topic` (depth 1000: bursts fit), in
        arrival order; taken by the collector process with `collect_apart`."""
        from rclpy.event_handler import SubscriptionEventCallbacks
        from rclpy.qos import QoSProfile

        if self._collect_apart:
            from prisma_testing.collector import Collector

            if self._collector is None:
                self._collector = Collector()
            collection = self._collector.collect(msg_type, topic, qos_profile)
            self._collections.append(collection)
            return collection
        received: list = []
        # without rclpy's QoS-event waitables, as the nodes' streams: a probe collecting a dozen 100 Hz
        # topics would spend more CPU walking them than the graph it observes
        subscription = self.probe.create_subscription(
            msg_type, topic, received.append, qos_profile or QoSProfile(depth=1000),
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self._collecting[id(received)] = subscription
        return received

    def stop_collecting(self, *lists: list) -> None:
        """Close the subscriptions that fill these `collect` lists: a probe still taking dozens of
        100 Hz topics a test is done with leaves the executor little time for the next test's."""
        for received in lists:
            if any(received is c for c in self._collections):
                self._collector.stop(received)
                self._collections.remove(received)
            else:
                self.probe.destroy_subscription(self._collecting.pop(id(received)))

    def message_at(self, received: Sequence, seconds_from_now: float, timeout_sec: float = 10.0) -> Any:
        """The first message in `received` (a `collect` list) stamped `seconds_from_now` or later,
        waiting for it. On a loaded machine this process receives a stream late: after a sleep,
        `received[-1]` can still be a message from before it (AssertionError at the timeout)."""
        return self.message_stamped(received, self.now_ns() + int(seconds_from_now * 1e9),
                                    timeout_sec + seconds_from_now)

    def message_stamped(self, received: Sequence, at_ns: int, timeout_sec: float = 10.0) -> Any:
        """The first message in `received` (a `collect` list, in stamp order) stamped `at_ns` or
        later, waiting up to `timeout_sec` for it (AssertionError naming the newest stamp and why)."""
        def found() -> Any:
            after = stamped_after(received, at_ns - 1)
            return after[0] if after else None

        spins = SpinCount()  # spin_until checks its condition once per spin
        if not self.spin_until(lambda: spins.tick() or found() is not None, timeout_sec):
            newest = f"{(stamp_ns(received[-1]) - at_ns) * 1e-9:+.3f} s" if received else "none"
            raise AssertionError(f"newest: {newest}; {spins}; {self._stream_check(received)}")
        return found()

    def wait_until_keeping_up(self, leader: Sequence, follower: Sequence, lag_sec: float, checks: int = 20,
                              timeout_sec: float = 60.0, period_sec: float = 0.1) -> None:
        """Wait until the latest header stamp in `follower` (a `collect` list) is within `lag_sec` of
        the latest in `leader` at `checks` checks in a row, `period_sec` apart: a downstream node
        has warmed up and keeps pace (AssertionError with the last lag at the timeout)."""
        deadline = time.monotonic() + timeout_sec
        good, lag = 0, None
        while good < checks:
            if time.monotonic() > deadline:
                raise AssertionError(f"still {lag} s behind after {timeout_sec} s")
            self.spin_for(period_sec)
            lag = (stamp_ns(leader[-1]) - stamp_ns(follower[-1])) * 1e-9 if leader and follower else None
            good = good + 1 if lag is not None and lag < lag_sec else 0

    def _stream_check(self, received: Any) -> str:
        """Why the stream `received` collects stopped: `_fresh_look`, or that its collector exited."""
        if any(received is c for c in self._collections):
            collector = self._collector.proc
            if collector.poll() is not None:
                return (f"{received.topic}: the collector exited ({collector.returncode}): "
                        f"{self._collector.stderr_tail(1500)}")
            return self._fresh_look(received, received.topic, received.msg_type)
        subscription = self._collecting.get(id(received))
        if subscription is None:
            return "its subscription is closed"
        return self._fresh_look(received, subscription.topic_name, subscription.msg_type, subscription)

    def _fresh_look(self, received: Sequence, topic: str, msg_type: type, subscription: Any = None,
                    seconds: float = 2.0) -> str:
        """Whether the stream a `collect` list stopped receiving is still published: a fresh
        subscription to its topic for `seconds` tells a silent publisher from a stalled reader; with the
        collecting `subscription` (in-process), its `_reader_state` too."""
        reader = "" if subscription is None else f"; {self._reader_state(subscription)}"
        fresh: list = []
        check = self.probe.create_subscription(msg_type, topic, fresh.append, 1000)
        try:
            self.spin_for(seconds)
        finally:
            self.probe.destroy_subscription(check)
        publishers = self.probe.count_publishers(topic)
        if not fresh:
            return f"{topic}: {publishers} publisher(s), a fresh subscription received nothing in {seconds} s"
        newest = (stamp_ns(fresh[-1]) - self.now_ns()) * 1e-9
        return (f"{topic}: {publishers} publisher(s), a fresh subscription received {len(fresh)} in "
                f"{seconds} s (newest {newest:+.3f} s), the collecting one {len(received)} in all{reader}")

    def _reader_state(self, subscription: Any) -> str:
        """Why a collecting subscription's messages stopped: how many callbacks per stream this
        process's executor ran in the next second (a process kept from the CPU serves every stream a
        few times; a stalled subscription none), and how many messages its DDS reader then held
        untaken (taken now, as its handler would; thousands: the executor is behind, none: DDS never
        delivered them). Whether the executor would take it now tells an rclpy stall (a subscription
        marked taken by a handler that never ran is left out of every wait set)."""
        served: collections.Counter = collections.Counter()
        wrapped = [s for node in self.executor.get_nodes() for s in node.subscriptions]
        callbacks = [s.callback for s in wrapped]

        def counted(topic: str, callback: Callable) -> Callable:
            def call(*args: Any) -> Any:
                served[topic] += 1
                return callback(*args)

            async def call_async(*args: Any) -> Any:  # awaited by the executor, as the callback was
                served[topic] += 1
                return await callback(*args)
            return call_async if inspect.iscoroutinefunction(callback) else call

        for s, callback in zip(wrapped, callbacks):
            s.callback = counted(s.topic_name, callback)
        try:
            self.spin_for(1.0)
        finally:
            for s, callback in zip(wrapped, callbacks):
                s.callback = callback
        can_execute = getattr(self.executor, "can_execute", None)  # the events executor has none
        takes = "?" if can_execute is None else can_execute(subscription)
        held = 0
        with subscription.handle:
            while held < 10_000 and subscription.handle.take_message(subscription.msg_type, False):
                held += 1
        return (f"callbacks in the next 1 s: {dict(served)}; its reader then held {held} untaken; "
                f"the executor would take it now: {takes}")

    def _close_streams(self) -> None:
        """Stop the collector process and remove its files (the probe's subscriptions go with it)."""
        if self._collector is not None:
            self._collector.close()
            self._collector = None
            for collection in self._collections:
                collection.close()
            self._collections.clear()
