"""Core data <-> ROS messages for the tactile driver, plus the header helpers other packages reuse.

Every function takes a message-class lookup `types(name)`: on the robot
`rosidl_runtime_py.utilities.get_message`, off-robot `prisma_bringup.typestore.types`.
Messages are built by keyword with every field (typestore classes have no defaults).
"""
from __future__ import annotations

from typing import Any, Callable, Iterable

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
