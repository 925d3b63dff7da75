"""Converters fill array fields with what each message class takes: numpy arrays for the rosbags
typestore (bags), rclpy's containers for the generated classes on the robot (field checks on, as
conftest sets ROS_PYTHON_CHECK_FIELDS=1): array.array for numeric sequences, lists of bool for bool
arrays. Each converter is run on both kinds of class and read back; rclpy's serialised bytes are
read by the typestore and the other way round, so the bags and the live topics agree byte for byte."""
from __future__ import annotations

import array

import numpy as np
import pytest

from prisma_testing.ros_harness import require_ros

require_ros()

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from prisma_common.messages import is_rosidl_class, robot_types, sequence_field
from prisma_common.typestore import get_typestore
from prisma_common.typestore import types as typestore_types
from prisma_manipulation.contact_monitor import ContactMonitor
from prisma_manipulation.manipulation_core import Feedback, Finished, GripperRequest, GripperStatus
from prisma_manipulation.ros_conversions import (
    contact_state_from_msg,
    contact_state_to_msg,
    gripper_feedback_to_msg,
    gripper_request_from_msg,
    gripper_result_to_msg,
    joint_sample_from_msg,
)
from prisma_manipulation.teleop_goal import (
    TeleopStatus,
    teleop_feedback_to_msg,
    teleop_result_to_msg,
    teleop_target_from_msg,
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
from stag_glove.processing import FrameProcessor
from stag_glove.ros_conversions import (
    Estimate,
    estimate_from_msg,
    estimate_to_msg,
    glove_frame_from_msg,
    glove_frame_to_msg,
    image_to_pressure,
    pressure_image_msg,
)


@pytest.fixture(scope="module")
def rclpy_types():
    from rosidl_runtime_py.utilities import get_action, get_message

    return robot_types(get_message, get_action)


def cdr_round_trip(msg):
    """Serialise with the message's own library, read back with the other one and return to it.

    rclpy message -> rclpy bytes -> typestore message -> typestore bytes -> rclpy message, and the
    mirror image for a typestore message: both libraries must agree on every byte.
    """
    store = get_typestore()
    if hasattr(msg, "__msgtype__"):  # a typestore (rosbags) message
        data = store.serialize_cdr(msg, msg.__msgtype__)
        rclpy_cls = _rclpy_class(msg.__msgtype__)
        via_rclpy = deserialize_message(bytes(data), rclpy_cls)
        assert bytes(serialize_message(via_rclpy)) == bytes(data)
        return store.deserialize_cdr(data, msg.__msgtype__)
    typename = _typename(type(msg))
    data = serialize_message(msg)
    via_store = store.deserialize_cdr(data, typename)
    assert bytes(store.serialize_cdr(via_store, typename)) == bytes(data)
    return deserialize_message(data, type(msg))


def _typename(cls) -> str:
    """'sensor_msgs/msg/JointState' for the generated class (action parts included)."""
    package = cls.__module__.split(".")[0]
    kind = cls.__module__.split(".")[1]
    return f"{package}/{kind}/{cls.__name__}"


def _rclpy_class(typename: str):
    from rosidl_runtime_py.utilities import get_action, get_message

    package, kind, name = typename.split("/")
    if kind == "msg":
        return get_message(typename)
    action, _, part = name.rpartition("_")
    action_cls = get_action(f"{package}/action/{action}")
    return getattr(action_cls, part)


def test_sequence_field_gives_numpy_to_typestore_classes(rclpy_types):
    joint_state = typestore_types("sensor_msgs/msg/JointState")
    assert not is_rosidl_class(joint_state) and is_rosidl_class(rclpy_types("sensor_msgs/msg/JointState"))
    source = np.array([[1, 2], [3, 4]], dtype=np.int64)
    value = sequence_field(joint_state, source, np.float64)
    assert value.dtype == np.float64 and value.tolist() == [1.0, 2.0, 3.0, 4.0]  # flattened in C order
    source[0, 0] = 9
    assert value[0] == 1.0  # a copy: the message shares nothing with the caller's array
    safe = sequence_field(typestore_types("prisma_msgs/msg/ContactState"), [1, 0, 1], bool)
    assert safe.dtype == np.bool_ and safe.tolist() == [True, False, True]


def test_sequence_field_gives_rclpy_containers_to_generated_classes(rclpy_types):
    joint_state = rclpy_types("sensor_msgs/msg/JointState")
    position = sequence_field(joint_state, np.array([0.5, -1.25]), np.float64)
    assert isinstance(position, array.array) and position.typecode == "d" and list(position) == [0.5, -1.25]
    msg = joint_state()
    msg.position = position  # the setter that rejects a numpy array takes it
    frame = rclpy_types("prisma_msgs/msg/GloveFrame")()
    frame.raw = sequence_field(type(frame), np.arange(6).reshape(2, 3), np.uint16)
    frame.pressure = sequence_field(type(frame), [0.25, 0.5], np.float32)
    assert (frame.raw.typecode, list(frame.raw)) == ("H", [0, 1, 2, 3, 4, 5])
    assert (frame.pressure.typecode, list(frame.pressure)) == ("f", [0.25, 0.5])
    contact = rclpy_types("prisma_msgs/msg/ContactState")()
    contact.safe = sequence_field(type(contact), np.arange(9) % 2 == 0, bool)
    assert contact.safe == [True, False] * 4 + [True] and all(type(v) is bool for v in contact.safe)
    with pytest.raises(ValueError, match="no ROS sequence element type"):
        sequence_field(joint_state, ["a"], np.str_)


def test_manipulation_converters_on_both_kinds_of_class(rclpy_types):
    volts = np.full(9, 1.2, dtype=np.float32)
    volts[[2, 5, 8]] = 0.1  # one column of the 3x3 pad lost
    e = ContactMonitor(0.8).evaluate("middle", 1_700_000_000_123_456_789, volts)
    states = {"fingers": MotorState("fingers", 1.5, 60.0, 250.0),
              "thumb_rotation": MotorState("thumb_rotation", -0.5, -20.0, 10.0)}
    goal = MoveGoal(["fingers", "thumb_flexion"], "velocity", [10.0, -5.0], [8.0, 0.5], 2.5, 1_700_000_000_123_456_789,
                    "/left/manipulation")
    result = MoveResult(False, [1.0, 2.0], "motor_fault")
    for types in (rclpy_types, typestore_types):
        contact = contact_state_to_msg(types, e, "prisma_middle_pad")
        back = contact_state_from_msg(cdr_round_trip(contact))
        assert np.array_equal(back.safe, e.safe) and back.safe.sum() == 6 and back.lost_edges == e.lost_edges
        joints = joint_state_to_msg(types, 2_000_000_000, states)
        sample = joint_sample_from_msg(cdr_round_trip(joints))
        assert sample.positions == {"fingers": 1.5, "thumb_rotation": -0.5}
        assert move_goal_from_msg(cdr_round_trip(move_goal_to_msg(types, goal))) == goal
        assert move_result_from_msg(cdr_round_trip(move_result_to_msg(types, result))) == result
        feedback = move_feedback_to_msg(types, MoveFeedback([1.0], [2.0], [3.0]))
        assert list(cdr_round_trip(feedback).currents) == [3.0]
        if types is rclpy_types:
            assert contact.safe == [bool(v) for v in e.safe]  # bool[9]: a list of bool on the robot
            assert isinstance(joints.position, array.array) and isinstance(feedback.currents, array.array)
            assert joint_sample_from_msg(joints).positions == sample.positions  # reads array.array too
        else:
            assert contact.safe.dtype == np.bool_ and joints.position.dtype == np.float64


def test_gripper_command_converters_on_the_robots_classes(rclpy_types):
    """control_msgs/GripperCommand on rclpy's classes, serialised and read back (the bag typestore
    does not hold control_msgs: no bag tool of this workspace reads the gripper action)."""
    from control_msgs.action import GripperCommand

    def round_trip(msg):
        return deserialize_message(serialize_message(msg), type(msg))

    goal = GripperCommand.Goal()
    goal.command.position, goal.command.max_effort = 9.0, 1.0
    assert gripper_request_from_msg(round_trip(goal)) == GripperRequest(9.0, 1.0)
    status = GripperStatus(position=4.2, effort=1.02, stalled=True)
    feedback = round_trip(gripper_feedback_to_msg(rclpy_types, Feedback("gripper", "close", status)))
    assert (feedback.position, feedback.effort, feedback.stalled, feedback.reached_goal) == (4.2, 1.02, True, False)
    done = Finished("gripper", True, "reached", 1.43,
                    GripperStatus(position=8.92, effort=float("inf"), reached_goal=True))
    result = round_trip(gripper_result_to_msg(rclpy_types, done))
    assert (result.position, result.stalled, result.reached_goal) == (8.92, False, True)
    assert np.isnan(result.effort)  # non-finite values are sent as NaN, as in every converter here


def test_teleoperate_converters_on_both_kinds_of_class(rclpy_types):
    status = TeleopStatus(("fingers", "thumb_flexion", "thumb_rotation"), (5.0, float("nan"), 0.0), (4.9, 1.0, 0.0),
                          (0.4, 2.02, 0.0, 0.0, 0.0), ("fingers",))
    for types in (rclpy_types, typestore_types):
        targets = joint_state_to_msg(types, 1_700_000_000_123_456_789, {"fingers": MotorState("fingers", 3.0, 0, 0)})
        assert teleop_target_from_msg(cdr_round_trip(targets))[1].positions == {"fingers": 3.0}
        feedback = cdr_round_trip(teleop_feedback_to_msg(types, Feedback("teleop", "holding", status)))
        assert (feedback.phase, list(feedback.force_limited), list(feedback.positions)) == \
            ("holding", ["fingers"], pytest.approx([4.9, 1.0, 0.0]))
        result = teleop_result_to_msg(types, Finished("teleop", False, "input_stale", 2.5, status,
                                                      "prisma/teleop/motor_targets silent for 153 ms"))
        back = cdr_round_trip(result)
        assert back.reason == "input_stale: prisma/teleop/motor_targets silent for 153 ms" and np.isnan(back.targets[1])
        if types is rclpy_types:
            assert isinstance(result.pad_forces, array.array) and result.pad_forces.typecode == "f"


def test_glove_converters_on_both_kinds_of_class(rclpy_types):
    raw = np.random.default_rng(0).integers(450, 700, (32, 32)).astype(np.uint16)
    frame = FrameProcessor().process(raw, stamp_ns=1_700_000_000_123_456_789)
    estimate = Estimate("mug", 0.75, ["mug", "ball"], np.array([0.75, 0.25], dtype=np.float32), 12)
    for types in (rclpy_types, typestore_types):
        msg = glove_frame_to_msg(types, frame, "stag_glove")
        for received in (msg, cdr_round_trip(msg)):
            np.testing.assert_array_equal(glove_frame_from_msg(received).raw, frame.raw)
        image = pressure_image_msg(frame, types, "stag_glove")
        np.testing.assert_array_equal(image_to_pressure(image), frame.pressure)
        back = estimate_from_msg(cdr_round_trip(estimate_to_msg(types, estimate, 5, "stag_glove")))
        assert back.labels == ["mug", "ball"] and back.probabilities.tolist() == [0.75, 0.25]
        if types is rclpy_types:
            assert isinstance(msg.raw, array.array) and msg.raw.typecode == "H"
            assert isinstance(image.data, array.array) and image.data.typecode == "B"
