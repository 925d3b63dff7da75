"""Node cores without ROS: watchdog, scan alignment, ManipulationCore decisions (goal admission and
readiness, one goal at a time, foreign /joint_states, the MoveMotors lease), MotorDriverCore
reconnect/diagnostics and preemption on a failing bus, parameter validation against config/*.yaml,
and CDR round trips of the converters."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from prisma_common.messages import make_header, robot_types
from prisma_common.typestore import get_typestore, types
from prisma_manipulation.contact_monitor import ContactMonitor
from prisma_manipulation.controllers import JointSample
from prisma_manipulation.manipulation_core import (
    MOVE_LEASE_S,
    Feedback,
    Finished,
    GraspRequest,
    Ignored,
    ManipulateRequest,
    ManipulationCore,
    MoveLease,
    SendMove,
    StopMotors,
)
from prisma_manipulation.node_config import ManipulationConfig
from prisma_manipulation.ros_conversions import (
    contact_state_from_msg,
    contact_state_to_msg,
    grasp_result_to_msg,
    hand_contact_to_msg,
    joint_sample_from_msg,
    manipulate_feedback_to_msg,
    manipulate_result_to_msg,
)
from prisma_manipulation.sample_alignment import SampleAligner
from prisma_manipulation.watchdog import SensorWatchdog
from prisma_motor_driver.motor_bus import BusError, MotorState
from prisma_motor_driver.motor_driver_core import ERROR, OK, MotorDriverCore, StartOutcome
from prisma_motor_driver.motor_goals import MoveFeedback, MoveGoal, MoveResult
from prisma_motor_driver.node_config import MotorDriverConfig
from prisma_motor_driver.ros_conversions import (
    joint_state_to_msg,
    move_feedback_to_msg,
    move_goal_from_msg,
    move_goal_to_msg,
    move_result_from_msg,
    move_result_to_msg,
)

REPO = Path(__file__).resolve().parents[1]
MS = 1_000_000


def roundtrip(msg):
    store = get_typestore()
    return store.deserialize_cdr(store.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


# ---- watchdog -----------------------------------------------------------------------------------
def test_watchdog_age_by_header_stamps_and_silence_by_receipt():
    w = SensorWatchdog(100 * MS)
    assert w.check(["taxels/thumb"], 10**9) is None  # not armed: no goal
    w.arm(0)
    assert w.check(["taxels/thumb"], 90 * MS) is None  # grace for a stream not seen yet
    w.reference(100 * MS, 100 * MS)
    assert "taxels/thumb silent for 110 ms" == w.check(["taxels/thumb"], 110 * MS)
    w.arm(200 * MS)
    w.reference(300 * MS, 300 * MS)
    w.sample("taxels/thumb", 250 * MS, 300 * MS)
    assert w.check(["taxels/thumb"], 300 * MS) is None  # 50 ms old
    w.sample("taxels/thumb", 190 * MS, 310 * MS)  # delivered 120 ms late
    assert w.check(["taxels/thumb"], 310 * MS) == "taxels/thumb 110 ms older than /joint_states"
    w.sample("taxels/thumb", 305 * MS, 320 * MS)
    assert w.check(["taxels/thumb"], 320 * MS) is None
    assert w.check(["taxels/thumb"], 450 * MS) == "/joint_states silent for 150 ms"


def test_watchdog_freshness_for_admission_has_no_grace():
    w = SensorWatchdog(100 * MS)
    assert w.fresh(["taxels/thumb"], 0) == "no /joint_states received yet"
    w.reference(10 * MS, 10 * MS)
    assert w.fresh(["taxels/thumb"], 10 * MS) == "no taxels/thumb received yet"  # no grace: never seen
    w.sample("taxels/thumb", 10 * MS, 12 * MS)
    assert w.fresh(["taxels/thumb"], 20 * MS) is None
    assert w.fresh(["taxels/thumb", "wrench/thumb"], 20 * MS) == "no wrench/thumb received yet"
    assert w.fresh(["taxels/thumb"], 113 * MS) == "/joint_states silent for 103 ms"
    w.reference(120 * MS, 120 * MS)
    assert w.fresh(["taxels/thumb"], 120 * MS) == "taxels/thumb silent for 108 ms"
    w.sample("taxels/thumb", 15 * MS, 120 * MS)  # arrives now, 105 ms old
    assert w.fresh(["taxels/thumb"], 120 * MS) == "taxels/thumb 105 ms older than /joint_states"
    assert w.check(["taxels/thumb"], 120 * MS) is None  # admission only: nothing is armed


def test_aligner_steps_once_per_complete_scan_and_drops_late_parts():
    a = SampleAligner()
    need = {("taxels", "thumb"), ("wrench", "thumb")}
    a.add(("taxels", "thumb"), 10, "t10")
    assert a.ready(need) is None
    a.add(("taxels", "thumb"), 20, "t20")
    a.add(("wrench", "thumb"), 10, "w10")
    assert a.ready(need) == (10, {("taxels", "thumb"): "t10", ("wrench", "thumb"): "w10"})
    assert a.ready(need) is None  # consumed
    a.add(("wrench", "thumb"), 20, "w20")
    assert a.ready(need)[0] == 20
    a.add(("wrench", "thumb"), 15, "late")  # older than a consumed scan: ignored
    assert a.ready({("wrench", "thumb")}) is None


# ---- ManipulationCore ---------------------------------------------------------------------------
def _core():
    core = ManipulationCore(ManipulationConfig())
    core.on_joints(JointSample(0, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), 0)
    return core


def _volts(right_lost=False):
    v = np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], dtype=np.float32)
    if right_lost:
        v[[0, 3, 6]] = 0.5
    return v


def test_core_validates_goals_with_defaults_and_limits():
    core = _core()
    resolved, reason = core.resolve_grasp(GraspRequest("pinch"))
    assert reason is None and (resolved.finger_force, resolved.thumb_force, resolved.speed_rpm) == (0.8, 1.0, 60.0)
    assert (core.resolve_grasp(GraspRequest("pinch", speed_rpm=71.0))[1]
            == "speed_rpm 71.0 above the configured limit 70.0")
    assert (core.resolve_grasp(GraspRequest("pinch", thumb_force=3.5))[1]
            == "thumb_force 3.5 above the configured limit 3.0")
    assert core.resolve_grasp(GraspRequest("pinch", finger_force=-1.0))[1] == "finger_force -1.0 must be > 0"
    assert "k 0.55 too low for hold" in core.resolve_manipulate(ManipulateRequest("hold", k=0.55))[1]
    assert "motion 'roll'" in core.resolve_manipulate(ManipulateRequest("roll"))[1]
    resolved, _ = core.resolve_manipulate(ManipulateRequest("vertical"))
    assert resolved.speed_rpm == 10.0 and resolved.k == 0.8
    # a goal beyond the limits is refused for that, whatever else is missing
    assert core.accept_grasp(GraspRequest("pinch", speed_rpm=71.0), False, 0) == \
        "speed_rpm 71.0 above the configured limit 70.0"
    thumb_only = ManipulationCore(ManipulationConfig(fingers=["thumb", "middle"]))
    assert thumb_only.resolve_grasp(GraspRequest("pinch"))[1] == \
        "grasp pinch needs the index pad(s), not in parameter fingers ['thumb', 'middle']"


def _feed(core, t_ms, taxels=("thumb", "index"), wrenches=("thumb", "index"), joints=True, age_ms=0):
    """One scan at t_ms received at t_ms: joint states, then the named streams stamped age_ms earlier."""
    t = t_ms * MS
    if joints:
        core.on_joints(JointSample(t, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), t)
    for f in taxels:
        core.on_taxels(f, t - age_ms * MS, _volts(), t)
    for f in wrenches:
        core.on_wrench(f, t - age_ms * MS, 0.0, t)


def test_goals_are_rejected_until_every_stream_they_need_flows():
    core = ManipulationCore(ManipulationConfig())
    pinch, horizontal = GraspRequest("pinch"), ManipulateRequest("horizontal")
    assert core.accept_grasp(pinch, False, 0) == \
        "MoveMotors action server prisma/motors/move not available (motor_driver not running?)"
    assert core.accept_grasp(pinch, True, 0) == "no /joint_states received yet"
    _feed(core, 0, taxels=("thumb",), wrenches=())
    assert core.accept_grasp(pinch, True, 0) == "no taxels/index received yet"
    # a horizontal manipulation steps on the thumb's taxels alone: it could run now
    assert core.readiness(*core.manipulate_streams(horizontal), True, 0) is None
    _feed(core, 10, wrenches=("thumb",))  # the force estimator is still warming up for the index
    assert core.accept_grasp(pinch, True, 10 * MS) == "no wrench/index received yet"
    use_force = ManipulateRequest("hold", use_force=True)
    assert core.readiness(*core.manipulate_streams(use_force), True, 10 * MS) is None
    _feed(core, 20, wrenches=("thumb",))
    _feed(core, 130, taxels=(), wrenches=())  # joint states on; the hub went quiet at 20 ms
    assert core.accept_grasp(pinch, True, 130 * MS) == "taxels/thumb silent for 110 ms"
    _feed(core, 140, age_ms=120)  # every stream back, but 120 ms old
    assert core.accept_grasp(pinch, True, 140 * MS) == "taxels/thumb 120 ms older than /joint_states"
    _feed(core, 150)
    assert core.accept_grasp(pinch, True, 150 * MS) is None
    assert not core.busy  # accepted: held for this goal until it starts


def test_one_goal_at_a_time_from_acceptance_to_the_end():
    core = ManipulationCore(ManipulationConfig())
    _feed(core, 0)
    pinch, horizontal = GraspRequest("pinch"), ManipulateRequest("horizontal")
    assert core.accept_grasp(pinch, True, 0) is None
    # a Manipulate goal sent together with the Grasp: its goal callback runs before the Grasp starts
    assert core.accept_manipulate(horizontal, True, 0) == "a grasp goal was accepted and is starting"
    assert core.accept_grasp(pinch, True, 0) == "a grasp goal was accepted and is starting"
    with pytest.raises(ValueError, match="a grasp goal was accepted"):
        core.start_manipulate(horizontal, 0)  # only the accepted goal may start
    core.start_grasp(pinch, 0)
    assert core.accept_manipulate(horizontal, True, 0) == "a grasp goal is running"
    actions = core.cancel(10 * MS)
    assert actions[-1].reason == "canceled" and not core.busy
    assert core.accept_manipulate(horizontal, True, 0) is None  # serving again
    core.start_manipulate(horizontal, 0)
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
    foreign = [joint_sample_from_msg(roundtrip(m)) for m in foreign_msgs]  # no ValueError: empty samples
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
                log.append(core.accept_manipulate(ManipulateRequest("horizontal"), True, t))
                log.append(core.start_manipulate(ManipulateRequest("horizontal"), t))
            log.append(core.on_taxels("thumb", t, _volts(right_lost=t_ms >= 200), t + 2 * MS)[1])
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
    core = _core()
    actions = core.start_manipulate(ManipulateRequest("horizontal", k=0.9), 0)
    assert actions[0] == SendMove({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 20.0}, MOVE_LEASE_S)
    assert core.monitor.k == 0.9  # the goal's k for the goal's duration
    ev, actions = core.on_taxels("thumb", 10 * MS, _volts(), 10 * MS)
    assert ev.k == 0.9 and [type(a) for a in actions] == [Feedback]
    ev, actions = core.on_taxels("thumb", 20 * MS, _volts(right_lost=True), 20 * MS)
    assert ev.lost_edges == ("right",)
    assert actions[0] == SendMove({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": -20.0}, MOVE_LEASE_S)
    core.on_joints(JointSample(30 * MS, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), 30 * MS)
    _, actions = core.on_taxels("thumb", 30 * MS, _volts(), 30 * MS)
    assert isinstance(actions[0], StopMotors)
    done = actions[-1]
    assert isinstance(done, Finished) and done.success and done.reason == "edge_lost"
    assert done.stop_time_s == pytest.approx(0.02)
    assert not core.busy and core.monitor.k == 0.8  # back to the parameter


def test_core_grasp_waits_for_the_wrench_of_the_same_scan():
    core = _core()
    core.start_grasp(GraspRequest("pinch"), 0)
    _, actions = core.on_taxels("thumb", 10 * MS, _volts(), 10 * MS)
    assert actions == []
    _, actions = core.on_taxels("index", 10 * MS, _volts(), 10 * MS)
    assert actions == [] and core.on_wrench("thumb", 10 * MS, 0.0, 11 * MS) == []
    actions = core.on_wrench("index", 10 * MS, 0.85, 12 * MS)
    assert actions[0] == SendMove({"fingers": 0.0, "thumb_flexion": 60.0, "thumb_rotation": 0.0}, MOVE_LEASE_S)


def test_core_stale_and_cancel_and_motor_fault_stop_the_motors():
    for trigger, reason in (("stale", "sensor_stale"), ("cancel", "canceled"), ("fault", "motor_fault")):
        core = _core()
        core.start_grasp(GraspRequest("pinch"), 0)
        if trigger == "stale":
            actions = core.check(101 * MS)
        elif trigger == "cancel":
            actions = core.cancel(5 * MS)
        else:
            actions = core.on_move_result("motor_fault: fingers (id 1) hardware error bit 5 overload", 5 * MS)
        assert isinstance(actions[0], StopMotors)
        assert actions[-1].reason == reason and not actions[-1].success
        assert not core.busy
    assert core.on_move_result("joint_limit", 0) == []


def test_motor_commands_are_leased_and_refreshed_while_they_hold():
    """The motor driver stops a MoveMotors goal after MOVE_LEASE_S (0.3 s); the core re-sends the
    running command every 0.1 s, so the motors stop within 0.3 s of the last refresh when it dies."""
    core = _core()
    rotate = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 20.0}
    back = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": -20.0}

    def scan(t_ms, rotation=0.5, right_lost=False):
        """Joint states (refreshes ride on their check) and a thumb sample at t_ms: what was sent."""
        t = t_ms * MS
        sent = core.on_joints(JointSample(t, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": rotation}), t)
        sent += core.on_taxels("thumb", t, _volts(right_lost), t)[1]
        return [a for a in sent if not isinstance(a, Feedback)]

    assert core.start_manipulate(ManipulateRequest("horizontal"), 0)[0] == SendMove(rotate, 0.3)
    assert [scan(t) for t in range(10, 100, 10)] == [[]] * 9  # same command: nothing sent
    assert scan(100) == [SendMove(rotate, 0.3)]  # the refresh
    assert core.check(150 * MS) == [] and scan(190) == [] and scan(200) == [SendMove(rotate, 0.3)]
    # the driver's goal timed out before a refresh reached it (this node stalled): sent again at once
    assert core.on_move_result("timeout", 230 * MS) == [SendMove(rotate, 0.3)]
    assert scan(240) == [] and scan(320) == [] and scan(330) == [SendMove(rotate, 0.3)]
    # a new command restarts the lease period
    assert scan(340, right_lost=True) == [SendMove(back, 0.3)]
    assert [scan(t) for t in range(350, 440, 10)] == [[]] * 9 and scan(440) == [SendMove(back, 0.3)]
    # the driver stopped the motors at its joint limit: no refresh drives them on
    assert core.on_move_result("joint_limit", 450 * MS) == []
    assert [scan(t) for t in range(450, 610, 10)] == [[]] * 16 and core.busy
    # a stop is a cancel, and nothing is refreshed after the goal
    core.on_joints(JointSample(610 * MS, {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}), 610 * MS)
    _, actions = core.on_taxels("thumb", 610 * MS, _volts(), 610 * MS)
    assert isinstance(actions[0], StopMotors) and isinstance(actions[-1], Finished)
    assert core.check(10**9) == [] and core.on_move_result("timeout", 10**9) == []


def test_move_lease_decisions():
    lease = MoveLease(lease_s=0.3, refresh_s=0.1)
    assert lease.refresh(0) is None  # nothing to keep alive
    assert lease.command({"fingers": 60.0}, 5 * MS) == SendMove({"fingers": 60.0}, 0.3)
    assert lease.refresh(104 * MS) is None and lease.refresh(105 * MS) == SendMove({"fingers": 60.0}, 0.3)
    assert lease.command({"fingers": 0.0, "thumb_flexion": 0.0}, 110 * MS) == StopMotors()
    assert lease.refresh(10**9) is None and lease.renew(10**9) is None
    with pytest.raises(ValueError, match="refresh 0.3 s must be > 0 and below the lease 0.3 s"):
        MoveLease(lease_s=0.3, refresh_s=0.3)


# ---- MotorDriverCore ----------------------------------------------------------------------------
class FlakyBus:
    """Opens only after `failures` attempts; can lose the link."""

    def __init__(self, failures):
        from prisma_motor_driver.motor_bus import BusStats, default_motors

        self.motors, self.stats, self.failures = default_motors(), BusStats(), failures
        self.attempts, self.down = [], False

    def open(self):
        self.attempts.append(self.now)
        if len(self.attempts) <= self.failures:
            raise BusError("cannot open Dynamixel port /dev/ttyUSB9")
        self.down = False

    def close(self):
        pass

    def read_state(self, stamp_ns):
        if self.down:
            raise BusError("sync read present state: There is no status packet! after 4 attempts")
        return {n: MotorState(n, 0.0, 0.0, 0.0) for n in self.motors}

    def set_velocities(self, rpm):
        pass

    def stop(self, names=None):
        pass


def test_driver_reconnects_with_exponential_backoff_and_reports_it():
    bus = FlakyBus(failures=3)
    core = MotorDriverCore(MotorDriverConfig(backend="dynamixel"), bus=bus)
    for t_ms in range(0, 5000, 10):
        bus.now = t_ms * MS
        core.tick(t_ms * MS)
    assert bus.attempts == [0, 500 * MS, 1500 * MS, 3500 * MS]  # 0.5, 1, 2 s apart
    assert core.connected
    core.start(MoveGoal(["fingers"], "velocity", [10.0]), 5000 * MS)
    bus.down = True
    bus.now = 5010 * MS
    tick = core.tick(5010 * MS)
    assert tick.states is None and tick.result.reason.startswith("motor_fault: communication: sync read")
    diag = core.diagnostics()
    assert diag[0].level == ERROR and "disconnected" in diag[0].message and diag[0].values["reconnects"] == "1"
    assert core.validate(MoveGoal(["fingers"], "velocity", [1.0])).startswith("motor bus not connected")


def test_bus_error_while_preempting_ends_the_old_goal_and_the_new_one():
    bus = FlakyBus(failures=0)
    bus.now, stops, writes = 0, [], []
    bus.fail_writes = False

    def set_velocities(rpm):
        if bus.fail_writes:
            raise BusError("sync write goal velocity: There is no status packet! after 4 attempts")
        writes.append(dict(rpm))

    bus.set_velocities, bus.stop = set_velocities, lambda names=None: stops.append(list(names))
    core = MotorDriverCore(MotorDriverConfig(backend="dynamixel"), bus=bus)
    core.tick(0)
    assert core.start(MoveGoal(["fingers"], "velocity", [10.0]), 0) == StartOutcome()
    core.tick(10 * MS)
    bus.fail_writes = True
    outcome = core.start(MoveGoal(["fingers", "thumb_flexion"], "velocity", [20.0, 5.0]), 20 * MS)
    assert outcome.preempted.reason == "preempted" and outcome.preempted.final_positions == [0.0]
    assert outcome.failed == MoveResult(
        False, [], "motor_fault: communication: sync write goal velocity: There is no status packet! after 4 attempts")
    assert not core.runner.active  # neither goal is left running
    assert stops == [["fingers", "thumb_flexion"]]  # what either goal moved was told to stop
    assert core.tick(30 * MS).result is None  # nothing to end later on
    # an invalid goal changes nothing: the running goal goes on
    bus.fail_writes = False
    core.start(MoveGoal(["fingers"], "velocity", [10.0]), 40 * MS)
    with pytest.raises(ValueError, match="velocity 90.0 rpm for fingers above the limit"):
        core.start(MoveGoal(["fingers"], "velocity", [90.0]), 50 * MS)
    assert core.runner.active and core.runner.goal.targets == [10.0]


def test_driver_diagnostics_per_motor():
    core = MotorDriverCore(MotorDriverConfig())
    core.tick(10 * MS)
    diag = {d.name: d for d in core.diagnostics()}
    assert diag["motor_driver: bus"].level == OK
    assert diag["motor_driver: thumb_rotation"].values["id"] == "3"


# ---- parameters -----------------------------------------------------------------------------------
@pytest.mark.parametrize("cls, path, node", [
    (MotorDriverConfig, "config/motor_driver.yaml", "motor_driver"),
    (ManipulationConfig, "config/manipulation.yaml", "manipulation"),
])
def test_yaml_matches_the_declared_defaults(cls, path, node):
    params = yaml.safe_load((REPO / path).read_text())[f"/**/{node}"]["ros__parameters"]
    assert params == cls().as_parameters()
    cls.from_parameters(params)


def test_manipulation_limits_equal_the_motor_driver_limits():
    driver = yaml.safe_load((REPO / "config/motor_driver.yaml").read_text())["/**/motor_driver"]["ros__parameters"]
    manip = yaml.safe_load((REPO / "config/manipulation.yaml").read_text())["/**/manipulation"]["ros__parameters"]
    for key in ("motor_names", "min_positions", "max_positions"):
        assert manip[key] == driver[key]


@pytest.mark.parametrize("cls, values, message", [
    (MotorDriverConfig, {"backend": "can"}, "invalid parameter 'backend' = 'can'"),
    (MotorDriverConfig, {"rate_hz": 0.0}, "invalid parameter 'rate_hz' = 0.0"),
    (MotorDriverConfig, {"motor_ids": [1, 2]}, "invalid parameter 'motor_ids' = [1, 2]"),
    (MotorDriverConfig, {"max_positions": [9.0, 7.0, -4.0]}, "position limits"),
    (ManipulationConfig, {"grasp_speed_rpm": 80.0}, "invalid parameter 'grasp_speed_rpm' = 80.0: above max_speed_rpm"),
    (ManipulationConfig, {"monitored_finger": "wrist"}, "invalid parameter 'monitored_finger' = 'wrist'"),
    (ManipulationConfig, {"frame_id_format": "pad"}, "invalid parameter 'frame_id_format' = 'pad'"),
])
def test_bad_parameters_name_themselves(cls, values, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        cls.from_parameters(values)


# ---- converters (CDR round trip) ------------------------------------------------------------------
def test_contact_state_round_trip():
    e = ContactMonitor(0.8).evaluate("middle", 1_700_000_000_123_456_789, _volts(right_lost=True))
    back = contact_state_from_msg(roundtrip(contact_state_to_msg(types, e, "prisma_middle_pad")))
    assert back.finger == "middle" and back.stamp_ns == e.stamp_ns
    assert np.array_equal(back.voltages, e.voltages) and np.array_equal(back.safe, e.safe)
    assert back.lost_edges == ("right",) and back.feasible is False
    assert back.threshold == pytest.approx(e.threshold, rel=1e-6) and back.k == pytest.approx(0.8)


def test_hand_contact_holds_each_fingers_contact_state():
    monitor = ContactMonitor(0.8)
    evaluations = [monitor.evaluate("thumb", 3_000_000_000, _volts()),
                   monitor.evaluate("index", 3_000_400_000, _volts(right_lost=True))]
    msg = roundtrip(hand_contact_to_msg(types, [contact_state_to_msg(types, e, f"{e.finger}_pad")
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
    msg = roundtrip(joint_state_to_msg(types, 2_000_000_000, states))
    assert list(msg.velocity) == pytest.approx([2 * np.pi, -2 * np.pi / 3])  # rad/s
    assert list(msg.effort) == pytest.approx([0.25, 0.01])  # A
    sample = joint_sample_from_msg(msg)
    assert sample.stamp_ns == 2_000_000_000 and sample.positions == {"fingers": 1.5, "thumb_rotation": -0.5}
    assert sample.velocities["fingers"] == pytest.approx(60.0) and sample.currents["fingers"] == pytest.approx(250.0)


def test_action_message_round_trips():
    goal = MoveGoal(["fingers", "thumb_flexion"], "velocity", [10.0, -5.0], [8.0, 0.5], 2.5)
    assert move_goal_from_msg(roundtrip(move_goal_to_msg(types, goal))) == goal
    result = MoveResult(False, [1.0, 2.0], "motor_fault: fingers (id 1) hardware error bit 5 overload")
    assert move_result_from_msg(roundtrip(move_result_to_msg(types, result))) == result
    fb = roundtrip(move_feedback_to_msg(types, MoveFeedback([1.0], [2.0], [3.0])))
    assert list(fb.currents) == [3.0]
    done = Finished("grasp", True, "force_reached", 1.25, 0.81, 1.02)
    r = roundtrip(grasp_result_to_msg(types, done))
    assert r.success and r.reason == "force_reached" and r.thumb_force == pytest.approx(1.02)
    m = roundtrip(manipulate_result_to_msg(types, Finished("manipulate", True, "edge_lost", 0.42, 0, 0)))
    assert m.stop_reason == "edge_lost" and m.stop_time == pytest.approx(0.42)
    f = roundtrip(manipulate_feedback_to_msg(types, Feedback("manipulate", "rotate", 0, 0, True, 0.9)))
    assert f.phase == "rotate" and f.feasible and f.threshold == pytest.approx(0.9)


def test_robot_types_fetches_action_parts_from_the_action_class():
    class Action:
        Goal, Result, Feedback = "G", "R", "F"

    lookup = robot_types(lambda name: f"msg:{name}",
                         lambda name: Action if name == "prisma_msgs/action/MoveMotors" else None)
    assert lookup("prisma_msgs/action/MoveMotors_Goal") == "G"
    assert lookup("prisma_msgs/msg/ContactState") == "msg:prisma_msgs/msg/ContactState"
