"""Record and read ROS 2 bags (MCAP by default, sqlite3 on request) with prisma_msgs types."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer

from .typestore import get_typestore, message_definition

STORAGE = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}


@dataclass
class BagMessage:
    topic: str
    msgtype: str
    timestamp_ns: int
    message: Any


def stamp_ns(message: Any) -> int | None:
    """Nanoseconds of message.header.stamp, or None for messages without a header."""
    header = getattr(message, "header", None)
    if header is None:
        return None
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


class BagWriter:
    """Write typestore messages to a new bag directory; one connection per topic.

    Receive time defaults to the message's header stamp, so replayed bags keep the
    sensor's time line (logic uses header stamps, DESIGN.md section 4).
    """

    def __init__(self, path: str | Path, storage: str = "mcap") -> None:
        if storage not in STORAGE:
            raise ValueError(f"storage must be one of {sorted(STORAGE)}, got {storage!r}")
        self.path = Path(path)
        self._typestore = get_typestore()
        self._writer = Writer(self.path, version=9, storage_plugin=STORAGE[storage])
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self._writer.open()

    def write(self, topic: str, message: Any, timestamp_ns: int | None = None) -> None:
        msgtype = message.__msgtype__
        connection = self._connections.get(topic)
        if connection is None:
            msgdef, rihs01 = message_definition(msgtype)
            connection = self._writer.add_connection(topic, msgtype, msgdef=msgdef, rihs01=rihs01)
            self._connections[topic] = connection
        elif connection.msgtype != msgtype:
            raise TypeError(f"topic {topic!r} carries {connection.msgtype}, not {msgtype}")
        if timestamp_ns is None:
            timestamp_ns = stamp_ns(message)
        if timestamp_ns is None:
            raise ValueError(f"{msgtype} on {topic!r} has no header; pass timestamp_ns")
        data = self._typestore.serialize_cdr(message, msgtype)
        self._writer.write(connection, timestamp_ns, bytes(data))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def write_all(self, items: Iterable[tuple[str, Any]]) -> None:
        for topic, message in items:
            self.write(topic, message)

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_bag(path: str | Path, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in log-time order, deserialised with the prisma typestore."""
    wanted = set(topics) if topics is not None else None
    with AnyReader([Path(path)], default_typestore=get_typestore()) as reader:
        connections = [c for c in reader.connections if wanted is None or c.topic in wanted]
        for connection, timestamp, raw in reader.messages(connections=connections):
            message = reader.deserialize(raw, connection.msgtype)
            yield BagMessage(connection.topic, connection.msgtype, timestamp, message)
