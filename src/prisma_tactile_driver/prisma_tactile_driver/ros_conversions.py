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

from prisma_common.messages import make_header, newest_header, ns_from_stamp

from .taxels import TaxelFrame

Types = Callable[[str], Any]


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
