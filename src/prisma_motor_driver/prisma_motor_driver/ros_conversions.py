"""Core data <-> ROS messages for the motor driver: /joint_states, the MoveMotors goal, feedback
and result, and the HomeMotors feedback and result.

Every function takes a message-class lookup `types(name)` (on the robot
`prisma_common.messages.robot_types`, off-robot `prisma_common.typestore.types`) and builds
messages by keyword with every field.

/joint_states units: position rad (motor shaft, from the configured zero), velocity rad/s (the
JointState convention; MoveMotors feedback keeps rpm), effort = motor current in A (the servos
measure current, not torque).
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from prisma_common.messages import Types, make_header, ns_from_stamp, sequence_field, stamp_from_ns

from .backend import MotorState
from .control_table import rpm_to_rad_s
from .homing_job import HomingFeedback, HomingResult
from .motor_goals import MoveFeedback, MoveGoal, MoveResult


def joint_state_to_msg(types: Types, stamp_ns: int, states: Mapping[str, MotorState], frame_id: str = "") -> Any:
    names = list(states)
    cls = types("sensor_msgs/msg/JointState")
    return cls(
        header=make_header(types, stamp_ns, frame_id),
        name=names,
        position=sequence_field(cls, [states[n].position_rad for n in names], np.float64),
        velocity=sequence_field(cls, [rpm_to_rad_s(states[n].velocity_rpm) for n in names], np.float64),
        effort=sequence_field(cls, [states[n].current_ma / 1000.0 for n in names], np.float64),
    )


# ---- MoveMotors ---------------------------------------------------------------------------------
def move_goal_to_msg(types: Types, goal: MoveGoal) -> Any:
    cls = types("prisma_msgs/action/MoveMotors_Goal")
    return cls(
        motors=list(goal.motors), mode=goal.mode,
        targets=sequence_field(cls, goal.targets, np.float64),
        position_limits=sequence_field(cls, goal.position_limits, np.float64),
        timeout=float(goal.timeout_s), stamp=stamp_from_ns(types, goal.stamp_ns), controller=goal.controller,
    )


def move_goal_from_msg(msg: Any) -> MoveGoal:
    # `timeout` is a float32: 0.3 arrives as 0.30000001192..., which would end a 0.3 s goal one
    # 10 ms tick late; microseconds are far below a tick and far above float32's error
    return MoveGoal(list(msg.motors), str(msg.mode), [float(t) for t in msg.targets],
                    [float(p) for p in msg.position_limits], round(float(msg.timeout), 6), ns_from_stamp(msg.stamp),
                    str(msg.controller))


def velocity_goal(velocities_rpm: Mapping[str, float], timeout_s: float, stamp_ns: int = 0,
                  controller: str = "") -> MoveGoal:
    """A velocity goal; `stamp_ns` (the sending instant, or earlier) makes its timeout count from then, `controller`
    (the sender's fully qualified node name) names whose lease it is."""
    return MoveGoal(list(velocities_rpm), "velocity", [float(v) for v in velocities_rpm.values()], [], timeout_s,
                    stamp_ns, controller)


def move_feedback_to_msg(types: Types, fb: MoveFeedback) -> Any:
    cls = types("prisma_msgs/action/MoveMotors_Feedback")
    return cls(
        positions=sequence_field(cls, fb.positions, np.float64),
        velocities=sequence_field(cls, fb.velocities, np.float64),
        currents=sequence_field(cls, fb.currents, np.float64),
    )


def move_result_to_msg(types: Types, result: MoveResult) -> Any:
    cls = types("prisma_msgs/action/MoveMotors_Result")
    return cls(
        success=bool(result.success), final_positions=sequence_field(cls, result.final_positions, np.float64),
        reason=result.reason,
    )


def move_result_from_msg(msg: Any) -> MoveResult:
    return MoveResult(bool(msg.success), [float(p) for p in msg.final_positions], str(msg.reason))


def homing_feedback_to_msg(types: Types, feedback: HomingFeedback) -> Any:
    cls = types("prisma_msgs/action/HomeMotors_Feedback")
    return cls(
        motors=list(feedback.motors),
        positions=sequence_field(cls, feedback.positions, np.float64),
        currents=sequence_field(cls, feedback.currents, np.float64),
        homed=sequence_field(cls, feedback.homed, np.bool_),
    )


def homing_result_to_msg(types: Types, result: HomingResult) -> Any:
    cls = types("prisma_msgs/action/HomeMotors_Result")
    return cls(
        success=result.success,
        reason=result.reason,
        motors=list(result.motors),
        zero_ticks=sequence_field(cls, result.zero_ticks, np.int32),
        travel_rad=sequence_field(cls, result.travel_rad, np.float64),
        stall_current_ma=sequence_field(cls, result.stall_current_ma, np.float64),
    )
