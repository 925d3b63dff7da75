"""Core data <-> ROS messages for prisma_manipulation: ContactState, JointState -> JointSample,
and (defined in each goal kind's module, re-exported here) the Grasp / Manipulate / GripperCommand
(control_msgs) / Teleoperate goals, feedback and results, and the teleoperation targets (JointState).

Every function takes a message-class lookup `types(name)` (on the robot
`prisma_common.messages.robot_types`, off-robot `prisma_common.typestore.types`) and builds
messages by keyword with every field. Header helpers and `sequence_field` (the container each
message class takes for a numeric sequence or a bool array) come from prisma_common; the motor
driver's converters (/joint_states, MoveMotors) from prisma_motor_driver.ros_conversions.

/joint_states units: position rad, velocity rad/s (the JointState convention), effort = motor
current in A.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from prisma_common.messages import make_header, newest_header, ns_from_stamp, sequence_field
from prisma_motor_driver.control_table import rad_s_to_rpm

from .contact_monitor import EDGE_NAMES, ContactEvaluation
from .controllers import JointSample
from .grasp_goal import grasp_feedback_to_msg, grasp_request_from_msg, grasp_result_to_msg
from .gripper_goal import gripper_feedback_to_msg, gripper_request_from_msg, gripper_result_to_msg
from .manipulate_goal import manipulate_feedback_to_msg, manipulate_request_from_msg, manipulate_result_to_msg
from .teleop_goal import (
    teleop_feedback_to_msg,
    teleop_request_from_msg,
    teleop_result_to_msg,
    teleop_target_from_msg,
)

__all__ = ["contact_state_from_msg", "contact_state_to_msg", "grasp_feedback_to_msg", "grasp_request_from_msg",
           "grasp_result_to_msg", "gripper_feedback_to_msg", "gripper_request_from_msg", "gripper_result_to_msg",
           "hand_contact_samples", "hand_contact_to_msg", "joint_sample_from_msg",
           "manipulate_feedback_to_msg", "manipulate_request_from_msg", "manipulate_result_to_msg",
           "normal_force_from_wrench", "teleop_feedback_to_msg", "teleop_request_from_msg", "teleop_result_to_msg",
           "teleop_target_from_msg"]

Types = Callable[[str], Any]


def contact_state_to_msg(types: Types, e: ContactEvaluation, frame_id: str) -> Any:
    cls = types("prisma_msgs/msg/ContactState")
    return cls(
        header=make_header(types, e.stamp_ns, frame_id),
        finger=e.finger,
        voltages=np.asarray(e.voltages, dtype=np.float32),
        mean_voltage=float(e.mean_voltage),
        k=float(e.k),
        threshold=float(e.threshold),
        safe=sequence_field(cls, e.safe, bool),
        lost_edges=list(e.lost_edges),
        feasible=bool(e.feasible),
    )


def hand_contact_to_msg(types: Types, contacts: list[Any]) -> Any:
    """prisma_msgs/HandContact holding `contacts` (ContactState messages), stamped with the newest."""
    return types("prisma_msgs/msg/HandContact")(header=newest_header(types, contacts), contacts=list(contacts))


def contact_state_from_msg(msg: Any) -> ContactEvaluation:
    lost = tuple(name for name in EDGE_NAMES if name in list(msg.lost_edges))
    return ContactEvaluation(msg.finger, ns_from_stamp(msg.header.stamp), np.asarray(msg.voltages, dtype=np.float32),
                             float(msg.mean_voltage), float(msg.k), float(msg.threshold),
                             np.asarray(msg.safe, dtype=bool), lost, bool(msg.feasible))


def joint_sample_from_msg(msg: Any) -> JointSample:
    """The joints a JointState message gives values for. Arrays that are empty or do not match
    `name` in length carry nothing (sensor_msgs/JointState allows empty arrays; another publisher
    on /joint_states may send anything): such a message yields a sample without positions,
    velocities or currents, and the manipulation core ignores it."""
    names = [str(n) for n in msg.name]

    def by_name(values: Any, scale: Callable[[float], float]) -> dict[str, float]:
        values = list(values)
        return {n: scale(float(v)) for n, v in zip(names, values)} if len(values) == len(names) else {}

    return JointSample(
        ns_from_stamp(msg.header.stamp),
        by_name(msg.position, float),
        by_name(msg.velocity, rad_s_to_rpm),
        by_name(msg.effort, lambda amps: amps * 1000.0),
    )


def normal_force_from_wrench(msg: Any) -> tuple[int, float]:
    """(stamp_ns, Fz) of a geometry_msgs/WrenchStamped from the force estimator (+Fz presses)."""
    return ns_from_stamp(msg.header.stamp), float(msg.wrench.force.z)


def hand_contact_samples(msg: Any) -> list[tuple[str, Any]]:
    """(finger, ContactState) pairs of a prisma_msgs/HandContact."""
    return [(str(contact.finger), contact) for contact in msg.contacts]

