"""Diagnostics as plain data (`DiagnosticStatusData`, the levels) and their converters to and from
diagnostic_msgs/DiagnosticArray."""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from .messages import Types, make_header

# diagnostic_msgs/DiagnosticStatus levels
OK, WARN, ERROR, STALE = 0, 1, 2, 3


@dataclass
class DiagnosticStatusData:
    """Plain form of diagnostic_msgs/DiagnosticStatus."""

    name: str
    level: int
    message: str
    hardware_id: str = ""
    values: dict[str, str] = field(default_factory=dict)


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
                           values=[key_value(key=str(k), value=str(v)) for k, v in s.values.items()])
                for s in statuses],
    )


def diagnostics_from_msg(msg: Any) -> list[DiagnosticStatusData]:
    return [DiagnosticStatusData(s.name, level_value(s.level), s.message, s.hardware_id,
                                 {kv.key: kv.value for kv in s.values}) for s in msg.status]
