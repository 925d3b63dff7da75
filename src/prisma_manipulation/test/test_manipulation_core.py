"""ManipulationCore without ROS: goal admission and refusals (invalid, busy, not_ready,
no_contact), one goal at a time, foreign /joint_states, stops, the motor driver's refusals and faults as
every kind's end reason, a gripper goal (the MoveMotors lease:
test_move_lease.py)."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_common.goal_refusal import BUSY, INVALID, NOT_READY, Refusal, refusal_code
from prisma_common.messages import make_header
from prisma_common.typestore import types
from prisma_hand_sim.pad_model import PadParams
from prisma_manipulation.controllers import JointSample
from prisma_manipulation.grasp_goal import GRASP_GOAL
from prisma_manipulation.gripper_goal import GRIPPER_GOAL
from prisma_manipulation.manipulation_core import (
    MOVE_LEASE_S,
    Feedback,
    Finished,
    GoalRefused,
    GraspRequest,
    GripperRequest,
    GripperStatus,
    Ignored,
    ManipulateRequest,
    ManipulationCore,
    SendMove,
    StopMotors,
)
from prisma_manipulation.node_config import ManipulationConfig
from prisma_manipulation.ros_conversions import (
    joint_sample_from_msg,
)
from prisma_manipulation.teleop_goal import TeleopRequest
from prisma_testing.cdr import cdr_round_trip
from prisma_testing.core_inputs import core_at_rest, pressed_pad

MS = 1_000_000



def test_core_validates_goals_with_defaults_and_limits():
    core = core_at_rest()
    resolved, refusal = core.resolve(GraspRequest("pinch"))
    assert refusal is None and (resolved.finger_force, resolved.thumb_force, resolved.speed_rpm) == (0.8, 1.0, 60.0)
    assert (core.resolve(GraspRequest("pinch", speed_rpm=71.0))[1]
            == Refusal(INVALID, "speed_rpm 71.0 above the configured limit 70.0"))
    assert (str(core.resolve(GraspRequest("pinch", thumb_force=3.5))[1])
            == "invalid: thumb_force 3.5 above the configured limit 3.0")
    assert (str(core.resolve(GraspRequest("pinch", finger_force=-1.0))[1])
            == "invalid: finger_force -1.0 must be > 0")
    assert "k 0.55 too low for hold" in str(core.resolve(ManipulateRequest("hold", k=0.55))[1])
    assert "invalid: motion 'roll'" in str(core.resolve(ManipulateRequest("roll"))[1])
    resolved, _ = core.resolve(ManipulateRequest("vertical"))
    assert resolved.speed_rpm == 10.0 and resolved.k == 0.8
    # a goal beyond the limits is refused for that, whatever else is missing
    assert str(core.accept(GraspRequest("pinch", speed_rpm=71.0), False, 0)) == \
        "invalid: speed_rpm 71.0 above the configured limit 70.0"
    thumb_only = ManipulationCore(ManipulationConfig(fingers=["thumb", "middle"]))
    assert str(thumb_only.resolve(GraspRequest("pinch"))[1]) == \
        "invalid: grasp pinch needs the index pad(s), not in parameter fingers ['thumb', 'middle']"
    # GripperCommand: position is the fingers motor angle within its range; max_effort 0 = the default
    assert core.resolve(GripperRequest(4.5)) == (GripperRequest(4.5, 1.0), None)
    assert core.resolve(GripperRequest(0.0, 2.0)) == (GripperRequest(0.0, 2.0), None)
    assert str(core.resolve(GripperRequest(9.5))[1]) == \
        "invalid: position 9.5 rad outside the fingers motor's range [0.0, 9.0] (0 = open)"
    assert str(core.resolve(GripperRequest(3.0, -1.0))[1]) == \
        "invalid: max_effort -1.0 must be >= 0 N (0 = gripper_max_effort 1.0 N)"
    assert str(core.resolve(GripperRequest(3.0, 50.0))[1]) == \
        "invalid: max_effort 50.0 above the configured limit 3.0"
    assert core.resolve(GripperRequest(float("nan")))[1].code == INVALID


def _feed(core, t_ms, taxels=("thumb", "index"), wrenches=("thumb", "index"), joints=True, age_ms=0):
    """One scan at t_ms received at t_ms: joint states, then the named streams stamped age_ms earlier."""
    t = t_ms * MS
    if joints:
        core.on_joints(JointSample(t, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), t)
    for f in taxels:
        core.on_taxels(f, t - age_ms * MS, pressed_pad(), t)
    for f in wrenches:
        core.on_wrench(f, t - age_ms * MS, 0.0, t)


def test_goals_are_refused_not_ready_until_every_stream_they_need_flows():
    core = ManipulationCore(ManipulationConfig())
    pinch, horizontal = GraspRequest("pinch"), ManipulateRequest("horizontal")
    assert core.accept(pinch, False, 0) == Refusal(
        NOT_READY, "MoveMotors action server prisma/motors/move not available (motor_driver not running?)")
    assert str(core.accept(pinch, True, 0)) == "not_ready: no /joint_states received yet"
    _feed(core, 0, taxels=("thumb",), wrenches=())
    assert str(core.accept(pinch, True, 0)) == "not_ready: no taxels/index received yet"
    # a horizontal manipulation steps on the thumb's taxels alone: it could run now
    assert core.readiness(core.streams(horizontal), True, 0) is None
    _feed(core, 10, wrenches=("thumb",))  # the force estimator is still warming up for the index
    assert str(core.accept(pinch, True, 10 * MS)) == "not_ready: no wrench/index received yet"
    use_force = ManipulateRequest("hold", use_force=True)
    assert core.readiness(core.streams(use_force), True, 10 * MS) is None
    _feed(core, 20, wrenches=("thumb",))
    _feed(core, 130, taxels=(), wrenches=())  # joint states on; the hub went quiet at 20 ms
    assert str(core.accept(pinch, True, 130 * MS)) == "not_ready: taxels/thumb silent for 110 ms"
    _feed(core, 140, age_ms=120)  # every stream back, but 120 ms old
    assert str(core.accept(pinch, True, 140 * MS)) == "not_ready: taxels/thumb 120 ms older than /joint_states"
    _feed(core, 150)
    assert core.accept(pinch, True, 150 * MS) is None
    assert not core.busy  # accepted: held for this goal until it starts


def test_one_goal_at_a_time_from_acceptance_to_the_end():
    core = ManipulationCore(ManipulationConfig())
    _feed(core, 0)
    pinch, horizontal = GraspRequest("pinch"), ManipulateRequest("horizontal")
    assert core.accept(pinch, True, 0) is None
    # a Manipulate goal sent together with the Grasp: its goal callback runs before the Grasp starts
    assert str(core.accept(horizontal, True, 0)) == "busy: a grasp goal was accepted and is starting"
    assert str(core.accept(GripperRequest(0.0), True, 0)) == "busy: a grasp goal was accepted and is starting"
    with pytest.raises(GoalRefused, match="busy: a grasp goal was accepted"):
        core.start(horizontal, 0)  # only the admitted goal may start
    core.start(pinch, 0)
    assert core.accept(horizontal, True, 0) == Refusal(BUSY, "a grasp goal is running")
    assert str(core.accept(GripperRequest(0.0), True, 0)) == "busy: a grasp goal is running"
    actions = core.cancel(10 * MS)
    assert actions[-1].reason == "canceled" and not core.busy
    assert core.accept(horizontal, True, 0) is None  # serving again
    core.start(horizontal, 0)
    assert core.busy and core.kind == "manipulate"


def test_foreign_joint_states_change_no_decision():
    """An arm driver's /joint_states (other names, its own stamps) and empty or malformed messages
    between the hand's: the same actions as without them, and each is reported as ignored."""
    from prisma_common.typestore import types as ts

    def hand(t):
        t_ms = t // MS  # the thumb turns out until 200 ms, then back
        return JointSample(t, {"fingers": 1.0, "thumb_flexion": 2.0, "thumb_rotation": 0.01 * min(t_ms, 400 - t_ms)})

    js = ts("sensor_msgs/msg/JointState")
    foreign_msgs = [
        js(header=make_header(ts, 10**12, ""), name=["shoulder", "elbow"], position=np.array([0.1, 0.2]),
           velocity=np.array([], dtype=np.float64), effort=np.array([], dtype=np.float64)),
        js(header=make_header(ts, 0, ""), name=[], position=np.array([], dtype=np.float64),
           velocity=np.array([], dtype=np.float64), effort=np.array([], dtype=np.float64)),
        js(header=make_header(ts, 10**12, ""), name=["fingers", "thumb_flexion", "thumb_rotation"],
           position=np.array([], dtype=np.float64), velocity=np.array([], dtype=np.float64),
           effort=np.array([], dtype=np.float64)),
        js(header=make_header(ts, 10**12, ""), name=["fingers", "thumb_flexion", "thumb_rotation"],
           position=np.array([5.0]), velocity=np.array([], dtype=np.float64), effort=np.array([], dtype=np.float64)),
    ]
    foreign = [joint_sample_from_msg(cdr_round_trip(m)) for m in foreign_msgs]  # no ValueError: empty samples
    assert [f.positions for f in foreign] == [{"shoulder": 0.1, "elbow": 0.2}, {}, {}, {}]

    def run(with_foreign):
        core = ManipulationCore(ManipulationConfig())
        log = []
        for t_ms in range(0, 400, 10):
            t = t_ms * MS
            log.append(core.on_joints(hand(t), t))
            if with_foreign:
                for sample in foreign:
                    ignored = core.on_joints(sample, t + MS)
                    assert len(ignored) == 1 and isinstance(ignored[0], Ignored)
            if t_ms == 20:
                log.append(core.accept(ManipulateRequest("horizontal"), True, t))
                log.append(core.start(ManipulateRequest("horizontal"), t))
            log.append(core.on_taxels("thumb", t, pressed_pad(right_lost=t_ms >= 200), t + 2 * MS)[1])
            log.append(core.check(t + 5 * MS))
        return log, core

    plain, _ = run(False)
    mixed, core = run(True)
    assert mixed == plain
    assert core.ignored_joint_states == 4 * 40
    assert "no position for fingers, thumb_flexion, thumb_rotation (joints ['elbow', 'shoulder'])" in \
        core.on_joints(foreign[0], 0)[0].reason
    finished = [a for actions in plain if isinstance(actions, list) for a in actions if isinstance(a, Finished)]
    assert [f.reason for f in finished] == ["edge_lost"]


def test_core_steps_on_each_complete_scan_and_stops_on_edge_lost():
    core = core_at_rest()
    actions = core.start(ManipulateRequest("horizontal", k=0.9), 0)
    # the lease counts from the oldest watched input: /joint_states from t=0
    assert actions[0] == SendMove({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 20.0}, MOVE_LEASE_S, 0)
    assert core.monitor.k == 0.9  # the goal's k for the goal's duration
    ev, actions = core.on_taxels("thumb", 10 * MS, pressed_pad(), 10 * MS)
    assert ev.k == 0.9 and [type(a) for a in actions] == [Feedback]
    ev, actions = core.on_taxels("thumb", 20 * MS, pressed_pad(right_lost=True), 20 * MS)
    assert ev.lost_edges == ("right",)
    assert actions[0] == SendMove({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": -20.0}, MOVE_LEASE_S, 0)
    core.on_joints(JointSample(30 * MS, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), 30 * MS)
    _, actions = core.on_taxels("thumb", 30 * MS, pressed_pad(), 30 * MS)
    assert isinstance(actions[0], StopMotors)
    done = actions[-1]
    assert isinstance(done, Finished) and done.success and done.reason == "edge_lost"
    assert done.stop_time_s == pytest.approx(0.02)
    assert not core.busy and core.monitor.k == 0.8  # back to the parameter


def test_core_grasp_waits_for_the_wrench_of_the_same_scan():
    core = core_at_rest()
    core.start(GraspRequest("pinch"), 0)
    _, actions = core.on_taxels("thumb", 10 * MS, pressed_pad(), 10 * MS)
    assert actions == []
    _, actions = core.on_taxels("index", 10 * MS, pressed_pad(), 10 * MS)
    assert actions == [] and core.on_wrench("thumb", 10 * MS, 0.0, 11 * MS) == []
    actions = core.on_wrench("index", 10 * MS, 0.85, 12 * MS)
    assert actions[0] == SendMove({"fingers": 0.0, "thumb_flexion": 60.0, "thumb_rotation": 0.0}, MOVE_LEASE_S, 0)


def test_core_stale_and_cancel_and_motor_fault_stop_the_motors():
    overload = "motor_fault: fingers (id 1) hardware error bit 5 overload"
    for trigger, reason in (("stale", "sensor_stale"), ("cancel", "canceled"), ("fault", overload)):
        core = core_at_rest()
        core.start(GraspRequest("pinch"), 0)
        if trigger == "stale":
            for t in range(20, 100, 20):  # the watchdog's ticks: nothing arrives
                core.check(t * MS)
            actions = core.check(101 * MS)
        elif trigger == "cancel":
            actions = core.cancel(5 * MS)
        else:
            actions = core.on_move_result(overload, 5 * MS)
        assert isinstance(actions[0], StopMotors)
        assert actions[-1].reason == reason and not actions[-1].success
        assert not core.busy
    assert core.on_move_result("joint_limit", 0) == []


def test_live_parameters_apply_when_they_should():
    """reconfigure (the node's live parameters): k and min_mean_voltage from the next sample, the
    watchdog's timeout from its next check, goal defaults from the next goal; a running goal's own k
    gives way only to a change of k itself."""
    from dataclasses import replace

    core = core_at_rest()
    core.start(GraspRequest("pinch"), 0)
    core.reconfigure(replace(core.config, stale_timeout=0.2, grasp_speed_rpm=40.0, min_mean_voltage=2.0))
    assert core.busy and not any(isinstance(a, Finished) for a in core.check(150 * MS))  # stale after 200 ms now
    ev, _ = core.on_taxels("thumb", 160 * MS, pressed_pad(), 160 * MS)
    assert ev.mean_voltage < 2.0 and not ev.feasible  # below the new min_mean_voltage
    assert core.resolve(GraspRequest("pinch"))[0].speed_rpm == 40.0
    assert core.check(361 * MS)[-1].reason == "sensor_stale"  # /joint_states silent for 361 ms
    core.start(ManipulateRequest("horizontal", k=0.9), 400 * MS)
    core.reconfigure(replace(core.config, grasp_timeout=5.0))
    assert core.monitor.k == 0.9  # another parameter changed: the goal keeps its k
    core.reconfigure(replace(core.config, k=0.7))
    assert core.monitor.k == 0.7 and core.k_parameter == 0.7


def test_a_manipulation_is_refused_no_contact_on_an_untouched_pad():
    core = ManipulationCore(ManipulationConfig())
    _feed(core, 0, taxels=("thumb",), wrenches=())
    rest = np.array(PadParams().rest_volts, dtype=np.float32)  # mean 0.436 V: nothing on the pad
    core.on_taxels("thumb", 10 * MS, rest, 10 * MS)
    refusal = core.accept(ManipulateRequest("horizontal"), True, 10 * MS)
    assert str(refusal) == ("no_contact: the thumb pad is not in contact (mean 0.44 V, below min_mean_voltage "
                            "0.55 V): a manipulation starts from a held object, grasp first")
    # the refused goal holds nothing: the next one is refused for its own reason, not busy
    assert str(core.accept(GraspRequest("pinch"), True, 10 * MS)) == "not_ready: no taxels/index received yet"
    core.on_taxels("thumb", 20 * MS, pressed_pad(), 20 * MS)  # mean 1.03 V: held
    assert core.accept(ManipulateRequest("horizontal"), True, 20 * MS) is None


def test_a_manipulation_that_loses_its_contact_ends_no_contact():
    core = core_at_rest()
    core.start(ManipulateRequest("vertical"), 0)
    _, actions = core.on_taxels("thumb", 10 * MS, np.array(PadParams().rest_volts, dtype=np.float32), 10 * MS)
    assert isinstance(actions[0], StopMotors)
    done = actions[-1]
    assert (done.kind, done.success, done.reason, done.stop_time_s, done.detail) == \
        ("manipulate", False, "no_contact", 0.01, "")
    assert (done.status.finger_force, done.status.thumb_force) == (0.0, 0.0)


NOT_HOMED_FINGERS = ("not_homed: fingers (id 1) not homed since the servo powered up (the zero may be a turn off): "
                     "home first (the HomeMotors action prisma/motors/home, or home:=true at launch)")


@pytest.mark.parametrize("reason", [
    NOT_HOMED_FINGERS,
    "not_ready: homing (fingers, thumb_flexion, thumb_rotation): send it again when the homing has ended",
    "not_ready: motor bus not connected: [Errno 2] No such file",
    "busy: MoveMotors held by /other: its goal holds the motors for 120 ms more unless renewed"])
@pytest.mark.parametrize("request_", [GraspRequest("pinch"), ManipulateRequest("horizontal"), TeleopRequest(),
                                      GripperRequest(3.0)], ids=lambda r: type(r).__name__)
def test_a_move_goal_the_driver_refuses_ends_every_kind_with_the_drivers_refusal(request_, reason):
    """The driver's code and why, not motor_fault, in the goal's end and in its result's text."""
    core = core_at_rest()
    core.start(request_, 0)
    kind = core.goal
    done = core.on_move_result(reason, 5 * MS)[-1]
    assert (done.kind, done.success, done.reason, done.detail) == (kind.name, False, reason, "")
    assert not core.busy
    if kind is not GRIPPER_GOAL:  # GripperCommand's result has no text (the node's log and /diagnostics say it)
        result = cdr_round_trip(kind.result_to_msg(types, done))
        assert getattr(result, "stop_reason", getattr(result, "reason", None)) == reason


def test_a_motor_command_the_driver_finds_invalid_ends_the_goal_not_ready_with_the_drivers_words():
    """The client's goal was checked here: the driver's invalid (the command late on its way) is not
    the client's to act on by changing its goal, but to send it again."""
    core = core_at_rest()
    core.start(GraspRequest("pinch"), 0)
    late = ("invalid: its timeout 0.3 s ended before it arrived (sent 350 ms ago by its stamp): held up on the way "
            "(a link that dropped?), or the client's clock is behind this one")
    done = core.on_move_result(late, 5 * MS)[-1]
    assert done.reason == f"not_ready: the motor driver refused this node's motor command ({late})"
    assert refusal_code(done.reason) == NOT_READY and not core.busy


def test_a_motor_fault_ends_the_goal_with_the_drivers_words_and_a_bare_one_stays_bare():
    core = core_at_rest()
    core.start(GraspRequest("pinch"), 0)
    overload = "motor_fault: fingers (id 1) hardware error bit 5 overload"
    done = core.on_move_result(overload, 5 * MS)[-1]
    assert (done.reason, cdr_round_trip(GRASP_GOAL.result_to_msg(types, done)).reason) == (overload, overload)
    core.start(GraspRequest("pinch"), 10 * MS)
    assert core.on_move_result("motor_fault", 15 * MS)[-1].reason == "motor_fault"
    core.start(GraspRequest("pinch"), 20 * MS)
    # the driver's own ends of a goal it ran are not refusals: a timeout is renewed, a joint limit ends nothing
    assert not any(isinstance(a, Finished) for a in core.on_move_result("timeout", 25 * MS))
    assert core.on_move_result("joint_limit", 30 * MS) == [] and core.busy


def test_gripper_goal_through_thecore_at_rest():
    """Every configured pad's taxels and wrench step it; the fingers close at 60 rpm and the thumb at
    0.8333 x 60; the highest pad force (the estimator's Fz) stops it; feedback and result carry
    position, effort, stalled and reached_goal."""
    core = ManipulationCore(ManipulationConfig())
    fingers = ("thumb", "index", "middle", "ring", "little")
    _feed(core, 0, taxels=fingers[:2], wrenches=fingers[:2])
    assert str(core.accept(GripperRequest(9.0), True, 0)) == "not_ready: no taxels/middle received yet"
    _feed(core, 10, taxels=fingers, wrenches=fingers)
    refused = core.refused("gripper", Refusal(BUSY, "a grasp goal is running"))
    assert (refused.success, refused.reason, refused.status.position, refused.status.effort) == \
        (False, "busy: a grasp goal is running", 0.0, 0.0)
    assert core.accept(GripperRequest(9.0), True, 10 * MS) is None
    actions = core.start(GripperRequest(9.0), 10 * MS)
    assert actions[0] == SendMove({"fingers": 60.0, "thumb_flexion": 60.0 * 0.8333, "thumb_rotation": 0.0},
                                  MOVE_LEASE_S, 10 * MS)
    assert actions[1] == Feedback("gripper", "close", GripperStatus(position=0.0))

    def scan(t_ms, fingers_rad, forces):
        t = t_ms * MS
        core.on_joints(JointSample(t, {"fingers": fingers_rad, "thumb_flexion": 0.8 * fingers_rad,
                                       "thumb_rotation": 0.0}), t)
        out = []
        for f in fingers:
            out += core.on_taxels(f, t, pressed_pad(), t)[1]
        for f in fingers:
            out += core.on_wrench(f, t, forces.get(f, 0.0), t)
        return out

    assert scan(20, 0.1, {"index": 0.0}) == [Feedback("gripper", "close", GripperStatus(position=0.1))]
    assert scan(30, 3.6, {"index": 0.7, "thumb": 0.6})[-1].status.effort == 0.7
    actions = scan(40, 3.7, {"index": 0.98, "thumb": 1.02})
    assert isinstance(actions[0], StopMotors)
    done = actions[-1]
    assert (done.kind, done.success, done.reason) == ("gripper", True, "force_reached")
    assert done.status == GripperStatus(position=3.7, effort=1.02, stalled=True, reached_goal=False)
    assert not core.busy
