"""Record and read ROS 2 bags (MCAP by default, sqlite3 on request) with prisma_msgs types.

A bag is written whole or not at all: BagWriter records into `<bag>.partial-<pid>/<bag>/` and
renames it to `<bag>` on close, and an exception (or ctrl-C) inside its `with` block deletes it,
so nothing at `<bag>` ever looks complete while it is not. rosbags is imported when a bag is
written or read, not with this module.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .atomic import atomic_output
from .typestore import get_typestore, message_definition

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader

# storage name -> rosbags StoragePlugin member
STORAGE = {"mcap": "MCAP", "sqlite3": "SQLITE3"}


class BagError(ValueError):
    """A bag that cannot be read, or lacks topics a tool needs; the message names the bag, the
    missing topics and the topics it has."""


class MissingTopicsError(BagError):
    def __init__(self, path: str | Path, missing: list[str], present: dict[str, str]) -> None:
        self.path, self.missing, self.present = str(path), list(missing), dict(present)
        has = ", ".join(f"{t} ({m})" for t, m in sorted(present.items())) or "no topics at all"
        topics = "topic" if len(missing) == 1 else "topics"
        super().__init__(f"bag {path} has no {topics} {', '.join(map(repr, missing))}; it has: {has}")


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
    sensor's time line (logic uses header stamps, docs/architecture.md).
    """

    def __init__(self, path: str | Path, storage: str = "mcap", replace: bool = False) -> None:
        """`replace`: an existing bag at `path` is replaced when this one is complete (the caller
        has checked that it is a bag); otherwise an existing `path` raises FileExistsError."""
        if storage not in STORAGE:
            raise ValueError(f"storage must be one of {sorted(STORAGE)}, got {storage!r}")
        self.path = Path(path)
        self._typestore = get_typestore()
        self._output = atomic_output(self.path, replace=replace)
        staged = self._output.open()
        try:
            from rosbags.rosbag2 import StoragePlugin, Writer

            self._writer = Writer(staged, version=9, storage_plugin=getattr(StoragePlugin, STORAGE[storage]))
            self._writer.open()
        except BaseException:
            self._output.abort()
            raise
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self._closed = False

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
        """Finish the bag and move it into place at `path`."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
        except BaseException:
            self._output.abort()
            raise
        self._output.commit()

    def abort(self) -> None:
        """Drop the bag: nothing appears at `path` (an earlier bag there stays)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()
        finally:
            self._output.abort()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def _reader(path: str | Path) -> AnyReader:
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise BagError(f"bag {path} does not exist")
    return AnyReader([path], default_typestore=get_typestore())


@contextmanager
def _open_reader(path: str | Path) -> Iterator[AnyReader]:
    """The bag opened for reading; BagError, in one line, for one that cannot be."""
    from rosbags.highlevel import AnyReaderError

    try:
        reader = _reader(path)
        reader.open()
    except (AnyReaderError, OSError) as exc:  # no metadata.yaml, an unknown file type, a damaged file
        raise BagError(f"{path} is not a readable ROS 2 bag (a directory with metadata.yaml, or an "
                       f".mcap/.db3 file): {exc}") from None
    except KeyError as exc:  # rosbags meets an MCAP schema encoding it has no reader for
        raise BagError(_undefined_schema_message(Path(path), str(exc.args[0]) if exc.args else "")) from None
    try:
        yield reader
    finally:
        reader.close()


# rosbag2 records action feedback (`<pkg>/action/<Action>_FeedbackMessage`) without a message definition
FEEDBACK_TYPE_SUFFIX = "_FeedbackMessage"


def _undefined_schema_message(path: Path, encoding: str) -> str:
    """Why a bag whose MCAP holds a schema rosbags cannot read is refused, naming the topics that
    rosbag2 records so (action feedback) where its metadata.yaml lists them, and what to do."""
    feedback = [f"{name} ({msgtype})" for name, msgtype in _listed_topics(path).items()
                if msgtype.endswith(FEEDBACK_TYPE_SUFFIX)]
    which = f": {', '.join(feedback)}" if feedback else " (rosbag2 records action feedback so)"
    return (f"bag {path} holds topics recorded without a message definition (schema encoding {encoding!r}), "
            f"which the bag tools cannot read{which}; record action topics into a bag of their own and give "
            f"the tools the bag of sensor topics (docs/recording.md, \"Record and replay\")")


def _listed_topics(path: Path) -> dict[str, str]:
    """topic -> type as the bag directory's metadata.yaml lists them; empty when there is none to read."""
    import yaml

    try:
        info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        return {t["topic_metadata"]["name"]: t["topic_metadata"]["type"] for t in info["topics_with_message_count"]}
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return {}


def bag_topics(path: str | Path) -> dict[str, str]:
    """topic -> message type of every connection in the bag; BagError if it is not a readable bag."""
    with _open_reader(path) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def require_topics(path: str | Path, topics: Iterable[str]) -> dict[str, str]:
    """The bag's topics; MissingTopicsError naming every absent one of `topics` and what the bag has."""
    present = bag_topics(path)
    missing = [t for t in dict.fromkeys(topics) if t not in present]
    if missing:
        raise MissingTopicsError(path, missing, present)
    return present


def read_bag(path: str | Path, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in log-time order, deserialised with the prisma typestore; with `topics`,
    only those (none at all if the bag has none of them)."""
    wanted = set(topics) if topics is not None else None
    with _open_reader(path) as reader:
        connections = [c for c in reader.connections if wanted is None or c.topic in wanted]
        if wanted is not None and not connections:
            return  # rosbags reads an empty connection list as "every topic"
        for connection, timestamp, raw in reader.messages(connections=connections):
            message = reader.deserialize(raw, connection.msgtype)
            yield BagMessage(connection.topic, connection.msgtype, timestamp, message)
