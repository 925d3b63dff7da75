"""Core data <-> ROS messages for the tactile driver, plus the helpers other packages reuse
(headers and stamps, `sequence_field` for array fields).

Every function takes a message-class lookup `types(name)`: on the robot
`rosidl_runtime_py.utilities.get_message`, off-robot `prisma_bringup.typestore.types`.
Messages are built by keyword with every field (typestore classes have no defaults).
"""
from __future__ import annotations

import array
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from .hub import DiagnosticStatusData
from .taxels import TaxelFrame

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


def taxel_frame_to_msg(frame: TaxelFrame, types: Types, frame_id: str) -> Any:
    return types("prisma_msgs/msg/TaxelArray")(
        header=make_header(types, frame.stamp_ns, frame_id),
        finger=frame.finger,
        counts=np.asarray(frame.counts, dtype=np.uint16),
        voltages=np.asarray(frame.voltages, dtype=np.float32),
    )


def taxel_frame_from_msg(msg: Any) -> TaxelFrame:
    return TaxelFrame(msg.finger, ns_from_stamp(msg.header.stamp),
                      np.asarray(msg.counts, dtype=np.uint16), np.asarray(msg.voltages, dtype=np.float32))


def hand_taxels_to_msg(types: Types, samples: list[Any], frame_id: str = "") -> Any:
    """prisma_msgs/HandTaxels holding `samples` (TaxelArray messages, in the order read), stamped
    with the newest sample's stamp."""
    return types("prisma_msgs/msg/HandTaxels")(header=newest_header(types, samples, frame_id), samples=list(samples))


def hand_taxels_samples(msg: Any) -> list[tuple[str, Any]]:
    """(finger, TaxelArray) for each sample of a HandTaxels message."""
    return [(str(sample.finger), sample) for sample in msg.samples]


def _level(status_cls: Any, level: int) -> Any:
    # `byte` fields are bytes of length 1 in rclpy and int in rosbags: follow the class constant
    return bytes([level]) if isinstance(getattr(status_cls, "OK", 0), bytes) else level


def level_value(level: Any) -> int:
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def diagnostics_to_msg(types: Types, stamp_ns: int, statuses: Iterable[DiagnosticStatusData]) -> Any:
    status_cls = types("diagnostic_msgs/msg/DiagnosticStatus")
    key_value = types("diagnostic_msgs/msg/KeyValue")
    return types("diagnostic_msgs/msg/DiagnosticArray")(
        header=make_header(types, stamp_ns, ""),
        status=[status_cls(level=_level(status_cls, s.level), name=s.name, message=s.message,
                           hardware_id=s.hardware_id,
                           values=[key_value(key=k, value=str(v)) for k, v in s.values.items()])
                for s in statuses],
    )


def diagnostics_from_msg(msg: Any) -> list[DiagnosticStatusData]:
    return [DiagnosticStatusData(s.name, level_value(s.level), s.message, s.hardware_id,
                                 {kv.key: kv.value for kv in s.values}) for s in msg.status]
