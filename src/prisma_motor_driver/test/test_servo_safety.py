"""The motor driver made safe against servos as strict as the X-series e-Manual (the emulator): the
Bus Watchdog armed at open and re-armed after it fired, the Current Limit written, a servo that
powered up again taken out of service until homed, and homing after a power-up with the fingers
closed past one turn. The driver's core runs its real DynamixelBus (dynamixel-sdk) on the emulated
servos; the emulator's manual clock makes every instant exact."""
from __future__ import annotations

import math

import pytest

from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import BusError, MotorMap
from prisma_motor_driver.dynamixel_backend import DynamixelBus
from prisma_motor_driver.dynamixel_emulator import DynamixelEmulator, ManualClock
from prisma_motor_driver.homing_job import HOMING_AT_START_TRIES
from prisma_motor_driver.motor_driver_core import MotorDriverCore, TickResult
from prisma_motor_driver.motor_goals import MoveGoal
from prisma_motor_driver.node_config import MotorDriverConfig

IDS = {"fingers": 1, "thumb_flexion": 2, "thumb_rotation": 3}
MIN_RAD, MAX_RAD = [0.0, 0.0, -3.0], [9.0, 7.0, 3.0]
TICK_S = 0.01


def motor_map():
    return MotorMap.from_lists(list(IDS), list(IDS.values()), MIN_RAD, MAX_RAD, [70.0, 70.0, 70.0]).motors


@pytest.fixture
def hand(monkeypatch):
    """The emulated servos with the hand's mechanical end stops (open end = the minimum position,
    the far end 0.2 rad past the maximum), the driver's core on them."""
    import dynamixel_sdk.port_handler

    # see test_dynamixel_backend.rig: a loaded machine must not turn a late status into a drop
    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 200)
    clock = ManualClock()
    with DynamixelEmulator(list(IDS.values()), clock=clock) as emu:
        for servo_id, lo, hi in zip(IDS.values(), MIN_RAD, MAX_RAD):
            emu.set_end_stops(servo_id, ct.rad_to_ticks(lo), ct.rad_to_ticks(hi + 0.2))
        yield emu, clock


def make_core(emu, zeros=None) -> MotorDriverCore:
    bus = DynamixelBus(emu.port_name, 1_000_000, motor_map(), retries=1)
    core = MotorDriverCore(MotorDriverConfig(backend="dynamixel"), bus=bus, zeros=zeros)
    assert core.connect(0) is None
    emu.sync()  # the sync write that arms the watchdogs has no status packet to wait for
    return core


def light_leds(emu) -> None:
    """The servos as a homing in this power-up left them (LED on): with the zeros saved, homed."""
    for servo in emu.servos.values():
        servo.write_int(ct.ADDR_LED, 1, 1)


def run(core, emu, clock, seconds: float, until=None) -> list[TickResult]:
    """Tick the driver every 10 ms for `seconds` (or until `until(tick)` holds)."""
    ticks = []
    for _ in range(round(seconds / TICK_S)):
        emu.sync()  # every byte the driver sent is taken before time moves
        clock.advance(TICK_S)
        tick = core.tick(round(clock.now_s * 1e9))
        ticks.append(tick)
        if until is not None and until(tick):
            break
    return ticks


def close_fingers(rpm: float = 30.0) -> MoveGoal:
    return MoveGoal(["fingers"], "velocity", [rpm])


def test_open_arms_every_watchdog_and_writes_the_current_limit(hand):
    emu, clock = hand
    core = make_core(emu)
    for servo in emu.servos.values():
        assert servo.bus_watchdog == 5  # 0.1 s in 20 ms units
        assert servo.current_limit_units == 446  # 1200 mA / 2.69 mA, rounded down
        assert servo.torque_on
    info = core.bus.servo_info["fingers"]
    assert (info.model, info.firmware, info.watchdog_ms, info.operating_mode) == (1020, 46, 100.0, "velocity")
    assert info.current_limit_ma == pytest.approx(446 * 2.69)


def test_a_driver_that_falls_silent_is_stopped_by_the_servos_and_nothing_moves_until_a_new_goal(hand):
    emu, clock = hand
    light_leds(emu)
    core = make_core(emu, zeros={name: 0 for name in IDS})
    assert core.validate(close_fingers()) is None
    core.start(close_fingers(30.0), round(clock.now_s * 1e9))
    run(core, emu, clock, 0.2)
    last_packet_s = clock.now_s  # the last tick's sync reads: then the driver freezes (SIGSTOP, or killed)
    moving = emu.present()[1].mechanical_ticks
    clock.advance(1.0)
    present = emu.present()[1]
    assert present.velocity_rpm == 0.0 and present.bus_watchdog == ct.WATCHDOG_FIRED
    # every servo stopped itself 0.1 s after the last packet (the sync read of the last tick)
    assert sorted(f.servo_id for f in emu.watchdog_firings) == [1, 2, 3]
    assert [f.at_s for f in emu.watchdog_firings] == pytest.approx([last_packet_s + 0.1] * 3, abs=1e-9)
    # 30 rpm for 0.1 s after the last packet: 0.314 rad, not the 3.1 rad of the whole second
    assert ct.ticks_to_rad(present.mechanical_ticks - moving) == pytest.approx(math.pi * 0.1, abs=0.01)
    # the driver wakes (SIGCONT): it sees the fired watchdog, ends the goal, clears and re-arms it
    heard = emu.stats.instructions
    tick = core.tick(round(clock.now_s * 1e9))
    emu.sync()
    # in one sync read and sync writes, a packet each for every servo at once: a round trip per servo
    # and register gave the other servos' watchdogs time to fire on a slow bus
    assert emu.stats.instructions - heard == 5
    assert tick.result is not None and not tick.result.success
    assert tick.result.reason == (
        "motor_fault: fingers (id 1), thumb_flexion (id 2), thumb_rotation (id 3) stopped by their bus watchdogs: no "
        "instruction for more than 100 ms (the driver or the bus was held up); re-armed, still until the next goal")
    assert [s.bus_watchdog for s in emu.servos.values()] == [5, 5, 5]
    stopped_at = emu.present()[1].mechanical_ticks
    run(core, emu, clock, 0.5)
    assert emu.present()[1].mechanical_ticks == stopped_at  # no servo moves until a new goal
    assert core.validate(close_fingers()) is None
    core.start(close_fingers(30.0), round(clock.now_s * 1e9))
    run(core, emu, clock, 0.1)
    assert emu.present()[1].mechanical_ticks > stopped_at


def slow_round_trips(emu, clock, seconds: float) -> None:
    """Each instruction answered by a status packet costs the host `seconds` before it sends the next
    (a U2D2's FTDI adapter at its default 16 ms latency timer): the servos' clock runs on meanwhile."""
    handle = emu._handle

    def answered_late(packet):
        reply = handle(packet)
        if reply:
            clock.advance(seconds)
        return reply

    emu._handle = answered_late


def test_a_goal_that_changes_every_servos_mode_starts_without_starving_a_watchdog(hand):
    """Velocity to position mode on all three servos (torque off, Operating Mode, Goal Position from
    where each stands, torque on) at 16 ms a round trip: a round trip per servo and register left the
    last servo unaddressed for 10 of them (160 ms), past its 100 ms watchdog, and the goal's first
    write to it was refused. Sync writes and one sync read reach every servo within one round trip."""
    emu, clock = hand
    light_leds(emu)
    core = make_core(emu, zeros={name: 0 for name in IDS})
    run(core, emu, clock, 0.05)
    slow_round_trips(emu, clock, 0.016)
    before = clock.now_s
    goal = MoveGoal(list(IDS), "position", [1.0, 1.0, 0.5])
    assert core.validate(goal) is None
    outcome = core.start(goal, round(clock.now_s * 1e9))
    emu.sync()
    assert outcome.failed is None and emu.watchdog_firings == []
    assert clock.now_s - before <= 0.032 + 1e-9  # the sync reads' round trips, no more
    assert [s.table[ct.ADDR_OPERATING_MODE] for s in emu.servos.values()] == [ct.MODE_EXTENDED_POSITION] * 3
    assert all(s.torque_on for s in emu.servos.values())
    ticks = run(core, emu, clock, 3.0, until=lambda tick: tick.result is not None)
    assert ticks[-1].result is not None and ticks[-1].result.success, ticks[-1].result
    assert emu.watchdog_firings == []
    states = core.bus.read_state()
    assert [states[n].position_rad for n in IDS] == pytest.approx([1.0, 1.0, 0.5], abs=0.02)


def test_a_servo_that_powers_up_mid_goal_ends_the_goal_and_is_no_longer_homed(hand):
    emu, clock = hand
    light_leds(emu)
    core = make_core(emu, zeros={name: 0 for name in IDS})
    core.start(close_fingers(), round(clock.now_s * 1e9))
    run(core, emu, clock, 0.1)
    emu.power_cycle(1)
    tick = run(core, emu, clock, 0.01)[-1]
    assert tick.result is not None and tick.result.reason.startswith(
        "motor_fault: fingers (id 1) powered up again")
    assert emu.servos[1].bus_watchdog == 5 and emu.servos[1].torque_on  # made safe again, as at open
    refusal = core.validate(close_fingers())
    assert refusal is not None and refusal.code == "not_homed" and "fingers (id 1)" in refusal.why
    assert core.validate(MoveGoal(["thumb_flexion"], "velocity", [10.0])) is None  # the others still homed


def test_homing_after_a_power_cycle_with_the_fingers_closed_past_one_turn(hand):
    emu, clock = hand
    # the hand switched off with the fingers closed 7 rad (more than a turn), switched on again
    emu.place(1, ct.rad_to_ticks(7.0))
    emu.power_cycle()
    assert 0 <= emu.present()[1].position_ticks < ct.TICKS_PER_REV  # the turn count is lost
    core = make_core(emu, zeros={name: 0 for name in IDS})  # the zeros of before the power cycle
    assert core.bus.homed == {"fingers": False, "thumb_flexion": False, "thumb_rotation": False}
    # believing the old zero, it would read 7 rad as 0.72 rad and close another 8.3 rad into the stop
    assert core.tick(0).states["fingers"].position_rad == pytest.approx(7.0 - 2 * math.pi, abs=1e-3)
    refusal = core.validate(close_fingers())
    assert refusal is not None and str(refusal).startswith("not_homed: fingers (id 1) not homed since the servo")
    assert core.validate_homing([]) is None
    preempted, done = core.start_homing([], round(clock.now_s * 1e9))
    assert preempted is None and done is None
    ticks = run(core, emu, clock, 15.0, until=lambda t: t.homing_result is not None)
    result = ticks[-1].homing_result
    assert result is not None and result.success, result
    assert result.reason == "homed" and result.motors == list(IDS)
    # 7 rad from the fingers' open stop at 15 rpm: 4.7 s; then the thumb back from its -3 rad end to
    # 0 at the position goals' 30 rpm: 1 s more; the thumb's flexion was at its stop already
    assert result.travel_rad == pytest.approx([7.0, 0.0, 3.0], abs=0.02)
    assert clock.now_s == pytest.approx(7.0 / (15 * 2 * math.pi / 60) + 3.0 / math.pi, abs=0.3)
    # the driver's zero at the open stop: the open hand reads 0 rad, the thumb centred
    states = run(core, emu, clock, 0.05)[-1].states
    assert [s.position_rad for s in states.values()] == pytest.approx([0.0, 0.0, 0.0], abs=0.05)
    assert ct.ticks_to_rad(emu.present()[1].mechanical_ticks) == pytest.approx(0.0, abs=0.05)
    assert ct.ticks_to_rad(emu.present()[3].mechanical_ticks) == pytest.approx(0.0, abs=0.05)
    assert result.zero_ticks[0] == round(emu.present()[1].position_ticks)
    assert core.known_zeros["fingers"] == result.zero_ticks[0]
    # the tendon never pulled harder than the homing current (150 mA = 55 units), far below the limit
    assert emu.servos[1].peak_current_units <= ct.ma_to_current_units(150.0) < emu.servos[1].current_limit_units
    assert all(led for led in (s.read_int(ct.ADDR_LED, 1) for s in emu.servos.values()))
    # homed: the close goal runs, and stops at the 9 rad limit, short of the end stop at 9.2 rad
    assert core.validate(close_fingers(60.0)) is None
    core.start(close_fingers(60.0), round(clock.now_s * 1e9))
    ticks = run(core, emu, clock, 12.0, until=lambda t: t.result is not None)
    assert ticks[-1].result is not None and ticks[-1].result.reason == "joint_limit"
    assert ct.ticks_to_rad(emu.present()[1].mechanical_ticks) == pytest.approx(9.0, abs=0.1)


def test_homing_travel_counts_from_where_the_motors_stood_when_it_was_sent(hand):
    """The driver's first tick after the homing command may come late (a busy computer): the travel
    it reports is still from where the fingers stood, not from where that tick found them."""
    emu, clock = hand
    emu.place(1, ct.rad_to_ticks(7.0))
    emu.power_cycle()
    core = make_core(emu, zeros={name: 0 for name in IDS})
    run(core, emu, clock, 0.01)
    core.start_homing([], round(clock.now_s * 1e9))
    emu.sync()
    clock.advance(0.08)  # below the 100 ms Bus Watchdog: the fingers turn 0.13 rad toward the stop meanwhile
    ticks = run(core, emu, clock, 15.0, until=lambda t: t.homing_result is not None)
    result = ticks[-1].homing_result
    assert result is not None and result.success, result
    assert result.travel_rad == pytest.approx([7.0, 0.0, 3.0], abs=0.02)


def test_homing_with_no_end_stop_fails_naming_the_motor_and_leaves_it_stopped(hand):
    emu, clock = hand
    emu.set_end_stops(2, None, None)  # the thumb's flexion tendon off its spool: nothing stops it
    core = make_core(emu)
    core.start_homing(["thumb_flexion"], 0)
    ticks = run(core, emu, clock, 20.0, until=lambda t: t.homing_result is not None)
    result = ticks[-1].homing_result
    assert result is not None and not result.success
    assert result.reason.startswith("homing_failed: thumb_flexion: turned ")
    assert "without meeting its end stop" in result.reason
    # the whole range (7 rad) + a lost turn + 0.5 rad, at 15 rpm
    assert clock.now_s == pytest.approx((7.0 + 2 * math.pi + 0.5) / (15 * 2 * math.pi / 60), abs=0.3)
    stopped_at = emu.present()[2].mechanical_ticks
    run(core, emu, clock, 0.3)
    assert emu.present()[2].mechanical_ticks == stopped_at
    assert core.validate(MoveGoal(["thumb_flexion"], "velocity", [10.0])).code == "not_homed"


def test_a_homing_at_start_that_the_watchdog_interrupted_goes_again(hand):
    emu, clock = hand
    emu.place(1, ct.rad_to_ticks(2.0))
    emu.power_cycle()
    bus = DynamixelBus(emu.port_name, 1_000_000, motor_map(), retries=1)
    core = MotorDriverCore(MotorDriverConfig(backend="dynamixel", home_at_start=True), bus=bus)
    assert core.connect(0) is None
    homing = "not_ready: homing (fingers, thumb_flexion, thumb_rotation): send it again when the homing has ended"
    assert str(core.validate(close_fingers())) == homing  # due: the bus is open, the first tick starts it
    run(core, emu, clock, 0.5)  # homing: the fingers on their way to the open stop
    assert core.homing.run is not None
    assert str(core.validate(close_fingers())) == homing  # never not_homed: the driver is homing already
    clock.advance(0.5)  # the driver held up past its watchdog mid-homing
    tick = core.tick(round(clock.now_s * 1e9))
    assert tick.homing_result is not None and not tick.homing_result.success
    assert "stopped by their bus watchdogs" in tick.homing_result.reason
    assert str(core.validate(close_fingers())) == homing  # interrupted: it goes again on the next tick
    # the servos still homing went back to velocity mode, none left pulling in current-based position
    assert {s.read_int(ct.ADDR_OPERATING_MODE, 1) for s in emu.servos.values()} == {ct.MODE_VELOCITY}
    ticks = run(core, emu, clock, 15.0, until=lambda t: t.homing_result is not None)
    assert ticks[-1].homing_result is not None and ticks[-1].homing_result.success
    assert core.unhomed() == [] and core.validate(close_fingers()) is None
    assert ct.ticks_to_rad(emu.present()[1].mechanical_ticks) == pytest.approx(0.0, abs=0.05)


class StartsThatFail:
    """bus.start_homing failing its first `count` calls as a servo refusing a write does."""

    def __init__(self, bus: DynamixelBus, count: int) -> None:
        self.start_homing, self.count, self.calls = bus.start_homing, count, 0

    def __call__(self, names: list[str], rpm: float, current_ma: float) -> None:
        self.calls += 1
        if self.calls <= self.count:
            raise BusError("write 0 to address 65 of thumb_rotation (id 3): [RxPacketError] Data range error!")
        self.start_homing(names, rpm, current_ma)


def homing_at_start(hand, monkeypatch, failing_starts: int) -> tuple[MotorDriverCore, StartsThatFail]:
    """A driver that homes at start on the power-cycled emulated hand, its bus's first
    `failing_starts` homing starts refused."""
    emu, _clock = hand
    emu.power_cycle()
    bus = DynamixelBus(emu.port_name, 1_000_000, motor_map(), retries=1)
    core = MotorDriverCore(MotorDriverConfig(backend="dynamixel", home_at_start=True), bus=bus)
    assert core.connect(0) is None
    starts = StartsThatFail(bus, failing_starts)
    monkeypatch.setattr(bus, "start_homing", starts)
    return core, starts


def test_a_homing_at_start_whose_start_the_bus_failed_goes_again_a_bounded_number_of_times(hand, monkeypatch):
    emu, clock = hand
    core, starts = homing_at_start(hand, monkeypatch, failing_starts=100)
    results = [t.homing_result for t in run(core, emu, clock, 0.5) if t.homing_result is not None]
    # every try failed at its start; the tries stop after HOMING_AT_START_TRIES, nothing moved
    assert starts.calls == len(results) == HOMING_AT_START_TRIES
    assert all(r.reason.startswith("homing_failed: write 0 to address 65") for r in results)
    assert not core.homing.wanted and core.homing.run is None
    assert {s.read_int(ct.ADDR_OPERATING_MODE, 1) for s in emu.servos.values()} == {ct.MODE_VELOCITY}


def test_a_homing_at_start_whose_first_start_failed_homes_at_the_second(hand, monkeypatch):
    emu, clock = hand
    core, starts = homing_at_start(hand, monkeypatch, failing_starts=1)
    ticks = run(core, emu, clock, 15.0, until=lambda t: t.homing_result is not None and t.homing_result.success)
    assert starts.calls == 2
    assert ticks[-1].homing_result is not None and ticks[-1].homing_result.success
    assert core.unhomed() == []
