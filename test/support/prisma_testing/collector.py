"""A test's collections kept by a process of its own: every message of the topics a launch test
checks, taken as serialized bytes and appended to a file per topic, which the test reads when it looks.

    collector = Collector()                                   # the test's side (RosHarness does this)
    joints = collector.collect(JointState, "/joint_states")   # a Sequence that fills as the file grows
    joints[-1].position                                       # deserialized on first access
    collector.close()

Why a process apart: a launch test's own process, at the default priority beside a busy machine,
ran 130-190 executor callbacks a second against the ~750 messages a second its 100 Hz collections
receive, so every wait for "the message stamped now" worked through seconds of backlog
(docs/performance.md). rclpy's executor takes one message per Python callback; here the callback only
appends bytes to a file, at priorities.TEST_COLLECTOR_NICE, and the test process takes no
message at all: it reads the files' new bytes and deserializes only the messages it looks at.

Requests (stdin, one JSON line each; one JSON line answers each):
- collect(path, module, name, qos): subscribe to the topic with the message class `module.name` and
  the QoS fields, appending `<u32 length><CDR bytes>` per message to `path`;
- stop(path): close that subscription and its file.
The process ends when its input ends.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import queue
import shutil
import struct
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence
from typing import Any, overload

from prisma_testing.json_line_process import JsonLineProcess
from prisma_testing.priorities import TEST_COLLECTOR_NICE

_LENGTH = struct.Struct("<I")


def _qos_fields(qos_profile: Any) -> dict[str, int]:
    """A QoSProfile (or a depth, or None: depth 1000, as RosHarness.collect) as plain numbers."""
    from rclpy.qos import QoSProfile

    if qos_profile is None:
        qos_profile = QoSProfile(depth=1000)
    elif isinstance(qos_profile, int):
        qos_profile = QoSProfile(depth=qos_profile)
    return {"history": int(qos_profile.history), "depth": int(qos_profile.depth),
            "reliability": int(qos_profile.reliability), "durability": int(qos_profile.durability)}


class Collection(Sequence):
    """The messages of one topic the collector process has taken so far, in arrival order; each
    access first reads what it appended since (complete records only)."""

    def __init__(self, path: str, msg_type: type, topic: str) -> None:
        self.path, self.msg_type, self.topic = path, msg_type, topic
        self._fd: int | None = os.open(path, os.O_RDONLY)
        self._pending = b""
        self._raw: list[bytes] = []
        self._messages: list[Any] = []  # None until deserialized

    def _refresh(self) -> None:
        if self._fd is None:  # closed: it holds what it took
            return
        while chunk := os.read(self._fd, 1 << 20):
            self._pending += chunk
        data, at = self._pending, 0
        while at + _LENGTH.size <= len(data):
            (length,) = _LENGTH.unpack_from(data, at)
            if at + _LENGTH.size + length > len(data):
                break
            self._raw.append(data[at + _LENGTH.size: at + _LENGTH.size + length])
            at += _LENGTH.size + length
        self._pending = data[at:]
        self._messages.extend([None] * (len(self._raw) - len(self._messages)))

    def _message(self, index: int) -> Any:
        msg = self._messages[index]
        if msg is None:
            from rclpy.serialization import deserialize_message

            msg = self._messages[index] = deserialize_message(self._raw[index], self.msg_type)
        return msg

    def __len__(self) -> int:
        self._refresh()
        return len(self._raw)

    @overload
    def __getitem__(self, index: int) -> Any: ...
    @overload
    def __getitem__(self, index: slice) -> list: ...
    def __getitem__(self, index: int | slice) -> Any:
        self._refresh()
        if isinstance(index, slice):
            return [self._message(i) for i in range(*index.indices(len(self._raw)))]
        if not -len(self._raw) <= index < len(self._raw):
            raise IndexError(f"{self.topic}: message {index} of {len(self._raw)}")
        return self._message(index % len(self._raw))

    def __iter__(self) -> Iterator[Any]:
        self._refresh()
        return (self._message(i) for i in range(len(self._raw)))

    def __reversed__(self) -> Iterator[Any]:
        self._refresh()
        return (self._message(i) for i in range(len(self._raw) - 1, -1, -1))

    def __add__(self, other: Sequence) -> list:  # as the in-process collections' lists concatenate
        return [*self, *other]

    def __radd__(self, other: Sequence) -> list:
        return [*other, *self]

    def __repr__(self) -> str:
        return f"<Collection {self.topic}: {len(self)} messages>"

    def close(self) -> None:
        """Read what its file holds and close it (once the collector stopped writing it)."""
        self._refresh()
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


class Collector(JsonLineProcess):
    """The test's end: starts the collector process and asks it to collect topics."""

    def __init__(self, start_timeout_s: float = 60.0) -> None:
        self.folder = tempfile.mkdtemp(prefix="prisma-collector-")
        super().__init__([sys.executable, "-m", "prisma_testing.collector", "--nice", str(TEST_COLLECTOR_NICE)],
                         "collector", {**os.environ, "PYTHONUNBUFFERED": "1"})
        self._count = 0
        self.call("ping", start_timeout_s)

    def collect(self, msg_type: type, topic: str, qos_profile: Any = None) -> Collection:
        """A Collection of every message on `topic` from now on (the subscription exists on return)."""
        self._count += 1
        path = os.path.join(self.folder, f"{self._count}.cdr")
        open(path, "xb").close()
        self.call("collect", 30.0, path=path, topic=topic, module=msg_type.__module__,
                  name=msg_type.__qualname__, qos=_qos_fields(qos_profile))
        return Collection(path, msg_type, topic)

    def stop(self, collection: Collection) -> None:
        """Stop taking the collection's topic (what it holds stays readable)."""
        self.call("stop", 30.0, path=collection.path)
        collection.close()

    def close(self) -> None:
        """Stop the process and remove the folder of files it made."""
        super().close()
        shutil.rmtree(self.folder, ignore_errors=True)


# ---- the collector's end ------------------------------------------------------------------------------
class _CollectorNode:
    """Subscriptions taken without an executor: one wait for all of them, then every message each has
    queued taken and appended to its file in one write. rclpy's executor runs one Python callback per
    message (bench_collector's 600 messages a second: 23.7% of a core on the executor, 10.1% without;
    docs/performance.md). Requests come from the stdin thread through a queue and a guard condition,
    and are served in this loop's thread."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.guard_condition import GuardCondition

        self.node = rclpy.create_node("test_collector")
        self.requests: queue.Queue = queue.Queue()
        self.wake = GuardCondition(None, None, context=self.node.context)
        self.open: dict[str, tuple[Any, int]] = {}  # path -> (subscription, fd)
        self.ended = False

    def run(self) -> None:
        """Take and write until the input ends (`end`)."""
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        while not self.ended:
            subscriptions = list(self.open.items())
            wait_set = _rclpy.WaitSet(len(subscriptions), 1, 0, 0, 0, 0, self.node.context.handle)
            wait_set.add_guard_condition(self.wake.handle)
            for subscription, _ in (entry for _, entry in subscriptions):
                wait_set.add_subscription(subscription.handle)
            wait_set.wait(-1)
            ready = wait_set.get_ready_entities("subscription")
            for _, (subscription, fd) in subscriptions:
                if subscription.handle.pointer in ready:
                    self._drain(subscription, fd)
            self._serve()  # a request changes the subscriptions: the next wait set has them

    @staticmethod
    def _drain(subscription: Any, fd: int) -> None:
        records = []
        while (taken := subscription.handle.take_message(subscription.msg_type, True)) is not None:
            records += [_LENGTH.pack(len(taken[0])), taken[0]]
        if records:
            os.write(fd, b"".join(records))  # whole records in one write: a reader sees them or none

    def _serve(self) -> None:
        while not self.requests.empty():
            request = self.requests.get()
            try:
                answer = getattr(self, f"_{request.pop('op')}")(**request)
            except Exception as exc:  # noqa: BLE001 - the test reads the reason
                answer = {"error": f"{type(exc).__name__}: {exc}"}
            print(json.dumps(answer), flush=True)

    def _ping(self) -> dict:
        return {}

    def _end(self) -> dict:
        self.ended = True
        return {}

    def _collect(self, path: str, topic: str, module: str, name: str, qos: dict[str, int]) -> dict:
        from rclpy.event_handler import SubscriptionEventCallbacks
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        msg_type = importlib.import_module(module)
        for part in name.split("."):
            msg_type = getattr(msg_type, part)
        profile = QoSProfile(history=HistoryPolicy(qos["history"]), depth=qos["depth"],
                             reliability=ReliabilityPolicy(qos["reliability"]),
                             durability=DurabilityPolicy(qos["durability"]))
        subscription = self.node.create_subscription(  # taken by run(), never by a callback
            msg_type, topic, lambda _: None, profile, raw=True,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self.open[path] = (subscription, os.open(path, os.O_WRONLY | os.O_APPEND))
        return {}

    def _stop(self, path: str) -> dict:
        subscription, fd = self.open.pop(path)
        self._drain(subscription, fd)
        self.node.destroy_subscription(subscription)
        os.close(fd)
        return {}

    def close(self) -> None:
        for path in list(self.open):
            self._stop(path)
        self.wake.destroy()
        self.node.destroy_node()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nice", type=int, default=0,
                        help="niceness of the process (its DDS threads too) where permitted")
    args = parser.parse_args(argv)
    try:
        os.setpriority(os.PRIO_PROCESS, 0, args.nice)  # before rclpy starts DDS's threads: they inherit it
    except PermissionError:
        pass  # runs on at the default

    import rclpy

    rclpy.init()
    collector = _CollectorNode()

    def read_requests() -> None:
        for line in sys.stdin:
            collector.requests.put(json.loads(line))
            collector.wake.trigger()
        collector.requests.put({"op": "end"})
        collector.wake.trigger()

    threading.Thread(target=read_requests, daemon=True).start()
    try:
        collector.run()
    finally:
        collector.close()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
