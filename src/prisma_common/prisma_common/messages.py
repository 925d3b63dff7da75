"""Helpers every converter uses: stamps and headers from integer nanoseconds, the container a message
class takes for an array field (`sequence_field`), and `robot_types`, the node's message-class lookup.

Converters take a message-class lookup `types(name)`: on the robot `robot_types` over
`rosidl_runtime_py`, off-robot `prisma_common.typestore.types`. No ROS import here.
"""
from __future__ import annotations

import array
import functools
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

Types = Callable[[str], Any]
NS_PER_S = 1_000_000_000


def stamp_from_ns(types: Types, stamp_ns: int) -> Any:
    """builtin_interfaces/msg/Time from integer nanoseconds (non-negative)."""
    stamp_ns = int(stamp_ns)
    if stamp_ns < 0:
        raise ValueError(f"stamp_ns must be >= 0, got {stamp_ns}")
    sec, nanosec = divmod(stamp_ns, NS_PER_S)
    return types("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec)


def ns_from_stamp(stamp: Any) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def make_header(types: Types, stamp_ns: int, frame_id: str) -> Any:
    return types("std_msgs/msg/Header")(stamp=stamp_from_ns(types, stamp_ns), frame_id=frame_id)


def newest_header(types: Types, messages: Iterable[Any], frame_id: str = "") -> Any:
    """The header of a per-hand message: the newest stamp among the stamped `messages` it carries
    (0 when it carries none)."""
    return make_header(types, max((ns_from_stamp(m.header.stamp) for m in messages), default=0), frame_id)


# rosidl_generator_py's typecodes for numeric sequences (its SPECIAL_NESTED_BASIC_TYPES).
_TYPECODES = {np.dtype(t): code for t, code in (
    (np.float32, "f"), (np.float64, "d"), (np.int8, "b"), (np.uint8, "B"), (np.int16, "h"),
    (np.uint16, "H"), (np.int32, "i"), (np.uint32, "I"), (np.int64, "q"), (np.uint64, "Q"))}


def is_rosidl_class(message_class: Any) -> bool:
    """True for rclpy's generated message classes (and the test stand-in's), False for rosbags
    typestore classes, which have no get_fields_and_field_types()."""
    return hasattr(message_class, "get_fields_and_field_types")


def sequence_field(message_class: Any, values: Any, dtype: Any) -> np.ndarray | array.array | list[bool]:
    """`values` (flattened, as `dtype`) in the container `message_class` takes for a numeric sequence
    (T[], T[<=N]) or a bool array (bool[], bool[N]).

    rosbags typestore classes pack numpy arrays only. rclpy stores numeric sequences as array.array
    of the element's typecode and bool arrays as lists of bool. With field checks on, its setters
    assert a collections.abc.Sequence, which a numpy array is not; with them off (Jazzy's default)
    its C conversion compares each bool item with Python's True, so numpy bools in a bool[N] go out
    as False. Fixed numeric arrays (T[N]) are numpy arrays everywhere: pass
    `np.asarray(values, dtype)` for those.
    """
    data = np.array(values, dtype=dtype).reshape(-1)  # a copy: the message shares nothing with `values`
    if not is_rosidl_class(message_class):
        return data
    if data.dtype == np.bool_:
        return [bool(v) for v in data]
    typecode = _TYPECODES.get(data.dtype)
    if typecode is None:
        raise ValueError(f"no ROS sequence element type for dtype {data.dtype}")
    return array.array(typecode, data.tobytes())


def robot_types(get_message: Callable[[str], Any], get_action: Callable[[str], Any]) -> Types:
    """A `types` lookup for nodes: generated ROS action modules expose `MoveMotors.Goal`, not
    `MoveMotors_Goal`, so action parts are fetched from the action class. Cached: rosidl imports
    the class on every lookup, and converters look types up per message."""

    @functools.cache
    def types(name: str) -> Any:
        package, kind, typename = name.split("/")
        if kind == "action" and "_" in typename:
            base, part = typename.split("_", 1)
            return getattr(get_action(f"{package}/action/{base}"), part)
        return get_message(name)

    return types
