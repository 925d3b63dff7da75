"""CDR round trips of the manipulation and motor_driver converters."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_common.messages import robot_types
from prisma_common.typestore import types
from prisma_manipulation.contact_monitor import ContactMonitor
from prisma_manipulation.manipulation_core import (
    Feedback,
    Finished,
    GraspStatus,
    ManipulateStatus,
)
from prisma_manipulation.ros_conversions import (
    contact_state_from_msg,
    contact_state_to_msg,
    grasp_result_to_msg,
    hand_contact_to_msg,
    joint_sample_from_msg,
    manipulate_feedback_to_msg,
    manipulate_result_to_msg,
)
from prisma_motor_driver.backend import MotorState
from prisma_motor_driver.motor_goals import MoveFeedback, MoveGoal, MoveResult
from prisma_motor_driver.ros_conversions import (
    joint_state_to_msg,
    move_feedback_to_msg,
    move_goal_from_msg,
    move_goal_to_msg,
    move_result_from_msg,
    move_result_to_msg,
)
from prisma_testing.cdr import cdr_round_trip
from prisma_testing.core_inputs import pressed_pad


def test_contact_state_round_trip():
    e = ContactMonitor(0.8).evaluate("middle", 1_700_000_000_123_456_789, pressed_pad(right_lost=True))
    back = contact_state_from_msg(cdr_round_trip(contact_state_to_msg(types, e, "prisma_middle_pad")))
    assert back.finger == "middle" and back.stamp_ns == e.stamp_ns
    assert np.array_equal(back.voltages, e.voltages) and np.array_equal(back.safe, e.safe)
    assert back.lost_edges == ("right",) and back.feasible is False
    assert back.threshold == pytest.approx(e.threshold, rel=1e-6) and back.k == pytest.approx(0.8)


def test_hand_contact_holds_each_fingers_contact_state():
    monitor = ContactMonitor(0.8)
    evaluations = [monitor.evaluate("thumb", 3_000_000_000, pressed_pad()),
                   monitor.evaluate("index", 3_000_400_000, pressed_pad(right_lost=True))]
    msg = cdr_round_trip(hand_contact_to_msg(types, [contact_state_to_msg(types, e, f"{e.finger}_pad")
                                                     for e in evaluations]))
    assert msg.__msgtype__ == "prisma_msgs/msg/HandContact"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (3, 400_000)  # the newest
    back = [contact_state_from_msg(c) for c in msg.contacts]
    assert [(b.finger, b.stamp_ns, b.lost_edges) for b in back] == [("thumb", 3_000_000_000, ()),
                                                                    ("index", 3_000_400_000, ("right",))]
    assert np.array_equal(back[1].safe, evaluations[1].safe)


def test_joint_state_round_trip_units():
    states = {"fingers": MotorState("fingers", 1.5, 60.0, 250.0),
              "thumb_rotation": MotorState("thumb_rotation", -0.5, -20.0, 10.0)}
    msg = cdr_round_trip(joint_state_to_msg(types, 2_000_000_000, states))
    assert list(msg.velocity) == pytest.approx([2 * np.pi, -2 * np.pi / 3])  # rad/s
    assert list(msg.effort) == pytest.approx([0.25, 0.01])  # A
    sample = joint_sample_from_msg(msg)
    assert sample.stamp_ns == 2_000_000_000 and sample.positions == {"fingers": 1.5, "thumb_rotation": -0.5}
    assert sample.velocities["fingers"] == pytest.approx(60.0) and sample.currents["fingers"] == pytest.approx(250.0)


def test_action_message_round_trips():
    goal = MoveGoal(["fingers", "thumb_flexion"], "velocity", [10.0, -5.0], [8.0, 0.5], 2.5)
    assert move_goal_from_msg(cdr_round_trip(move_goal_to_msg(types, goal))) == goal
    result = MoveResult(False, [1.0, 2.0], "motor_fault: fingers (id 1) hardware error bit 5 overload")
    assert move_result_from_msg(cdr_round_trip(move_result_to_msg(types, result))) == result
    fb = cdr_round_trip(move_feedback_to_msg(types, MoveFeedback([1.0], [2.0], [3.0])))
    assert list(fb.currents) == [3.0]
    done = Finished("grasp", True, "force_reached", 1.25, GraspStatus(0.81, 1.02))
    r = cdr_round_trip(grasp_result_to_msg(types, done))
    assert r.success and r.reason == "force_reached" and r.thumb_force == pytest.approx(1.02)
    ended = Finished("manipulate", True, "edge_lost", 0.42, ManipulateStatus(0, 0, False, 0.0))
    m = cdr_round_trip(manipulate_result_to_msg(types, ended))
    assert m.stop_reason == "edge_lost" and m.stop_time == pytest.approx(0.42)
    f = cdr_round_trip(manipulate_feedback_to_msg(types, Feedback("manipulate", "rotate",
                                                                  ManipulateStatus(0, 0, True, 0.9))))
    assert f.phase == "rotate" and f.feasible and f.threshold == pytest.approx(0.9)


def test_robot_types_fetches_action_parts_from_the_action_class():
    class Action:
        Goal, Result, Feedback = "G", "R", "F"

    lookup = robot_types(lambda name: f"msg:{name}",
                         lambda name: Action if name == "prisma_msgs/action/MoveMotors" else None)
    assert lookup("prisma_msgs/action/MoveMotors_Goal") == "G"
    assert lookup("prisma_msgs/msg/ContactState") == "msg:prisma_msgs/msg/ContactState"
