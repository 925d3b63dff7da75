"""Cores of prisma_manipulation with hand-made inputs: contact monitor, sim motors, MoveMotors goal
runner, controllers, hand/world model and its ContactSource."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from prisma_hand_sim.contact_source import ContactSource
from prisma_hand_sim.hand_world import OBJECTS, Disturbance, HandWorld, HandWorldContactSource, released
from prisma_manipulation.contact_monitor import ContactMonitor, first_lost_index
from prisma_manipulation.controllers import (
    ControlInput,
    ControlLimits,
    JointSample,
    MotorCommand,
)
from prisma_manipulation.grasp_controller import GraspController
from prisma_manipulation.motion_controllers import ForceKeeper, HoldController, HorizontalController
from prisma_motor_driver.motor_bus import default_motors
from prisma_motor_driver.motor_goals import MoveGoal, MoveGoalRunner
from prisma_motor_driver.sim_motors import SimMotorBus

MS = 1_000_000


# ---- contact monitor ----------------------------------------------------------------------------
def test_monitor_flags_a_whole_edge_below_k_times_mean():
    v = np.full(9, 1.2, dtype=np.float32)
    v[[0, 3, 6]] = 0.5
    e = ContactMonitor(k=0.8).evaluate("thumb", 5, v)
    assert e.mean_voltage == pytest.approx((3 * 0.5 + 6 * 1.2) / 9)
    assert e.threshold == pytest.approx(0.8 * e.mean_voltage)
    assert e.lost_edges == ("right",) and not e.feasible
    assert e.safe.tolist() == [False, True, True] * 3
    assert e.safe_count("left") == 3 and e.safe_count("bottom") == 2
    # one taxel of the edge above v_t keeps the edge
    v[3] = 1.0
    assert ContactMonitor(k=0.8).evaluate("thumb", 6, v).lost_edges == ()


def test_k_changes_at_run_time_and_bad_k_is_refused_with_its_value():
    monitor = ContactMonitor(k=0.5)
    v = np.array([0.7, 1.0, 1.0, 0.7, 1.0, 1.0, 0.7, 1.0, 1.0], dtype=np.float32)
    assert monitor.evaluate("index", 0, v).feasible
    monitor.set_k(0.9)
    e = monitor.evaluate("index", 1, v)
    assert e.k == 0.9 and e.lost_edges == ("right",)
    for bad in (0.0, -0.1, 2.0, float("nan")):
        with pytest.raises(ValueError, match=f"k {bad}"):
            monitor.set_k(bad)
    assert monitor.k == 0.9


def test_untouched_pad_is_not_a_feasible_contact_with_a_minimum_mean():
    rest = np.array([0.42, 0.47, 0.39, 0.45, 0.41, 0.50, 0.44, 0.38, 0.46], dtype=np.float32)
    assert ContactMonitor(0.8).evaluate("thumb", 0, rest).feasible  # Algorithm 1 alone
    assert not ContactMonitor(0.8, min_mean_voltage=0.55).evaluate("thumb", 0, rest).feasible


@settings(max_examples=60, deadline=None)
@given(arrays(np.float32, (20, 9), elements=st.floats(0.25, 3.0, width=32)), st.floats(0.5, 1.0))
def test_reference_first_loss_matches_the_monitor(volts, k):
    monitor = ContactMonitor(k)
    for edge in ("bottom", "top", "right", "left"):
        expected = next((i for i, row in enumerate(volts) if edge in monitor.evaluate("thumb", i, row).lost_edges),
                        None)
        assert first_lost_index(volts, k, edge) == expected


# ---- sim motors ---------------------------------------------------------------------------------
def test_sim_motor_velocity_response_limits_and_current():
    bus = SimMotorBus(default_motors())
    bus.set_velocities({"fingers": 60.0})
    s = bus.read_state(10 * MS)["fingers"]
    assert s.velocity_rpm == pytest.approx(60.0 * (1 - math.exp(-1.0)), rel=1e-6)  # tau = 10 ms
    w = 2 * math.pi  # 60 rpm
    assert s.position_rad == pytest.approx(w * 0.01 - w * 0.01 * (1 - math.exp(-1.0)), rel=1e-6)
    idle = bus.read_state(200 * MS)["fingers"].current_ma
    bus.set_loads({"fingers": 0.1})
    loaded = bus.read_state(210 * MS)["fingers"].current_ma
    assert loaded - idle == pytest.approx(1000 * 0.1 / 1.8, rel=1e-3)  # current rises with load
    s = bus.read_state(20_000 * MS)["fingers"]  # long past the 9 rad limit
    assert s.position_rad == 9.0 and s.velocity_rpm == 0.0 and s.current_ma == 2300.0  # stalled
    bus.torque_off("fingers")
    assert bus.read_state(20_010 * MS)["fingers"].current_ma == 0.0


def test_sim_position_mode_reaches_target_at_profile_speed():
    bus = SimMotorBus(default_motors())
    bus.set_positions({"thumb_rotation": 1.0}, profile_rpm=30.0)
    assert bus.read_state(200 * MS)["thumb_rotation"].position_rad == pytest.approx(math.pi * 0.2, abs=0.05)
    assert bus.read_state(2000 * MS)["thumb_rotation"].position_rad == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ValueError, match="position 4.0 rad outside"):
        bus.set_positions({"thumb_rotation": 4.0}, 30.0)


# ---- MoveMotors goal runner ---------------------------------------------------------------------
@pytest.mark.parametrize("goal, message", [
    (MoveGoal(["wrist"], "velocity", [1.0]), "unknown motor"),
    (MoveGoal(["fingers"], "velocity", [80.0]), "velocity 80.0 rpm for fingers above the limit 70.0"),
    (MoveGoal(["fingers"], "position", [12.0]), "position 12.0 rad for fingers outside"),
    (MoveGoal(["fingers"], "torque", [1.0]), "mode 'torque'"),
    (MoveGoal(["fingers", "thumb_flexion"], "velocity", [1.0]), "1 targets for 2 motors"),
    (MoveGoal(["fingers"], "velocity", [float("nan")]), "not finite"),
    (MoveGoal(["fingers"], "velocity", [1.0], [1.0, 2.0, 3.0]), "position_limits has 3 entries"),
])
def test_goal_validation_names_the_bad_value(goal, message):
    runner = MoveGoalRunner(SimMotorBus(default_motors()))
    assert message in runner.validate(goal)
    with pytest.raises(ValueError, match=message.split(" ")[0]):
        runner.start(goal, 0)


def _run(runner, bus, until_ns, step_ns=10 * MS, start_ns=0):
    t = start_ns
    while t < until_ns:
        t += step_ns
        feedback, result = runner.tick(bus.read_state(t), t)
        if result:
            return t, feedback, result
    return t, None, None


def test_velocity_goal_stops_at_its_stop_position_with_joint_limit():
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    runner.start(MoveGoal(["thumb_rotation"], "velocity", [30.0], position_limits=[1.0]), 0)
    t, feedback, result = _run(runner, bus, 5000 * MS)
    assert result.success and result.reason == "joint_limit"
    assert 1.0 <= result.final_positions[0] < 1.0 + math.pi * 0.01 + 1e-9  # within one tick of travel
    assert feedback.velocities[0] > 0
    assert bus.read_state(t + 100 * MS)["thumb_rotation"].velocity_rpm == pytest.approx(0.0, abs=0.01)


def test_velocity_goal_timeout_cancel_and_preempt_stop_or_hand_over():
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    runner.start(MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.2), 0)
    t, _, result = _run(runner, bus, 1000 * MS)
    assert result.reason == "timeout" and t == 200 * MS
    runner.start(MoveGoal(["fingers"], "velocity", [10.0]), t)
    _run(runner, bus, t + 100 * MS, start_ns=t)
    result = runner.cancel()
    assert result.reason == "canceled" and not result.success
    assert bus.read_state(t + 300 * MS)["fingers"].velocity_rpm == pytest.approx(0.0, abs=0.01)
    runner.start(MoveGoal(["fingers"], "velocity", [10.0]), t + 300 * MS)
    preempted = runner.start(MoveGoal(["thumb_flexion"], "position", [1.0]), t + 310 * MS)
    assert preempted.reason == "preempted"
    _, _, result = _run(runner, bus, t + 5000 * MS, start_ns=t + 310 * MS)
    assert result.success and result.reason == "reached"


def test_a_resent_velocity_goal_continues_seamlessly_and_spares_a_motor_at_its_stop():
    """The manipulation node keeps a command alive by re-sending it (with a short timeout each
    time): the moving motor does not dip, a motor already stopped at its stop position is not driven
    again, and the last goal times out its timeout after it started, stopping the motors."""
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    goal = MoveGoal(["fingers", "thumb_rotation"], "velocity", [30.0, 30.0], position_limits=[9.0, 0.5],
                    timeout_s=0.4)
    runner.start(goal, 0)
    t, _, result = _run(runner, bus, 300 * MS)
    assert result is None and t == 300 * MS  # fingers still moving
    before = bus.read_state(t)["thumb_rotation"]
    assert 0.5 <= before.position_rad < 0.54 and before.velocity_rpm < 1e-3  # stopped at 0.5 rad
    assert runner.start(goal, t).reason == "preempted"  # the refresh
    after = bus.read_state(t + 10 * MS)
    assert after["fingers"].velocity_rpm == pytest.approx(30.0, abs=1e-6)  # no dip
    assert after["thumb_rotation"].position_rad == pytest.approx(before.position_rad, abs=1e-7)
    assert after["thumb_rotation"].velocity_rpm < 1e-3
    end, _, result = _run(runner, bus, t + 1000 * MS, start_ns=t + 10 * MS)
    assert result.reason == "timeout" and end == t + 400 * MS
    assert bus.read_state(end + 100 * MS)["fingers"].velocity_rpm == pytest.approx(0.0, abs=0.01)


def test_sim_hardware_error_aborts_naming_motor_and_bit():
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    runner.start(MoveGoal(["fingers"], "velocity", [10.0]), 0)
    bus.inject_hardware_error("thumb_flexion", 2)
    _, _, result = _run(runner, bus, 100 * MS)
    assert not result.success
    assert result.reason == "motor_fault: thumb_flexion (id 2) hardware error bit 2 overheating"
    assert not bus.read_state(200 * MS)["thumb_flexion"].torque_on


# ---- controllers --------------------------------------------------------------------------------
LIMITS = ControlLimits(default_motors())


def _input(t_ns, positions, forces=None, contact=None):
    contacts = {"thumb": contact} if contact is not None else {}
    return ControlInput(t_ns, contacts, forces or {}, JointSample(t_ns, positions))


def test_grasp_runs_into_the_joint_limit_or_times_out():
    c = GraspController(LIMITS, "pinch", timeout_s=0.5)
    out = c.start(JointSample(0, {"fingers": 0.0}))
    assert out.command == MotorCommand.of(fingers=60.0)
    out = c.step(_input(10 * MS, {"fingers": 8.99}, {"index": 0.0}))
    assert out.done and out.reason == "joint_limit" and out.command.is_stop and not out.success
    c = GraspController(LIMITS, "pinch", timeout_s=0.5)
    c.start(JointSample(0, {"fingers": 0.0}))
    assert c.step(_input(490 * MS, {"fingers": 1.0}, {"index": 0.1})).reason is None
    out = c.step(_input(500 * MS, {"fingers": 1.0}, {"index": 0.1}))
    assert out.reason == "timeout" and out.command.is_stop


def test_grasp_abort_stops_everything_with_the_reason():
    c = GraspController(LIMITS, "power")
    c.start(JointSample(0, {"fingers": 0.0}))
    out = c.abort(30 * MS, "sensor_stale")
    assert out.done and out.reason == "sensor_stale" and out.command.is_stop and c.stop_ns == 30 * MS
    assert c.step(_input(40 * MS, {"fingers": 1.0})).command is None  # finished: no more commands


def test_power_preset_averages_the_pads_in_contact_and_lateral_closes_by_position():
    c = GraspController(LIMITS, "power")
    assert c.fingers_force({"index": 0.9, "middle": 0.7, "ring": 0.0, "little": 0.05}) == pytest.approx(0.8)
    lateral = GraspController(LIMITS, "lateral", lateral_closure_rad=6.0)
    lateral.start(JointSample(0, {"fingers": 0.0}))
    assert lateral.step(_input(10 * MS, {"fingers": 5.9}, {"thumb": 0.0})).command is None
    out = lateral.step(_input(20 * MS, {"fingers": 6.0}, {"thumb": 0.0}))
    assert out.phase == "close_thumb" and out.command == MotorCommand.of(thumb_flexion=60.0)
    with pytest.raises(ValueError, match="grasp 'fist'"):
        GraspController(LIMITS, "fist")


def test_force_keeper_has_hysteresis():
    keeper = ForceKeeper(target_n=1.0, band_n=0.15, speed_rpm=20.0)
    assert [keeper.update(f) for f in (1.0, 0.9, 0.84, 0.9, 0.99, 1.0, 0.9)] == [0, 0, 20, 20, 20, 0, 0]
    assert keeper.restores == 1


def test_horizontal_joint_limit_also_returns_to_start():
    monitor = ContactMonitor(0.8)
    centred = monitor.evaluate("thumb", 0, np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], np.float32))
    c = HorizontalController(LIMITS)
    c.start(JointSample(0, {"thumb_rotation": 0.5}))
    out = c.step(_input(10 * MS, {"thumb_rotation": 2.99}, contact=centred))
    assert c.reason == "joint_limit" and c.stop_ns == 10 * MS and out.command == MotorCommand.of(thumb_rotation=-20.0)
    out = c.step(_input(20 * MS, {"thumb_rotation": 0.52}, contact=centred))
    assert out.done and out.reason == "joint_limit" and out.success


def test_hold_ignores_a_contact_lost_on_both_sides():
    monitor = ContactMonitor(0.8)
    both = monitor.evaluate("thumb", 0, np.array([0.1, 2.0, 0.1, 0.1, 2.0, 0.1, 0.1, 2.0, 0.1], np.float32))
    assert set(both.lost_edges) == {"right", "left"}
    c = HoldController(LIMITS)
    c.start(JointSample(0, {"thumb_rotation": 0.0}))
    out = c.step(_input(10 * MS, {"thumb_rotation": 0.0}, contact=both))
    assert out.phase == "hold" and c.side is None


# ---- hand/world model ---------------------------------------------------------------------------
def test_force_rises_with_closure_beyond_contact_and_loads_the_motor():
    world = HandWorld(obj=OBJECTS["lateral_card"])
    obj, p = world.obj, world.params
    world.update_joints({"thumb_flexion": obj.thumb_contact_rad - 0.1}, 0)
    assert world.contact("thumb") is None and world.forces()["thumb"] == 0.0
    forces = []
    for extra in (0.5, 1.0, 1.5):
        world.update_joints({"thumb_flexion": obj.thumb_contact_rad + extra}, 0)
        forces.append(world.forces()["thumb"])
    k = world.k
    # thumb pushes the card against a stiff support: F = k*(s - h + u), support gives u = -F/5
    expected = [k * extra * p.thumb_travel_mm_per_rad / (1 + k / obj.fixture_n_per_mm) for extra in (0.5, 1.0, 1.5)]
    assert forces == pytest.approx(expected, rel=1e-9)
    assert world.motor_loads()["thumb_flexion"] == pytest.approx(forces[-1] * p.load_nm_per_n)


def test_support_lets_go_once_the_pinch_holds_and_forces_balance():
    world = HandWorld()  # default: pinch ball presented by a hand that lets go
    pose = world.grasp_pose(1.0)
    world.update_joints({"fingers": pose["fingers"], "thumb_flexion": pose["thumb_flexion"] - 0.6}, 0)
    held = world.forces()
    assert held["index"] > held["thumb"] + 0.25  # the support takes the difference
    world.update_joints({}, 100 * MS)  # held from here
    world.update_joints({}, 500 * MS)
    assert world.state.fixture_n_per_mm == world.obj.fixture_n_per_mm  # not yet: needs 0.5 s held
    world.update_joints({}, 600 * MS)  # lets go, fading with 0.2 s
    world.update_joints({}, 3000 * MS)
    balanced = world.forces()
    assert balanced["index"] == pytest.approx(balanced["thumb"], abs=0.03)  # residual support only


def test_contact_source_contract_and_time_driven_disturbance():
    source = HandWorldContactSource()
    assert isinstance(source, ContactSource)
    assert source.contact("thumb", 0) is None  # open hand
    pose = source.world.grasp_pose(1.0)
    source.update_joints(list(pose), list(pose.values()), 10 * MS)
    c = source.contact("thumb", 10 * MS)
    assert c is not None and c.normal_n > 0.3
    # foreign /joint_states samples (names without positions, an arm's joints) change nothing
    before = dict(source.world.positions)
    assert source.update_joints(["fingers", "thumb_flexion"], [1.0], 20 * MS) is False
    assert source.update_joints(["elbow", "wrist"], [], 30 * MS) is False
    assert source.update_joints(["elbow", "wrist"], [0.5, 0.7], 40 * MS) is False
    assert source.world.positions == before and source._last_ns == 10 * MS
    assert source.contact("thumb", 10 * MS) == c
    world = HandWorld(obj=released("pinch_ball"), disturbances=[Disturbance(0.1, 0.1, dx_mm=-9.0)])
    world.set_positions(world.grasp_pose(1.0))
    source = HandWorldContactSource(world)
    source.update_joints(list(world.positions), list(world.positions.values()), 0)
    assert source.contact("thumb", 50 * MS).x_mm == 0.0
    assert source.contact("thumb", 150 * MS).x_mm == pytest.approx(-4.5)  # half-way through the push
    assert source.contact("thumb", 300 * MS) is None  # slipped off the 14 mm pad
