"""The servo emulator's e-Manual rules, on the wire through dynamixel-sdk's PacketHandler (no driver):
Bus Watchdog (fires at the exact instant, -1, goal writes refused with Data Range, cleared by 0, no
motion until a new goal, fed by sync reads), power-up / power cycle (RAM defaults, EEPROM kept,
Present Position within one turn + Homing Offset while the mechanical position stays), Current Limit
(caps Present Current, Goal Current beyond it refused with Data Limit), current-based position mode
against an end stop (velocity 0, stall current = Goal Current, peak kept, logged), Moving, LED and the
Baud Rate (a servo at another rate does not answer). Manual clock: every number is exact.
"""
from __future__ import annotations

import math
import time

import dynamixel_sdk as sdk
import pytest

from prisma_motor_driver import control_table as ct
from prisma_motor_driver.dynamixel_emulator import DynamixelEmulator, ManualClock
from prisma_motor_driver.dynamixel_packets import ERR_ACCESS, ERR_DATA_LIMIT, ERR_DATA_RANGE

TICKS_PER_S_AT_30_RPM = ct.rpm_to_units(30.0) * ct.RPM_PER_VELOCITY_UNIT / 60.0 * ct.TICKS_PER_REV


@pytest.fixture
def wire(monkeypatch):
    """(emu, port, ph, clock): the emulator with IDs 1 and 2 and the SDK's port opened at 1 Mbps."""
    import dynamixel_sdk.port_handler

    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 200)  # see test_dynamixel_backend
    clock = ManualClock(10.0)
    lines: list[str] = []
    with DynamixelEmulator([1, 2], clock=clock, log=lines.append) as emu:
        port = sdk.PortHandler(emu.port_name)
        assert port.openPort() and port.setBaudRate(1_000_000)
        yield emu, port, sdk.PacketHandler(2.0), clock, lines
        port.closePort()


def ok(result) -> None:
    """A TxRx answer (comm, error) or (value, comm, error) that succeeded."""
    assert result[-2:] == (sdk.COMM_SUCCESS, 0), result


def velocity_with_watchdog(emu, port, ph, units: int = 5) -> None:
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, units))
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_VELOCITY, ct.rpm_to_units(30.0)))


# ---- Bus Watchdog -----------------------------------------------------------------------------
def test_watchdog_stops_velocity_mode_at_the_exact_instant_and_locks_the_goals(wire):
    emu, port, ph, clock, lines = wire
    velocity_with_watchdog(emu, port, ph)  # 5 units = 100 ms; the goal write at t = 10.0 s fed it last
    clock.advance(0.5)
    emu.update()
    [firing] = emu.watchdog_firings
    assert firing.servo_id == 1 and firing.at_s == pytest.approx(10.1)
    expected = 0.100 * TICKS_PER_S_AT_30_RPM  # 30 rpm (131 units) for 100 ms, not 500 ms
    assert firing.position_ticks == pytest.approx(expected) and emu.servos[1].position_ticks == pytest.approx(expected)
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG)[0] == 0xFF  # -1
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_VELOCITY)[0] == 0
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_MOVING)[0] == 0
    assert emu.servos[1].torque_on  # stopped, not limp
    assert any("bus watchdog fired at t=10.100 s" in line for line in lines)
    # every goal register is read-only now: Data Range error, nothing written
    for address, size in ct.GOAL_REGISTERS:
        write = {2: ph.write2ByteTxRx, 4: ph.write4ByteTxRx}[size]
        assert write(port, 1, address, 7) == (sdk.COMM_SUCCESS, ERR_DATA_RANGE), address
    assert emu.servos[1].read_int(ct.ADDR_GOAL_VELOCITY, 4) == ct.rpm_to_units(30.0)
    assert ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 5) == (sdk.COMM_SUCCESS, ERR_DATA_RANGE)  # clear first
    # cleared with 0; it does not resume the old goal by itself
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 0))
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG)[0] == 0
    clock.advance(1.0)
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)[0] == round(expected)
    # a new Goal Velocity moves it again
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_VELOCITY, ct.rpm_to_units(30.0)))
    clock.advance(0.2)
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)[0] == round(expected + 0.2 * TICKS_PER_S_AT_30_RPM)
    assert len(emu.watchdog_firings) == 1  # 0 switched it off


def test_watchdog_is_fed_by_a_sync_read_that_names_the_servo_and_not_by_one_that_does_not(wire):
    emu, port, ph, clock, _ = wire
    velocity_with_watchdog(emu, port, ph)
    ok(ph.write1ByteTxRx(port, 2, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write1ByteTxRx(port, 2, ct.ADDR_BUS_WATCHDOG, 5))
    reader = sdk.GroupSyncRead(port, ph, ct.STATE_START, ct.STATE_LENGTH)
    reader.addParam(1)  # only servo 1
    for _ in range(50):  # 1 s of 20 ms cycles
        clock.advance(0.02)
        assert reader.txRxPacket() == sdk.COMM_SUCCESS
    assert [f.servo_id for f in emu.watchdog_firings] == [2]
    assert emu.watchdog_firings[0].at_s == pytest.approx(10.1)  # 100 ms after its own last packet
    assert emu.servos[1].position_ticks == pytest.approx(1.0 * TICKS_PER_S_AT_30_RPM)  # never stopped


def test_watchdog_holds_a_position_mode_where_it_fired_and_needs_torque_on(wire):
    emu, port, ph, clock, _ = wire
    ok(ph.write1ByteTxRx(port, 2, ct.ADDR_BUS_WATCHDOG, 10))  # armed, torque off: it does not watch
    clock.advance(1.0)
    emu.update()
    assert emu.watchdog_firings == []
    ok(ph.write1ByteTxRx(port, 2, ct.ADDR_OPERATING_MODE, ct.MODE_EXTENDED_POSITION))
    ok(ph.write4ByteTxRx(port, 2, ct.ADDR_PROFILE_VELOCITY, ct.rpm_to_units(30.0)))
    ok(ph.write1ByteTxRx(port, 2, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write4ByteTxRx(port, 2, ct.ADDR_GOAL_POSITION, 8192))  # 2 turns; last packet at t = 11.0
    clock.advance(3.0)
    emu.update()
    [firing] = emu.watchdog_firings
    assert firing.at_s == pytest.approx(11.2)
    assert emu.servos[2].position_ticks == pytest.approx(0.2 * TICKS_PER_S_AT_30_RPM)


def test_a_broadcast_ping_is_answered_by_every_servo_and_feeds_their_watchdogs(wire):
    emu, port, ph, clock, _ = wire
    velocity_with_watchdog(emu, port, ph)
    clock.advance(0.09)
    found, result = ph.broadcastPing(port)
    assert result == sdk.COMM_SUCCESS and sorted(found) == [1, 2]
    clock.advance(0.09)  # 180 ms after the goal, 90 ms after the ping
    emu.update()
    assert emu.watchdog_firings == []


def test_out_of_range_watchdog_values_are_refused(wire):
    emu, port, ph, _, _ = wire
    assert ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 128) == (sdk.COMM_SUCCESS, ERR_DATA_RANGE)
    assert ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 0xFF) == (sdk.COMM_SUCCESS, ERR_DATA_RANGE)
    assert emu.servos[1].bus_watchdog == 0


def test_an_emulator_held_up_with_a_packet_waiting_judges_the_watchdog_by_that_packet(monkeypatch):
    """On real time: the emulator's thread kept from reading (its lock held, as a busy process would
    keep it) while the host's Goal Velocity write waits in the pty, past the watchdog's deadline. A
    servo hears a packet as it comes, so this one was fed in time and keeps turning; with no packet
    written it fires at its deadline as before."""
    import dynamixel_sdk.port_handler

    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 200)
    period_s = 10 * ct.WATCHDOG_UNIT_S  # 200 ms: a slow test thread still writes long before it
    lines: list[str] = []
    with DynamixelEmulator([1], log=lines.append) as emu:
        port = sdk.PortHandler(emu.port_name)
        assert port.openPort() and port.setBaudRate(1_000_000)
        ph = sdk.PacketHandler(2.0)
        ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
        ok(ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 10))
        for fed in (True, False):
            ok(ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_VELOCITY, ct.rpm_to_units(30.0)))
            with emu._lock:  # the emulator held up
                time.sleep(0.02)
                if fed:
                    sent = ph.write4ByteTxOnly(port, 1, ct.ADDR_GOAL_VELOCITY, ct.rpm_to_units(30.0))
                    assert sent == sdk.COMM_SUCCESS
                time.sleep(2 * period_s)
            emu.sync()
            emu.update()
            if fed:
                assert emu.watchdog_firings == [], lines
                assert emu.present()[1].velocity_rpm == pytest.approx(30.0, rel=0.01)
                assert any("passed while instructions waited unread" in line for line in lines), lines
            else:
                [firing] = emu.watchdog_firings
                assert emu.present()[1].velocity_rpm == 0.0
        port.closePort()


# ---- power-up ---------------------------------------------------------------------------------
def test_power_cycle_resets_ram_keeps_eeprom_and_loses_the_turn_count(wire):
    emu, port, ph, clock, _ = wire
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_HOMING_OFFSET, 100))
    ok(ph.write2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT, 500))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_OPERATING_MODE, ct.MODE_EXTENDED_POSITION))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_LED, 1))
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_PROFILE_VELOCITY, 50))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 20))
    emu.inject_hardware_error(1, 5)
    mechanical = ct.rad_to_ticks(7.0)  # 4563: past one turn
    emu.place(1, mechanical)
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)[0] == mechanical + 100  # powered: it counted
    emu.power_cycle(1)
    servo = emu.servos[1]
    assert servo.mechanical_ticks == mechanical  # the spool did not move
    present, comm, error = ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)
    assert (present, comm, error) == (mechanical - 4096 + 100, sdk.COMM_SUCCESS, 0)  # within one turn + offset
    assert 100 <= present <= 4095 + 100
    for address, value in ((ct.ADDR_TORQUE_ENABLE, 0), (ct.ADDR_LED, 0), (ct.ADDR_BUS_WATCHDOG, 0),
                           (ct.ADDR_HARDWARE_ERROR_STATUS, 0)):
        assert ph.read1ByteTxRx(port, 1, address)[0] == value, address
    assert servo.read_int(ct.ADDR_PROFILE_VELOCITY, 4) == 0
    assert all(servo.read_int(a, n) == 0 for a, n in ct.GOAL_REGISTERS)
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_HOMING_OFFSET)[0] == 100
    assert ph.read2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT)[0] == 500
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_OPERATING_MODE)[0] == ct.MODE_EXTENDED_POSITION
    assert emu.servos[2].torque_on is False and emu.servos[2].position_ticks == 0  # the other one untouched
    # goal positions are in reported coordinates: 3 turns down mechanically is -4096*3 + offset reported
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_POSITION, present - 100))
    clock.advance(30.0)
    emu.update()
    assert servo.mechanical_ticks == mechanical - 100
    # a negative mechanical position also comes up within one turn
    emu.place(2, -1000)
    emu.power_cycle(2)
    assert ph.read4ByteTxRx(port, 2, ct.ADDR_PRESENT_POSITION)[0] == 4096 - 1000


def test_reboot_instruction_is_a_power_up(wire):
    emu, port, ph, _, _ = wire
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_LED, 1))
    emu.place(1, 5000)
    ok(ph.reboot(port, 1))
    assert emu.servos[1].table[ct.ADDR_LED] == 0 and emu.servos[1].position_ticks == 5000 - 4096


def test_eeprom_is_locked_with_torque_on_and_model_and_firmware_are_read_only(wire):
    emu, port, ph, _, _ = wire
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_FIRMWARE_VERSION)[0] == 46
    assert ph.write1ByteTxRx(port, 1, ct.ADDR_FIRMWARE_VERSION, 50) == (sdk.COMM_SUCCESS, ERR_ACCESS)
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    assert ph.write2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT, 100) == (sdk.COMM_SUCCESS, ERR_ACCESS)


# ---- current ----------------------------------------------------------------------------------
def test_current_limit_caps_present_current_and_refuses_goal_current_beyond_it(wire):
    emu, port, ph, _, _ = wire
    assert ph.read2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT)[0] == ct.CURRENT_LIMIT_MAX_UNITS
    assert ph.write2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT, ct.CURRENT_LIMIT_MAX_UNITS + 1) == (
        sdk.COMM_SUCCESS, ERR_DATA_RANGE)
    ok(ph.write2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT, 300))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    emu.set_load(1, 1000)
    current = ph.read2ByteTxRx(port, 1, ct.ADDR_PRESENT_CURRENT)[0]
    assert current == 300 and emu.present()[1].peak_current_units == 300
    emu.set_load(1, -1000)
    assert ct.to_signed(ph.read2ByteTxRx(port, 1, ct.ADDR_PRESENT_CURRENT)[0], 2) == -300
    assert ph.write2ByteTxRx(port, 1, ct.ADDR_GOAL_CURRENT, 301) == (sdk.COMM_SUCCESS, ERR_DATA_LIMIT)
    assert ph.write2ByteTxRx(port, 1, ct.ADDR_GOAL_CURRENT, ct.to_unsigned(-301, 2)) == (
        sdk.COMM_SUCCESS, ERR_DATA_LIMIT)
    ok(ph.write2ByteTxRx(port, 1, ct.ADDR_GOAL_CURRENT, 300))
    assert ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_VELOCITY, ct.VELOCITY_LIMIT_MAX + 1) == (
        sdk.COMM_SUCCESS, ERR_DATA_LIMIT)


def test_current_based_position_stalls_at_an_end_stop_with_the_goal_current(wire):
    emu, port, ph, clock, lines = wire
    emu.set_end_stops(1, -50.0, 2000.0)
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_OPERATING_MODE, ct.MODE_CURRENT_BASED_POSITION))
    ok(ph.write2ByteTxRx(port, 1, ct.ADDR_CURRENT_LIMIT, 600))
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_PROFILE_VELOCITY, ct.rpm_to_units(30.0)))
    ok(ph.write2ByteTxRx(port, 1, ct.ADDR_GOAL_CURRENT, 150))  # 403.5 mA
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_POSITION, 3 * 4096))  # beyond the stop at 2000
    clock.advance(0.2)
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_MOVING)[0] == 1
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)[0] == round(0.2 * TICKS_PER_S_AT_30_RPM)
    clock.advance(5.0)
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)[0] == 2000
    assert ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_VELOCITY)[0] == 0
    assert ph.read1ByteTxRx(port, 1, ct.ADDR_MOVING)[0] == 0
    assert ph.read2ByteTxRx(port, 1, ct.ADDR_PRESENT_CURRENT)[0] == 150
    servo = emu.servos[1]
    assert servo.peak_current_units == 150
    # reached at the stop: 2000 ticks at 30 rpm (131 units) from t = 10.0
    assert servo.peak_current_at_s == pytest.approx(10.2 + 5.0)  # seen at the first look after it
    assert [line for line in lines if "stalled" in line] == [
        "servo 1: stalled at its hi end stop (mechanical 2000 ticks) at t=15.200 s, pulling 404 mA "
        "(current_based_position mode)"]
    # velocity mode pushing into the low stop pulls the Current Limit
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 0))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_OPERATING_MODE, ct.MODE_VELOCITY))
    ok(ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1))
    ok(ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_VELOCITY, ct.to_unsigned(-ct.rpm_to_units(60.0), 4)))
    clock.advance(2.0)
    assert ct.to_signed(ph.read4ByteTxRx(port, 1, ct.ADDR_PRESENT_POSITION)[0], 4) == -50
    assert ct.to_signed(ph.read2ByteTxRx(port, 1, ct.ADDR_PRESENT_CURRENT)[0], 2) == -600
    assert servo.peak_current_units == 600 and math.isclose(servo.mechanical_ticks, -50.0)


# ---- LED and baud -----------------------------------------------------------------------------
def test_led_is_plain_ram(wire):
    emu, port, ph, _, _ = wire
    ok(ph.write1ByteTxRx(port, 2, ct.ADDR_LED, 1))
    assert ph.read1ByteTxRx(port, 2, ct.ADDR_LED)[0] == 1 and emu.present()[2].led == 1


def test_a_servo_at_another_baud_rate_does_not_answer(wire):
    emu, port, ph, _, _ = wire
    assert emu.host_baud() == 1_000_000
    emu.set_baud(2, 57_600)
    assert ph.ping(port, 2)[1] == sdk.COMM_RX_TIMEOUT
    assert ph.ping(port, 1)[:2] == (ct.MODEL_XM430_W350, sdk.COMM_SUCCESS)
    assert emu.stats.wrong_baud >= 1
    assert port.setBaudRate(57_600) and emu.host_baud() == 57_600
    assert ph.ping(port, 2)[1] == sdk.COMM_SUCCESS and ph.ping(port, 1)[1] == sdk.COMM_RX_TIMEOUT
    port.ser.baudrate = 4_500_000  # pyserial sets a rate Linux has no B constant for through BOTHER
    assert emu.host_baud() == 4_500_000
    with pytest.raises(ValueError, match="baud rate 12345"):
        emu.set_baud(1, 12345)
