"""Teleoperation data <-> ROS messages: the glove's hand pose (sensor_msgs/JointState), the motor
targets (prisma/teleop/motor_targets, sensor_msgs/JointState), the goals the teleop node sends
(prisma_msgs Teleoperate and Grasp, control_msgs GripperCommand) and what it reads from the STAG
glove (GloveFrame's total pressure; ObjectEstimate through stag_glove's converter), and the episode
markers (prisma/teleop/episode, prisma_msgs/msg/EpisodeMarker).

Every `*_to_msg` takes the message-class lookup `types(name)` first (rclpy's on the robot, the
prisma typestore off-robot) and builds the message by keyword.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from prisma_common.messages import make_header, ns_from_stamp, sequence_field

from .episodes import EVENTS, EpisodeMarker
from .stag_poses import GraspCommand
from .teleop_core import TeleopGoal

Types = Callable[[str], Any]


def hand_pose_to_msg(types: Types, stamp_ns: int, angles: Mapping[str, float], frame_id: str = "") -> Any:
    """A hand-pose glove sample: joint name -> angle (rad) as a JointState (positions only)."""
    cls = types("sensor_msgs/msg/JointState")
    return cls(header=make_header(types, stamp_ns, frame_id), name=list(angles),
               position=sequence_field(cls, np.fromiter(angles.values(), float, len(angles)), np.float64),
               velocity=sequence_field(cls, [], np.float64), effort=sequence_field(cls, [], np.float64))


def hand_pose_from_msg(msg: Any) -> tuple[int, dict[str, float]]:
    """(stamp_ns, joint name -> angle); ValueError when names and positions differ in number."""
    if len(msg.name) != len(msg.position):
        raise ValueError(f"JointState with {len(msg.name)} names and {len(msg.position)} positions")
    return ns_from_stamp(msg.header.stamp), dict(zip(msg.name, map(float, msg.position)))


def motor_targets_to_msg(types: Types, stamp_ns: int, targets: Mapping[str, float]) -> Any:
    """prisma/teleop/motor_targets: motor name -> target (rad), stamped with the glove sample's stamp."""
    return hand_pose_to_msg(types, stamp_ns, targets)


def motor_targets_from_msg(msg: Any) -> tuple[int, dict[str, float]]:
    return hand_pose_from_msg(msg)


def teleoperate_goal_to_msg(types: Types, goal: TeleopGoal) -> Any:
    return types("prisma_msgs/action/Teleoperate_Goal")(
        max_pad_force=float(goal.max_pad_force), max_speed_rpm=float(goal.max_speed_rpm),
        input_timeout=float(goal.input_timeout))


def grasp_goal_to_msg(types: Types, command: GraspCommand, speed_rpm: float = 0.0) -> Any:
    """A Grasp goal (speed 0 and timeout 0: the manipulation node's defaults)."""
    return types("prisma_msgs/action/Grasp_Goal")(
        grasp=command.grasp, finger_force=float(command.finger_force), thumb_force=float(command.thumb_force),
        speed_rpm=float(speed_rpm), timeout=0.0)


def open_goal_to_msg(types: Types) -> Any:
    """GripperCommand position 0: the hand opens (max_effort 0: the manipulation node's default)."""
    command = types("control_msgs/msg/GripperCommand")(position=0.0, max_effort=0.0)
    return types("control_msgs/action/GripperCommand_Goal")(command=command)


def pressure_total_from_msg(msg: Any) -> tuple[int, float, bool]:
    """A GloveFrame's (stamp_ns, total pressure: the sum of its normalised pressures, shorted)."""
    return ns_from_stamp(msg.header.stamp), float(np.sum(np.asarray(msg.pressure, dtype=np.float64))), \
        bool(msg.shorted)


def episode_marker_to_msg(types: Types, marker: EpisodeMarker, frame_id: str = "") -> Any:
    return types("prisma_msgs/msg/EpisodeMarker")(
        header=make_header(types, marker.stamp_ns, frame_id), episode=int(marker.episode), event=marker.event,
        task=marker.task, outcome=marker.outcome, reason=marker.reason)


def episode_marker_from_msg(msg: Any) -> EpisodeMarker:
    """ValueError for an event other than start or end."""
    if msg.event not in EVENTS:
        raise ValueError(f"EpisodeMarker event {msg.event!r}, expected {' or '.join(EVENTS)}")
    return EpisodeMarker(ns_from_stamp(msg.header.stamp), int(msg.episode), str(msg.event), str(msg.task),
                         str(msg.outcome), str(msg.reason))
