"""Core data <-> ROS messages for the tactile driver (header, stamp and array-field helpers:
prisma_common.messages).

Every function takes a message-class lookup `types(name)`: on the robot
`rosidl_runtime_py.utilities.get_message`, off-robot `prisma_common.typestore.types`.
Messages are built by keyword with every field (typestore classes have no defaults).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from prisma_common.kinematics import quaternion
from prisma_common.messages import make_header, newest_header, ns_from_stamp
from prisma_hand_sim.hand_world import ObjectPose

from .taxels import TaxelFrame

Types = Callable[[str], Any]
OBJECT_MARKER_TYPES = {"box": 1, "sphere": 2}  # visualization_msgs/Marker CUBE, SPHERE


def taxel_frame_to_msg(types: Types, frame: TaxelFrame, frame_id: str) -> Any:
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


def object_marker_to_msg(types: Types, frame_id: str, anchor: np.ndarray, pose: ObjectPose) -> Any:
    """visualization_msgs/Marker of the simulated object: `pose` (the world's, mm in the thumb pad's
    frame where the object was presented) placed by `anchor`, that frame's 4x4 pose in `frame_id`
    (metres). Stamp 0 and frame_locked: drawn on the newest transform of the hand's base."""
    centre = anchor[:3, :3] @ (np.asarray(pose.centre_mm) / 1000.0) + anchor[:3, 3]
    x, y, z, w = quaternion(anchor[:3, :3])
    sx, sy, sz = (max(v, 0.0) / 1000.0 for v in pose.size_mm)
    shape = OBJECT_MARKER_TYPES[pose.shape]
    return types("visualization_msgs/msg/Marker")(
        header=make_header(types, 0, frame_id), ns="sim_object", id=0, type=shape, action=0,
        pose=types("geometry_msgs/msg/Pose")(
            position=types("geometry_msgs/msg/Point")(x=float(centre[0]), y=float(centre[1]), z=float(centre[2])),
            orientation=types("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w)),
        scale=types("geometry_msgs/msg/Vector3")(x=sx, y=sy, z=sz),
        color=types("std_msgs/msg/ColorRGBA")(r=0.95, g=0.55, b=0.15, a=0.6), frame_locked=True)
