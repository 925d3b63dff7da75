"""Glove core data <-> ROS messages (GloveFrame, sensor_msgs/Image, ObjectEstimate, WeightEstimate,
DiagnosticArray).

Every function takes a message-class lookup `types(name)`: on the robot
`rosidl_runtime_py.utilities.get_message`, off-robot `prisma_bringup.typestore.types`. Messages are
built by keyword with every field. Dynamic numeric arrays are numpy arrays in the rosbags typestore
but `array.array` in rclpy (whose setters reject numpy arrays), so `_sequence` builds whichever the
class expects. The package keeps its own small header helpers so it depends on no hand package.
"""
from __future__ import annotations

import array
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .processing import ProcessedFrame

Types = Callable[[str], Any]
NS_PER_S = 1_000_000_000
OK, WARN, ERROR, STALE = 0, 1, 2, 3


def stamp_from_ns(types: Types, stamp_ns: int) -> Any:
    stamp_ns = int(stamp_ns)
    if stamp_ns < 0:
        raise ValueError(f"stamp_ns must be >= 0, got {stamp_ns}")
    sec, nanosec = divmod(stamp_ns, NS_PER_S)
    return types("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec)


def ns_from_stamp(stamp: Any) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def make_header(types: Types, stamp_ns: int, frame_id: str) -> Any:
    return types("std_msgs/msg/Header")(stamp=stamp_from_ns(types, stamp_ns), frame_id=frame_id)


def _is_typestore(cls: Any) -> bool:
    return hasattr(cls, "__msgtype__")


def _sequence(cls: Any, values: np.ndarray, dtype: Any, typecode: str) -> Any:
    values = np.ascontiguousarray(values, dtype=dtype).reshape(-1)
    return values if _is_typestore(cls) else array.array(typecode, values.tobytes())


# ------------------------------------------------------------------------------- glove frame
def glove_frame_to_msg(frame: ProcessedFrame, types: Types, frame_id: str) -> Any:
    cls = types("prisma_msgs/msg/GloveFrame")
    rows, cols = frame.raw.shape
    return cls(
        header=make_header(types, frame.stamp_ns, frame_id),
        rows=int(rows), cols=int(cols),
        raw=_sequence(cls, frame.raw, np.uint16, "H"),
        pressure=_sequence(cls, frame.pressure, np.float32, "f"),
        shorted=bool(frame.shorted), contact=bool(frame.contact),
    )


def glove_frame_from_msg(msg: Any) -> ProcessedFrame:
    rows, cols = int(msg.rows), int(msg.cols)
    raw = np.asarray(msg.raw, dtype=np.uint16)
    pressure = np.asarray(msg.pressure, dtype=np.float32)
    if raw.size != rows * cols or pressure.size != rows * cols:
        raise ValueError(f"GloveFrame says {rows}x{cols} but has {raw.size} raw and {pressure.size} pressure values")
    return ProcessedFrame(ns_from_stamp(msg.header.stamp), raw.reshape(rows, cols), pressure.reshape(rows, cols),
                          bool(msg.shorted), bool(msg.contact))


def pressure_image_msg(frame: ProcessedFrame, types: Types, frame_id: str) -> Any:
    """sensor_msgs/Image, encoding 32FC1 (little-endian float32 pressure 0..1) for rqt_image_view."""
    cls = types("sensor_msgs/msg/Image")
    rows, cols = frame.pressure.shape
    data = np.ascontiguousarray(frame.pressure, dtype="<f4").view(np.uint8)
    return cls(header=make_header(types, frame.stamp_ns, frame_id), height=int(rows), width=int(cols),
               encoding="32FC1", is_bigendian=0, step=int(cols * 4), data=_sequence(cls, data, np.uint8, "B"))


def image_to_pressure(msg: Any) -> np.ndarray:
    if msg.encoding != "32FC1":
        raise ValueError(f"expected a 32FC1 image, got {msg.encoding!r}")
    dtype = ">f4" if msg.is_bigendian else "<f4"
    return np.frombuffer(np.asarray(msg.data, dtype=np.uint8).tobytes(), dtype=dtype).reshape(msg.height, msg.width)


# ------------------------------------------------------------------------------- estimates
@dataclass
class Estimate:
    """Classifier output (object identity or hand pose)."""

    label: str
    confidence: float
    labels: list[str]
    probabilities: np.ndarray
    frames_used: int


@dataclass
class WeightResult:
    grams: float
    baseline_grams: float


def estimate_to_msg(estimate: Estimate, types: Types, stamp_ns: int, frame_id: str) -> Any:
    cls = types("prisma_msgs/msg/ObjectEstimate")
    return cls(header=make_header(types, stamp_ns, frame_id), label=estimate.label,
               confidence=float(estimate.confidence), labels=list(estimate.labels),
               probabilities=_sequence(cls, estimate.probabilities, np.float32, "f"),
               frames_used=int(min(estimate.frames_used, 255)))


def estimate_from_msg(msg: Any) -> Estimate:
    return Estimate(msg.label, float(msg.confidence), list(msg.labels),
                    np.asarray(msg.probabilities, dtype=np.float32), int(msg.frames_used))


def weight_to_msg(result: WeightResult, types: Types, stamp_ns: int, frame_id: str) -> Any:
    return types("prisma_msgs/msg/WeightEstimate")(header=make_header(types, stamp_ns, frame_id),
                                                   grams=float(result.grams),
                                                   baseline_grams=float(result.baseline_grams))


def weight_from_msg(msg: Any) -> WeightResult:
    return WeightResult(float(msg.grams), float(msg.baseline_grams))


# ------------------------------------------------------------------------------- diagnostics
@dataclass
class DiagnosticData:
    name: str
    level: int            # OK, WARN, ERROR, STALE
    message: str
    hardware_id: str = ""
    values: dict[str, str] = field(default_factory=dict)


def _level(status_cls: Any, level: int) -> Any:
    # `byte` fields are one-byte bytes in rclpy and int in rosbags: follow the class constant
    return bytes([level]) if isinstance(getattr(status_cls, "OK", 0), bytes) else level


def diagnostics_to_msg(types: Types, stamp_ns: int, statuses: list[DiagnosticData]) -> Any:
    status_cls = types("diagnostic_msgs/msg/DiagnosticStatus")
    key_value = types("diagnostic_msgs/msg/KeyValue")
    return types("diagnostic_msgs/msg/DiagnosticArray")(
        header=make_header(types, stamp_ns, ""),
        status=[status_cls(level=_level(status_cls, s.level), name=s.name, message=s.message,
                           hardware_id=s.hardware_id,
                           values=[key_value(key=str(k), value=str(v)) for k, v in s.values.items()])
                for s in statuses])


def diagnostics_from_msg(msg: Any) -> list[DiagnosticData]:
    def level(value: Any) -> int:
        return value[0] if isinstance(value, (bytes, bytearray)) else int(value)
    return [DiagnosticData(s.name, level(s.level), s.message, s.hardware_id, {kv.key: kv.value for kv in s.values})
            for s in msg.status]
