"""Glove core data <-> ROS messages (GloveFrame, sensor_msgs/Image, ObjectEstimate, WeightEstimate,
DiagnosticArray).

Every function takes a message-class lookup `types(name)`: on the robot
`rosidl_runtime_py.utilities.get_message`, off-robot `prisma_common.typestore.types`. Messages are
built by keyword with every field. Dynamic numeric arrays are numpy arrays in the rosbags typestore
but `array.array` in rclpy (whose setters reject numpy arrays), so prisma_common's `sequence_field`
builds whichever the class expects. Header and stamp helpers and the
diagnostics converters: prisma_common.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from prisma_common.messages import make_header, ns_from_stamp, sequence_field

from .processing import ProcessedFrame

Types = Callable[[str], Any]


# ------------------------------------------------------------------------------- glove frame
def glove_frame_to_msg(types: Types, frame: ProcessedFrame, frame_id: str) -> Any:
    cls = types("prisma_msgs/msg/GloveFrame")
    rows, cols = frame.raw.shape
    return cls(
        header=make_header(types, frame.stamp_ns, frame_id),
        rows=int(rows), cols=int(cols),
        raw=sequence_field(cls, frame.raw, np.uint16),
        pressure=sequence_field(cls, frame.pressure, np.float32),
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
               encoding="32FC1", is_bigendian=0, step=int(cols * 4), data=sequence_field(cls, data, np.uint8))


def pressure_map_to_msg(types: Types, image: np.ndarray, stamp_ns: int, frame_id: str) -> Any:
    """sensor_msgs/Image, encoding rgb8, of a drawn pressure map (pressure_map.PressureMap.draw)."""
    cls = types("sensor_msgs/msg/Image")
    height, width, _ = image.shape
    data = np.ascontiguousarray(image, dtype=np.uint8).reshape(-1)
    return cls(header=make_header(types, stamp_ns, frame_id), height=int(height), width=int(width),
               encoding="rgb8", is_bigendian=0, step=int(width * 3), data=sequence_field(cls, data, np.uint8))


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


def estimate_to_msg(types: Types, estimate: Estimate, stamp_ns: int, frame_id: str) -> Any:
    cls = types("prisma_msgs/msg/ObjectEstimate")
    return cls(header=make_header(types, stamp_ns, frame_id), label=estimate.label,
               confidence=float(estimate.confidence), labels=list(estimate.labels),
               probabilities=sequence_field(cls, estimate.probabilities, np.float32),
               frames_used=int(min(estimate.frames_used, 255)))


def estimate_from_msg(msg: Any) -> Estimate:
    return Estimate(msg.label, float(msg.confidence), list(msg.labels),
                    np.asarray(msg.probabilities, dtype=np.float32), int(msg.frames_used))


def weight_to_msg(types: Types, result: WeightResult, stamp_ns: int, frame_id: str) -> Any:
    return types("prisma_msgs/msg/WeightEstimate")(header=make_header(types, stamp_ns, frame_id),
                                                   grams=float(result.grams),
                                                   baseline_grams=float(result.baseline_grams))


def weight_from_msg(msg: Any) -> WeightResult:
    return WeightResult(float(msg.grams), float(msg.baseline_grams))
