"""Core data <-> ROS messages for prisma_manipulation: ContactState, Grasp / Manipulate /
GripperCommand (control_msgs) goals, feedback and results, JointState -> JointSample.

Every function takes a message-class lookup `types(name)` (on the robot
`prisma_common.messages.robot_types`, off-robot `prisma_common.typestore.types`) and builds
messages by keyword with every field. Header helpers and `sequence_field` (the container each
message class takes for a numeric sequence or a bool array) come from prisma_common; the motor
driver's converters (/joint_states, MoveMotors) from prisma_motor_driver.ros_conversions.

/joint_states units: position rad, velocity rad/s (the JointState convention), effort = motor
current in A.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from prisma_common.messages import make_header, newest_header, ns_from_stamp, sequence_field
from prisma_motor_driver.control_table import rad_s_to_rpm

from .contact_monitor import EDGE_NAMES, ContactEvaluation
from .controllers import JointSample
from .manipulation_core import Feedback, Finished, GraspRequest, GripperRequest, ManipulateRequest

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


# ---- Grasp / Manipulate -------------------------------------------------------------------------
def grasp_request_from_msg(msg: Any) -> GraspRequest:
    return GraspRequest(str(msg.grasp), float(msg.finger_force), float(msg.thumb_force), float(msg.speed_rpm),
                        float(msg.timeout))


def manipulate_request_from_msg(msg: Any) -> ManipulateRequest:
    return ManipulateRequest(str(msg.motion), float(msg.speed_rpm), float(msg.k), bool(msg.use_force),
                             float(msg.timeout))


def _f32(x: float) -> float:
    return float(x) if math.isfinite(x) else float("nan")


def grasp_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    return types("prisma_msgs/action/Grasp_Feedback")(phase=fb.phase, finger_force=_f32(fb.finger_force),
                                                      thumb_force=_f32(fb.thumb_force))


def grasp_result_to_msg(types: Types, done: Finished) -> Any:
    return types("prisma_msgs/action/Grasp_Result")(success=bool(done.success), reason=done.reason,
                                                    finger_force=_f32(done.finger_force),
                                                    thumb_force=_f32(done.thumb_force))


def manipulate_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    return types("prisma_msgs/action/Manipulate_Feedback")(phase=fb.phase, feasible=bool(fb.feasible),
                                                           threshold=_f32(fb.threshold))


def manipulate_result_to_msg(types: Types, done: Finished) -> Any:
    return types("prisma_msgs/action/Manipulate_Result")(success=bool(done.success), stop_reason=done.reason,
                                                         stop_time=_f32(done.stop_time_s))


def hand_contact_samples(msg: Any) -> list[tuple[str, Any]]:
    """(finger, ContactState) pairs of a prisma_msgs/HandContact."""
    return [(str(contact.finger), contact) for contact in msg.contacts]
def gripper_request_from_msg(msg: Any) -> GripperRequest:
    """control_msgs/GripperCommand goal: command.position = fingers motor rad, command.max_effort N."""
    return GripperRequest(float(msg.command.position), float(msg.command.max_effort))


def gripper_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    return types("control_msgs/action/GripperCommand_Feedback")(
        position=_f32(fb.position), effort=_f32(fb.effort), stalled=bool(fb.stalled),
        reached_goal=bool(fb.reached_goal))


def gripper_result_to_msg(types: Types, done: Finished) -> Any:
    """position = the fingers motor angle (rad), effort = the highest estimated pad force (N)."""
    return types("control_msgs/action/GripperCommand_Result")(
        position=_f32(done.position), effort=_f32(done.effort), stalled=bool(done.stalled),
        reached_goal=bool(done.reached_goal))


def hand_wrench_samples(msg: Any) -> list[tuple[str, Any]]:
    """(finger, WrenchStamped) pairs of a prisma_msgs/HandWrench; a malformed message (fingers and
    wrenches of different lengths) pairs up to the shorter list."""
    return [(str(finger), wrench) for finger, wrench in zip(msg.fingers, msg.wrenches)]
