"""The teleop goal kind through ManipulationCore: its validation, one goal at a time with a Grasp,
admitted before the targets flow (waiting), following the latest target once per scan, touch-limited,
ended input_stale by the targets' silence or age (the reason text exact), sensor_stale, a cancel as
its success; and its converters (JointState targets in, Teleoperate feedback and result out)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from prisma_common.messages import make_header
from prisma_common.typestore import types
from prisma_manipulation.controllers import JointSample
from prisma_manipulation.goal_kind import Feedback, Finished
from prisma_manipulation.manipulation_core import GraspRequest, ManipulationCore, SendMove, StopMotors
from prisma_manipulation.node_config import ManipulationConfig
from prisma_manipulation.teleop_goal import (
    TELEOP_GOAL,
    TeleopRequest,
    TeleopStatus,
    teleop_feedback_to_msg,
    teleop_request_from_msg,
    teleop_result_to_msg,
    teleop_target_from_msg,
)
from prisma_testing.cdr import cdr_round_trip

MS = 1_000_000
PADS = ("thumb", "index", "middle", "ring", "little")
VOLTS = np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], dtype=np.float32)
MOTORS = ("fingers", "thumb_flexion", "thumb_rotation")



def targets_msg(stamp_ns, names, positions):
    cls = types("sensor_msgs/msg/JointState")
    return cls(header=make_header(types, stamp_ns, ""), name=list(names),
               position=np.asarray(positions, dtype=np.float64), velocity=np.zeros(0), effort=np.zeros(0))


def scan(core, t_ms, fingers=1.0, forces=None, target=None, receipt_ms=None):
    """One tactile scan at t_ms (every pad, its wrench) with /joint_states; a target arrives 3 ms
    before it (stamped then, received at receipt_ms if given), as a glove's sample does."""
    t = t_ms * MS
    out = []
    if target is not None:
        stamp, value = teleop_target_from_msg(targets_msg(t - 3 * MS, *zip(*target.items())))
        out += core.on_input("teleop_target", stamp, value, (receipt_ms * MS) if receipt_ms else t - 3 * MS)
    out += core.on_joints(JointSample(t, {"fingers": fingers, "thumb_flexion": 0.5, "thumb_rotation": 0.0}), t)
    for f in PADS:
        out += core.on_taxels(f, t, VOLTS, t)[1]
    for f in PADS:
        out += core.on_wrench(f, t, (forces or {}).get(f, 0.1), t)
    return out


def started(request=None):
    request = request or TeleopRequest()
    core = ManipulationCore(ManipulationConfig())
    scan(core, 0)
    assert core.accept(request, True, 0) is None
    return core, core.start(request, 0)


def test_requests_take_the_parameters_and_are_checked_against_the_limits():
    core = ManipulationCore(ManipulationConfig())
    assert core.resolve(TeleopRequest()) == (TeleopRequest(2.0, 40.0, 0.15), None)
    assert core.resolve(TeleopRequest(1.5, 20.0, 0.3)) == (TeleopRequest(1.5, 20.0, 0.3), None)
    for request, why in ((TeleopRequest(max_pad_force=3.5), "max_pad_force 3.5 above the configured limit 3.0"),
                         (TeleopRequest(max_speed_rpm=-5.0), "max_speed_rpm -5.0 must be > 0"),
                         (TeleopRequest(max_speed_rpm=80.0), "max_speed_rpm 80.0 above the configured limit 70.0"),
                         (TeleopRequest(input_timeout_s=2.0), "input_timeout 2.0 above the configured limit 1.0"),
                         (TeleopRequest(max_pad_force=math.nan), "max_pad_force nan must be > 0")):
        assert str(core.accept(request, True, 0)) == f"invalid: {why}"
    no_thumb = ManipulationCore(ManipulationConfig(fingers=["index", "middle"], monitored_finger="index"))
    assert str(no_thumb.resolve(TeleopRequest())[1]) == ("invalid: teleoperation limits thumb_flexion by its pads' "
                                                         "force, none of them in parameter fingers ['index', 'middle']")


def test_one_goal_at_a_time_with_a_grasp_both_ways():
    core = ManipulationCore(ManipulationConfig())
    scan(core, 0)
    assert core.accept(GraspRequest("pinch"), True, 0) is None
    assert str(core.accept(TeleopRequest(), True, 0)) == "busy: a grasp goal was accepted and is starting"
    core.start(GraspRequest("pinch"), 0)
    assert str(core.accept(TeleopRequest(), True, 0)) == "busy: a grasp goal is running"
    core.cancel(5 * MS)
    core, _ = started()
    assert str(core.accept(GraspRequest("pinch"), True, 0)) == "busy: a teleop goal is running"


def test_admitted_without_targets_it_waits_then_follows_the_latest_target_each_scan():
    core, first = started()
    (feedback,) = first
    assert (feedback.phase, feedback.status.positions, feedback.status.pad_forces) == ("waiting", (1.0, 0.5, 0.0),
                                                                                      (0.1,) * 5)
    assert all(math.isnan(t) for t in feedback.status.targets)
    # a second of waiting: never stale, the motors still
    for t_ms in range(10, 1000, 10):
        actions = scan(core, t_ms)
        assert [a.phase for a in actions] == ["waiting"] and core.busy
    # the glove's targets: 50 Hz, stamps between the scans; each scan follows the latest
    actions = scan(core, 1000, target={"fingers": 5.0})
    assert actions[0] == SendMove({"fingers": 40.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}, 0.3, 1000 * MS)
    status = actions[-1].status
    assert actions[-1].phase == "following" and status.targets[0] == 5.0 and math.isnan(status.targets[1])
    # the index pad reaches the limit: the fingers motor stops, the goal holds
    actions = scan(core, 1010, fingers=3.5, forces={"index": 2.05})
    assert isinstance(actions[0], StopMotors) and actions[-1].phase == "holding"
    assert actions[-1].status.force_limited == ("fingers",) and actions[-1].status.pad_forces[1] == 2.05


def test_the_targets_silent_past_the_timeout_end_it_input_stale_with_the_motors_stopped():
    core, _ = started()
    scan(core, 10, target={"fingers": 5.0, "thumb_flexion": 3.0})
    actions = []
    for t_ms in range(20, 400, 10):  # the glove fell silent after the target received at 7 ms
        actions += scan(core, t_ms)
        if not core.busy:
            break
    # 0.15 s from the last target: the scan at 160 ms is 153 ms after it (the check runs on every /joint_states)
    assert t_ms == 160 and [type(a) for a in actions[-3:]] == [StopMotors, Feedback, Finished]
    done = actions[-1]
    assert (done.kind, done.success, done.reason, done.detail) == ("teleop", False, "input_stale",
                                                                   "prisma/teleop/motor_targets silent for 153 ms")
    result = cdr_round_trip(teleop_result_to_msg(types, done))
    assert result.reason == "input_stale: prisma/teleop/motor_targets silent for 153 ms"
    assert result.success is False and result.duration == pytest.approx(0.16)
    # a new goal follows again once the targets flow
    assert core.accept(TeleopRequest(), True, 170 * MS) is None
    core.start(TeleopRequest(), 170 * MS)
    assert scan(core, 180, target={"fingers": 0.0})[0] == SendMove({"fingers": -40.0, "thumb_flexion": 0.0,
                                                                    "thumb_rotation": 0.0}, 0.3, 180 * MS)


def test_targets_older_than_the_timeout_by_stamp_end_it_too():
    core, _ = started(request=TeleopRequest(input_timeout_s=0.1))
    # received now, stamped 200 ms ago (a glove's clock behind, or a queue that held them)
    t = 10 * MS
    core.on_input("teleop_target", t - 200 * MS, teleop_target_from_msg(targets_msg(0, ["fingers"], [2.0]))[1], t)
    done = scan(core, 10)[-1]
    assert (done.reason, done.detail) == ("input_stale", "prisma/teleop/motor_targets 200 ms older than /joint_states")


def test_stale_sensors_end_it_sensor_stale_and_a_cancel_is_its_success():
    core, _ = started()
    scan(core, 10, target={"fingers": 5.0})
    actions = []
    for t_ms in range(20, 200, 10):  # /joint_states and the targets flow, the taxels and wrenches stopped at 10 ms
        t = t_ms * MS
        core.on_input("teleop_target", t, teleop_target_from_msg(targets_msg(t, ["fingers"], [5.0]))[1], t)
        actions += core.on_joints(JointSample(t, {"fingers": 1.0, "thumb_flexion": 0.5, "thumb_rotation": 0.0}), t)
        if not core.busy:
            break
    done = actions[-1]
    assert (t_ms, done.reason, done.detail) == (120, "sensor_stale", "taxels/thumb silent for 110 ms")
    assert cdr_round_trip(teleop_result_to_msg(types, done)).reason == "sensor_stale: taxels/thumb silent for 110 ms"
    core, _ = started()
    scan(core, 10, target={"fingers": 5.0})
    actions = core.cancel(15 * MS)
    assert isinstance(actions[0], StopMotors)
    done = actions[-1]
    assert (done.success, done.reason) == (True, "canceled")
    result = cdr_round_trip(teleop_result_to_msg(types, done))
    assert (result.success, result.reason, list(result.motors), list(result.targets)[0]) == \
        (True, "canceled", list(MOTORS), 5.0)


def test_the_drivers_ends_of_a_move_that_are_no_reason_to_end_the_goal_leave_it_following():
    """A MoveMotors goal the motor driver ended without refusing it or a fault: a timeout is sent again
    at once; preempted or canceled (by another client) again by the lease's refresh within
    MOVE_REFRESH_S; at a joint limit the motors stand at their stops (a command pushing on into them
    moves nothing), and the next command that moves a motor goes out at once. The goal follows its
    targets on, never stopped without its end."""
    closing = {"fingers": 40.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
    core, _ = started()
    assert [a.velocities_rpm for a in moves(scan(core, 10, target={"fingers": 5.0}))] == [closing]
    assert [a.velocities_rpm for a in moves(core.on_move_result("timeout", 12 * MS))] == [closing]
    for ended in ("preempted", "canceled"):
        assert core.on_move_result(ended, 15 * MS) == [] and core.busy
    sent = {t_ms: moves(scan(core, t_ms, target={"fingers": 5.0})) for t_ms in range(20, 130, 10)}
    assert [(t_ms, a.velocities_rpm) for t_ms, actions in sent.items() for a in actions] == [(120, closing)]
    # the fingers reach their stop (9 rad) before the target's clamp (8.98 rad): the driver ends the move
    scan(core, 130, fingers=8.9, target={"fingers": 12.0})
    assert core.on_move_result("joint_limit", 135 * MS) == [] and core.busy
    assert moves(scan(core, 140, fingers=9.0, target={"fingers": 12.0})) == []  # at the target: stands
    opening = moves(scan(core, 150, fingers=9.0, target={"fingers": 4.0}))
    assert [a.velocities_rpm for a in opening] == [{**closing, "fingers": -40.0}] and core.busy


def test_converters():
    names = ["fingers", "wrist", "thumb_rotation", "thumb_flexion"]
    stamp, target = teleop_target_from_msg(cdr_round_trip(targets_msg(1_700_000_000_123_456_789, names,
                                                                      [3.0, 1.0, -0.5, math.nan])))
    assert stamp == 1_700_000_000_123_456_789 and dict(target.positions) == {"fingers": 3.0, "thumb_rotation": -0.5}
    assert dict(teleop_target_from_msg(targets_msg(0, ["fingers", "thumb_flexion"], [1.0]))[1].positions) == {}
    request = types("prisma_msgs/action/Teleoperate_Goal")(max_pad_force=1.5, max_speed_rpm=30.0, input_timeout=0.2)
    assert teleop_request_from_msg(cdr_round_trip(request)) == TeleopRequest(1.5, 30.0, pytest.approx(0.2))
    status = TeleopStatus(MOTORS, (3.0, math.nan, 0.0), (2.9, 1.0, 0.0), (0.5, 2.0, 0.0, 0.0, 0.0), ("fingers",))
    fb = cdr_round_trip(teleop_feedback_to_msg(types, Feedback("teleop", "holding", status)))
    assert (fb.phase, list(fb.force_limited), list(fb.pad_forces)) == ("holding", ["fingers"], [0.5, 2.0, 0, 0, 0])
    assert list(fb.positions) == pytest.approx([2.9, 1.0, 0.0]) and math.isnan(fb.targets[1])
    refused = cdr_round_trip(teleop_result_to_msg(types, Finished("teleop", False, "busy: a grasp goal is running", 0.0,
                                                                  status)))
    assert (refused.success, refused.reason) == (False, "busy: a grasp goal is running")
    fault = Finished("teleop", False, "motor_fault", 1.0, status, "motor_fault: fingers: overload")
    assert cdr_round_trip(teleop_result_to_msg(types, fault)).reason == "motor_fault: fingers: overload"
    # a goal refused before any /joint_states: where the hand stands is not known
    idle = TELEOP_GOAL.idle_status(ManipulationCore(ManipulationConfig()).context())
    assert all(math.isnan(v) for v in idle.positions + idle.targets + idle.pad_forces)


T0_MS = 1_796_664_778_000  # a wall clock's time, far from 0


def target_at(core, t_ms: float, stamp_ns: int, fingers: float = 4.5) -> list:
    """A target for the fingers stamped `stamp_ns`, received at t_ms."""
    return core.on_input("teleop_target", stamp_ns,
                         teleop_target_from_msg(targets_msg(stamp_ns, ["fingers"], [fingers]))[1], int(t_ms * MS))


def moves(actions: list) -> list:
    return [a for a in actions if isinstance(a, SendMove) and any(v != 0.0 for v in a.velocities_rpm.values())]


@pytest.mark.parametrize(("stamp_ns", "why"), [
    (0, "prisma/teleop/motor_targets stamped 0: publish header.stamp (ros2 topic pub: header: auto)"),
    ((T0_MS - 5000) * MS, "prisma/teleop/motor_targets stamped 5.00 s before it arrived (limit 2 s): stamp each "
                          "sample when it is taken"),
])
def test_targets_refused_by_their_stamp_refuse_the_goal_and_end_a_running_one_before_a_motor_moves(stamp_ns, why):
    core = ManipulationCore(ManipulationConfig())
    scan(core, T0_MS)
    news = target_at(core, T0_MS + 5, stamp_ns)
    assert [n.level for n in news] == ["warning"] and news[0].text.startswith(why)
    assert target_at(core, T0_MS + 5, stamp_ns) == []  # once per episode
    refusal = core.accept(TeleopRequest(), True, (T0_MS + 7) * MS)
    assert refusal is not None and refusal.code == "not_ready" and str(refusal).startswith(f"not_ready: {why}")
    # a goal admitted before the targets came: ended by the first refused target, no motor moved
    core = ManipulationCore(ManipulationConfig())
    scan(core, T0_MS)
    assert core.accept(TeleopRequest(), True, T0_MS * MS) is None
    actions = core.start(TeleopRequest(), T0_MS * MS)
    actions += target_at(core, T0_MS + 5, stamp_ns)
    actions += scan(core, T0_MS + 10)
    done = actions[-1]
    assert moves(actions) == [] and not core.busy
    assert (done.reason, done.detail.startswith(why)) == ("input_stale", True)


def test_targets_stale_against_joint_states_end_the_goal_before_its_first_step():
    # 300 ms old: within max_stamp_age (2 s), beyond the goal's input timeout (0.15 s) against /joint_states
    core = ManipulationCore(ManipulationConfig())
    scan(core, T0_MS)
    assert core.accept(TeleopRequest(), True, T0_MS * MS) is None
    actions = core.start(TeleopRequest(), T0_MS * MS)
    actions += target_at(core, T0_MS + 5, (T0_MS - 295) * MS)
    actions += scan(core, T0_MS + 10)  # taxels complete the scan: the step would have sent 40 rpm
    assert moves(actions) == [] and not core.busy
    assert (actions[-1].reason, actions[-1].detail) == ("input_stale", "prisma/teleop/motor_targets 305 ms older "
                                                                       "than /joint_states")
    # and such targets refuse the next goal at once
    target_at(core, T0_MS + 15, (T0_MS - 285) * MS)
    assert str(core.accept(TeleopRequest(), True, (T0_MS + 16) * MS)) == (
        "not_ready: prisma/teleop/motor_targets 295 ms older than /joint_states")


def test_joint_states_stamped_0_are_refused_and_said_once():
    core = ManipulationCore(ManipulationConfig())
    t = T0_MS * MS
    news = core.on_joints(JointSample(0, {"fingers": 1.0, "thumb_flexion": 0.5, "thumb_rotation": 0.0}), t)
    assert [n.text.split(":")[0] for n in news] == ["/joint_states stamped 0"]
    assert core.joints is None
    assert core.on_joints(JointSample(0, {"fingers": 1.0, "thumb_flexion": 0.5, "thumb_rotation": 0.0}), t + MS) == []
    refusal = str(core.accept(GraspRequest("pinch"), True, t + MS))
    assert refusal.startswith("not_ready: /joint_states stamped 0: publish")


def test_the_stamps_status_names_a_refused_stream_while_it_lasts():
    core = ManipulationCore(ManipulationConfig())
    scan(core, T0_MS)
    assert core.stamp_status() is None  # nothing refused yet: no status
    target_at(core, T0_MS + 5, 0)
    status = core.stamp_status()
    assert status is not None and (status.name, status.level, status.message) == (
        "manipulation: stamps", 1,
        "refused: prisma/teleop/motor_targets stamped 0: publish header.stamp (ros2 topic pub: header: auto)")
    assert status.values["/joint_states"] == "accepted"
    target_at(core, T0_MS + 10, (T0_MS + 9) * MS)
    status = core.stamp_status()
    assert status is not None and (status.level, status.message) == (0, "every stream's stamps accepted")
    assert status.values["refused_samples"] == "1"
