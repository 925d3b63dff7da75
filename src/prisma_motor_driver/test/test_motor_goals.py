"""MoveMotors goal runner on the simulated motors: validation, stop positions, timeout, cancel,
preemption, resent goals, hardware errors."""
from __future__ import annotations

import math

import pytest

from prisma_motor_driver.backend import BusError, default_motors
from prisma_motor_driver.motor_goals import MoveGoal, MoveGoalRunner, MoveResult, end_severity, goal_expired
from prisma_motor_driver.sim_backend import SimMotorBus

MS = 1_000_000


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


def test_a_stamped_goal_times_out_from_its_stamp_and_one_arriving_after_its_timeout_is_refused():
    """A velocity goal sent at 1.00 s with a 0.3 s lease: delivered at 1.05 s it runs until 1.30 s;
    delivered at 1.35 s (a link that dropped held it back) it is refused, naming the delay. A stamp
    from a client clock ahead of the driver's (arrival before the stamp) times out from the arrival."""
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    sent = 1000 * MS
    goal = MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, stamp_ns=sent)
    assert goal_expired(goal, sent + 50 * MS) is None
    runner.start(goal, sent + 50 * MS)
    t, _, result = _run(runner, bus, 3000 * MS, start_ns=sent + 50 * MS)
    assert result.reason == "timeout" and t == sent + 300 * MS
    assert goal_expired(goal, sent + 350 * MS) == (
        "its timeout 0.3 s ended before it arrived (sent 350 ms ago by its stamp): held up on the way "
        "(a link that dropped?), or the client's clock is behind this one")
    assert goal_expired(MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3), 10**12) is None  # unstamped
    ahead = MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, stamp_ns=5000 * MS)
    runner.start(ahead, 4000 * MS)
    t, _, result = _run(runner, bus, 9000 * MS, start_ns=4000 * MS)
    assert result.reason == "timeout" and t == 4300 * MS


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


MANIP, OTHER = "/manipulation", "/second/manipulation"


def test_one_controller_holds_the_motors_while_its_goal_runs_and_renews_it():
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    assert runner.lease_holder(0) is None and runner.busy_reason(MoveGoal(["fingers"], "velocity", [5.0]), 0) is None
    runner.start(MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, controller=MANIP), 0)
    assert runner.lease_holder(100 * MS) == MANIP
    other = MoveGoal(["thumb_flexion"], "velocity", [5.0], timeout_s=0.3, controller=OTHER)
    assert runner.busy_reason(other, 100 * MS) == (
        "MoveMotors held by /manipulation: its goal holds the motors for 200 ms more unless renewed; wait for its "
        "end, cancel it, or stop that controller (this goal's controller: /second/manipulation)")
    anonymous = MoveGoal(["fingers"], "velocity", [5.0])
    assert "(this goal's controller: an anonymous client (empty controller))" in runner.busy_reason(anonymous, 0)
    # the holder renews its lease: its next goal preempts its own, as before controllers were named
    renewal = MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, controller=MANIP)
    assert runner.busy_reason(renewal, 100 * MS) is None
    assert runner.start(renewal, 100 * MS).reason == "preempted"
    assert "for 300 ms more" in runner.busy_reason(other, 100 * MS)
    # its lease ends with its timeout: the next controller's goal is served
    t, _, result = _run(runner, bus, 1000 * MS, start_ns=100 * MS)
    assert result.reason == "timeout" and t == 400 * MS
    assert runner.lease_holder(t) is None and runner.busy_reason(other, t) is None
    runner.start(other, t)
    assert runner.lease_holder(t) == OTHER


def test_a_goal_without_timeout_holds_the_motors_until_it_ends_and_a_cancel_frees_them():
    bus = SimMotorBus(default_motors())
    runner = MoveGoalRunner(bus)
    runner.start(MoveGoal(["thumb_flexion"], "position", [1.0]), 0)  # anonymous: ros2 action send_goal
    reason = runner.busy_reason(MoveGoal(["fingers"], "velocity", [5.0], controller=MANIP), 5000 * MS)
    assert reason.startswith("MoveMotors held by an anonymous client (empty controller): its goal holds the "
                             "motors until it ends (no timeout)")
    # anonymous clients cannot be told apart: one preempts another's goal
    assert runner.busy_reason(MoveGoal(["fingers"], "velocity", [5.0]), 0) is None
    assert runner.cancel().reason == "canceled"
    assert runner.lease_holder(10 * MS) is None


def test_a_velocity_goal_ended_at_its_joint_limit_keeps_its_lease_until_its_timeout():
    """Its controller is still renewing it: another's goal in between would take over the motors
    for one renewal period."""
    bus = SimMotorBus(default_motors(), initial_positions={"thumb_rotation": 0.98})
    runner = MoveGoalRunner(bus)
    runner.start(MoveGoal(["thumb_rotation"], "velocity", [30.0], [1.0], timeout_s=0.3, controller=MANIP), 0)
    t, _, result = _run(runner, bus, 1000 * MS)
    assert result.reason == "joint_limit" and t < 300 * MS and not runner.active
    other = MoveGoal(["fingers"], "velocity", [5.0], controller=OTHER)
    assert runner.lease_holder(t) == MANIP
    assert f"for {300 - t // MS} ms more unless renewed" in runner.busy_reason(other, t)
    assert runner.busy_reason(other, 300 * MS) is None
    # a failure (or a cancel) frees them at once
    runner.start(MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, controller=MANIP), 400 * MS)
    assert runner.communication_failure(BusError("port gone")).reason.startswith("motor_fault")
    assert runner.lease_holder(410 * MS) is None


def test_the_log_keeps_quiet_about_a_refresh_and_a_stop():
    """A client's refresh (preempted) and stop (canceled, after every manipulation goal) are not news;
    a success is info, any other end a warning."""
    ends = [MoveResult(False, [], "preempted"), MoveResult(False, [], "canceled"), MoveResult(True, [], "timeout"),
            MoveResult(True, [], "joint_limit"), MoveResult(False, [], "motor_fault: fingers (id 1) overload")]
    assert [end_severity(r) for r in ends] == [None, None, "info", "info", "warn"]
