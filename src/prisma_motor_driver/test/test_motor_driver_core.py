"""MotorDriverCore without ROS: reconnect with backoff, preemption on a failing bus, diagnostics."""
from __future__ import annotations

import pytest

from prisma_common.parameters import ParameterError
from prisma_motor_driver.backend import BusError, MotorState
from prisma_motor_driver.motor_driver_core import ERROR, OK, MotorDriverCore, StartOutcome
from prisma_motor_driver.motor_goals import MoveGoal, MoveResult
from prisma_motor_driver.node_config import MotorDriverConfig

MS = 1_000_000


class FlakyBus:
    """Opens only after `failures` attempts; can lose the link."""

    def __init__(self, failures):
        from prisma_motor_driver.backend import BusStats, default_motors

        self.motors, self.stats, self.failures = default_motors(), BusStats(), failures
        self.attempts, self.down = [], False
        # motors that know their zero (as the sim's): homing is not what these tests are about
        self.homed, self.needs_homing, self.servo_info = {n: True for n in self.motors}, False, {}

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
    assert str(core.validate(MoveGoal(["fingers"], "velocity", [1.0]))).startswith("not_ready: motor bus not connected")


def test_a_backoff_that_could_not_double_is_refused_at_start():
    with pytest.raises(ParameterError, match="'reconnect_backoff_max' = 0.25: must be >= reconnect_backoff_initial"):
        MotorDriverConfig.from_parameters({"reconnect_backoff_initial": 0.5, "reconnect_backoff_max": 0.25})


def test_validation_at_arrival_refuses_a_goal_whose_timeout_ended_on_the_way():
    core = MotorDriverCore(MotorDriverConfig(backend="sim"))
    core.connect(0)
    late = MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, stamp_ns=1000 * MS)
    assert core.validate(late, 1299 * MS) is None
    assert str(core.validate(late, 2000 * MS)).startswith(
        "invalid: its timeout 0.3 s ended before it arrived (sent 1000 ms ago")
    assert core.validate(late) is None  # no arrival time given: the form alone


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


def test_a_goal_naming_a_faulted_motor_is_accepted_and_fails_with_the_fault_reason():
    """A client re-sending its goal as the fault is found must still learn the motor and the bit:
    an action rejection carries no reason, so the goal is valid and fails at start. The running goal
    and goals for the other motors are not affected; once the error clears the motor takes goals."""
    core = MotorDriverCore(MotorDriverConfig())
    core.tick(10 * MS)
    core.start(MoveGoal(["fingers"], "velocity", [5.0]), 10 * MS)
    core.bus.inject_hardware_error("fingers", 5)
    reason = "motor_fault: fingers (id 1) hardware error bit 5 overload"
    assert core.tick(20 * MS).result.reason == reason
    core.start(MoveGoal(["thumb_rotation"], "velocity", [5.0]), 30 * MS)
    faulted = MoveGoal(["fingers", "thumb_flexion"], "velocity", [10.0, 10.0])
    assert core.validate(faulted) is None
    assert str(core.validate(MoveGoal(["fingers"], "velocity", [90.0]))) == \
        "invalid: velocity 90.0 rpm for fingers above the limit 70.0 rpm"
    assert core.start(faulted, 40 * MS) == StartOutcome(failed=MoveResult(False, [], reason))
    assert core.runner.goal.motors == ["thumb_rotation"]  # the running goal goes on
    assert core.tick(50 * MS).result is None
    core.bus.clear_hardware_error("fingers")
    core.tick(60 * MS)
    outcome = core.start(faulted, 70 * MS)
    assert outcome.failed is None and outcome.preempted.reason == "preempted"
    assert core.runner.goal is faulted


def test_position_goal_settings_change_at_run_time():
    """reconfigure (the node's live parameters): the profile speed of the next position goal, the
    tolerance from the next tick."""
    from dataclasses import replace

    from prisma_motor_driver.motor_goals import POSITION

    core = MotorDriverCore(MotorDriverConfig())
    core.connect(0)
    core.tick(0)
    core.reconfigure(replace(core.config, position_profile_rpm=60.0))
    core.start(MoveGoal(["thumb_rotation"], POSITION, [1.0]), 0)
    assert core.bus._motor("thumb_rotation").profile_rad_s == pytest.approx(2 * 3.141592653589793)
    assert core.tick(10 * MS).result is None  # under way, not within 0.02 rad yet
    core.reconfigure(replace(core.config, position_tolerance=1.0))
    result = core.tick(20 * MS).result
    assert result is not None and (result.success, result.reason) == (True, "reached")
    assert (core.runner.profile_rpm, core.runner.position_tolerance_rad) == (60.0, 1.0)


def test_a_second_controllers_goal_is_refused_busy_and_the_holders_goal_goes_on():
    core = MotorDriverCore(MotorDriverConfig(backend="sim"))
    core.connect(0)
    held = MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3, stamp_ns=0, controller="/manipulation")
    assert core.validate(held, 0) is None and core.start(held, 0) == StartOutcome()
    intruder = MoveGoal(["fingers"], "velocity", [-10.0], timeout_s=0.3, controller="/left/manipulation")
    refusal = core.validate(intruder, 50 * MS)
    assert refusal.code == "busy" and str(refusal).startswith(
        "busy: MoveMotors held by /manipulation: its goal holds the motors for 250 ms more unless renewed")
    # an invalid goal is told what is wrong with it first, whoever holds the motors
    assert core.validate(MoveGoal(["fingers"], "velocity", [90.0], controller="/x"), 50 * MS).code == "invalid"
    assert core.runner.goal is held
    assert core.tick(60 * MS).states["fingers"].velocity_rpm == pytest.approx(10.0, abs=0.1)  # still driven
    assert core.validate(intruder, 300 * MS) is None  # the lease ran out: the motors are free again


def test_a_tick_after_a_long_gap_stops_the_motors_before_it_reads_them():
    """The driver held up (SIGSTOP) for 2 s mid-rotation with a 0.3 s lease: its first tick after the
    thaw stops the sim motors before reading them, so that tick's state already stands still (the
    velocity loop's 10 ms lag is all that moves) and no tick after it moves; the goal ends timeout."""
    core = MotorDriverCore(MotorDriverConfig())  # the sim motors
    assert core.connect(0) is None
    goal = MoveGoal(["thumb_rotation"], "velocity", [30.0], timeout_s=0.3, controller="/manipulation")
    assert core.validate(goal, 0) is None
    core.start(goal, 0)
    for t_ms in range(10, 110, 10):
        tick = core.tick(t_ms * MS)
    moving = tick.states["thumb_rotation"]
    assert moving.velocity_rpm == pytest.approx(30.0, rel=1e-3) and tick.result is None
    thawed = core.tick(2100 * MS)  # the next tick 2 s later: the lease ended at 300 ms
    at_thaw = thawed.states["thumb_rotation"]
    assert thawed.result is not None and thawed.result.reason == "timeout"
    assert at_thaw.velocity_rpm == 0.0
    # 30 rpm = 3.14 rad/s: only the lag's 3.14 x 0.01 s = 0.031 rad beyond the last sample, not 6.3 rad
    assert at_thaw.position_rad - moving.position_rad == pytest.approx(0.0314, abs=1e-3)
    after = [core.tick(t_ms * MS).states["thumb_rotation"] for t_ms in range(2110, 2200, 10)]
    assert [(s.position_rad, s.velocity_rpm) for s in after] == [(at_thaw.position_rad, 0.0)] * len(after)


def test_move_goals_are_refused_not_ready_while_the_homing_at_start_is_due_or_runs():
    """`home:=true`: from the moment the bus is open until the homing has ended a goal is refused
    not_ready naming the motors (send it again), never not_homed (which asks the client to home)."""
    core = MotorDriverCore(MotorDriverConfig(home_at_start=True))  # the sim motors: homed at the first tick
    assert core.connect(0) is None
    goal = MoveGoal(["fingers"], "velocity", [10.0], timeout_s=0.3)
    assert str(core.validate(goal, 0)) == ("not_ready: homing (fingers, thumb_flexion, thumb_rotation): send it "
                                           "again when the homing has ended")
    tick = core.tick(10 * MS)
    assert tick.homing_result is not None and tick.homing_result.success
    assert core.validate(goal, 10 * MS) is None
