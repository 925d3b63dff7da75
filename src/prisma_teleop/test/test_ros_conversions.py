"""Teleoperation converters, by CDR round trip through the typestore: the glove's hand pose, the
motor targets (the interface with the manipulation node) and the goals the teleop node sends (the
GripperCommand goal, a control_msgs type the typestore does not hold: test_teleop_node.py), and the
episode markers."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_common.typestore import get_typestore, types
from prisma_teleop.episodes import EpisodeMarker
from prisma_teleop.ros_conversions import (
    episode_marker_from_msg,
    episode_marker_to_msg,
    grasp_goal_to_msg,
    hand_pose_from_msg,
    hand_pose_to_msg,
    motor_targets_from_msg,
    motor_targets_to_msg,
    pressure_total_from_msg,
    teleoperate_goal_to_msg,
)
from prisma_teleop.stag_poses import GraspCommand
from prisma_teleop.teleop_core import TeleopGoal

STAMP_NS = 1_700_000_000_123_456_789


def round_trip(msg):
    store = get_typestore()
    return store.deserialize_cdr(store.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


def test_motor_targets_carry_the_glove_samples_stamp_and_nothing_else():
    targets = {"fingers": 7.25, "thumb_flexion": 5.5, "thumb_rotation": -0.75}
    msg = round_trip(motor_targets_to_msg(types, STAMP_NS, targets))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert list(msg.name) == ["fingers", "thumb_flexion", "thumb_rotation"]
    assert len(msg.velocity) == 0 and len(msg.effort) == 0
    assert motor_targets_from_msg(msg) == (STAMP_NS, targets)


def test_hand_pose_round_trip_and_a_malformed_one():
    angles = {"index_mcp": 0.5, "thumb_cmc_abduction": -0.125}
    msg = round_trip(hand_pose_to_msg(types, STAMP_NS, angles, "glove"))
    assert msg.header.frame_id == "glove" and hand_pose_from_msg(msg) == (STAMP_NS, angles)
    msg.position = np.array([0.5])
    with pytest.raises(ValueError, match="JointState with 2 names and 1 positions"):
        hand_pose_from_msg(msg)


def test_goals():
    teleop = round_trip(teleoperate_goal_to_msg(types, TeleopGoal(1.5, 30.0, 0.2)))
    assert (teleop.max_pad_force, teleop.max_speed_rpm, teleop.input_timeout) == pytest.approx((1.5, 30.0, 0.2))
    grasp = round_trip(grasp_goal_to_msg(types, GraspCommand("power", 1.25, 1.5, "hook"), 45.0))
    assert (grasp.grasp, grasp.finger_force, grasp.thumb_force, grasp.speed_rpm, grasp.timeout) == (
        "power", 1.25, 1.5, 45.0, 0.0)


def test_glove_frame_total_pressure():
    cls = types("prisma_msgs/msg/GloveFrame")
    from prisma_common.messages import make_header

    pressure = np.zeros(1024, np.float32)
    pressure[:40] = 0.5
    msg = cls(header=make_header(types, STAMP_NS, "stag_glove"), rows=32, cols=32, raw=np.zeros(1024, np.uint16),
              pressure=pressure, shorted=False, contact=True)
    assert pressure_total_from_msg(round_trip(msg)) == (STAMP_NS, 20.0, False)


def test_an_episode_marker_round_trip_and_an_unknown_event():
    marker = EpisodeMarker(STAMP_NS, 7, "end", "pinch the ball", "failure", "the goal ended motor_fault: overload")
    msg = round_trip(episode_marker_to_msg(types, marker))
    assert msg.__msgtype__ == "prisma_msgs/msg/EpisodeMarker"
    assert episode_marker_from_msg(msg) == marker
    msg.event = "pause"
    with pytest.raises(ValueError, match="EpisodeMarker event 'pause', expected start or end"):
        episode_marker_from_msg(msg)
