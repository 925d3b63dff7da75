"""Diagnostics as plain data (`DiagnosticStatusData`, the levels) and their converters to and from
diagnostic_msgs/DiagnosticArray.

Every node publishes on the absolute /diagnostics, so two hands on one domain would report under the
same names (`motor_driver: fingers`, hardware `sim#1`) and a robot monitor would merge them. A node in
a namespace therefore puts it in front of its statuses' names and hardware IDs (`in_namespace`:
`left/motor_driver: fingers`, `left/sim#1`); at the root they stay as the node made them.
`of_namespace` is the reverse, for a reader of one hand (prisma-doctor --namespace).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
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


def namespace_prefix(namespace: str) -> str:
    """What goes in front of a status name of a node in `namespace`: `left/` for /left, "" at the root."""
    ns = namespace.strip("/")
    return f"{ns}/" if ns else ""


def in_namespace(statuses: Iterable[DiagnosticStatusData], namespace: str) -> list[DiagnosticStatusData]:
    """The statuses named for a node in `namespace` (a ROS namespace such as /left; / or "" = the root):
    its prefix in front of each name and non-empty hardware ID."""
    prefix = namespace_prefix(namespace)
    if not prefix:
        return list(statuses)
    return [replace(s, name=prefix + s.name, hardware_id=prefix + s.hardware_id if s.hardware_id else "")
            for s in statuses]


def of_namespace(status: DiagnosticStatusData, namespace: str) -> DiagnosticStatusData | None:
    """`status` as its node made it when a node in `namespace` published it (`in_namespace` undone),
    None when it comes from another namespace. A root node's statuses carry no `/` before the `:`."""
    prefix = namespace_prefix(namespace)
    source = status.name.split(":", 1)[0]
    if not prefix:
        return status if "/" not in source else None
    if not status.name.startswith(prefix) or "/" in source[len(prefix):]:
        return None
    hardware_id = status.hardware_id[len(prefix):] if status.hardware_id.startswith(prefix) else status.hardware_id
    return replace(status, name=status.name[len(prefix):], hardware_id=hardware_id)
