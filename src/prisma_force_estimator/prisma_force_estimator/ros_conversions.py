"""Force estimator data <-> geometry_msgs/WrenchStamped, and prisma_msgs/HandWrench both ways: the
writer's converters, which its readers (manipulation, visualization, the dataset tool) import.

Every function takes the message-class lookup `types(name)`: rosidl's get_message on the robot,
prisma_common.typestore.types off-robot, so the node and the bag tools share one converter.
Header helpers and the /diagnostics converter are the tactile driver's (one of each in the
workspace).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from prisma_common.messages import make_header, newest_header, ns_from_stamp

from .wrench import WrenchSample

MessageLookup = Callable[[str], Any]


def wrench_to_msg(types: MessageLookup, sample: WrenchSample) -> Any:
    """geometry_msgs/WrenchStamped stamped with the sample's (the input's) stamp."""
    vector3 = types("geometry_msgs/msg/Vector3")
    w = [float(v) for v in sample.wrench]
    return types("geometry_msgs/msg/WrenchStamped")(
        header=make_header(types, sample.stamp_ns, sample.frame_id),
        wrench=types("geometry_msgs/msg/Wrench")(
            force=vector3(x=w[0], y=w[1], z=w[2]),
            torque=vector3(x=w[3], y=w[4], z=w[5]),
        ),
    )


def wrench_from_msg(msg: Any) -> WrenchSample:
    f, t = msg.wrench.force, msg.wrench.torque
    return WrenchSample(ns_from_stamp(msg.header.stamp),
                        np.array([f.x, f.y, f.z, t.x, t.y, t.z], dtype=np.float64),
                        str(msg.header.frame_id))


def hand_wrench_to_msg(types: MessageLookup, fingers: Sequence[str], wrenches: Sequence[Any]) -> Any:
    """prisma_msgs/HandWrench: wrenches[i] (WrenchStamped) of fingers[i], stamped with the newest."""
    if len(fingers) != len(wrenches):
        raise ValueError(f"{len(fingers)} fingers for {len(wrenches)} wrenches")
    return types("prisma_msgs/msg/HandWrench")(header=newest_header(types, wrenches),
                                               fingers=list(fingers), wrenches=list(wrenches))


def hand_wrench_samples(msg: Any) -> list[tuple[str, Any]]:
    """(finger, WrenchStamped) pairs of a prisma_msgs/HandWrench; a malformed message (fingers and
    wrenches of different lengths) pairs up to the shorter list."""
    return [(str(finger), wrench) for finger, wrench in zip(msg.fingers, msg.wrenches)]
