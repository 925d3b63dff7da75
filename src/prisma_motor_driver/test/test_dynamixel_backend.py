"""Dynamixel Protocol 2.0: packet codec, the pty servo emulator, and the DynamixelBus (real
dynamixel-sdk PortHandler/PacketHandler/GroupSyncRead/GroupSyncWrite code paths) against it.

The pty: pyserial sets the requested baud on the slave side with termios; Linux ptys accept every
standard rate the SDK allows, so PortHandler.openPort/setBaudRate run unpatched here.
"""
from __future__ import annotations

import math

import dynamixel_sdk as sdk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import BusError, MotorMap
from prisma_motor_driver.dynamixel_backend import DynamixelBus
from prisma_motor_driver.dynamixel_emulator import DynamixelEmulator, ManualClock
from prisma_motor_driver.dynamixel_packets import (
    INST_PING,
    INST_WRITE,
    PacketDecoder,
    crc16,
    encode,
    encode_status,
    stuff,
    unstuff,
)
from prisma_motor_driver.motor_driver_core import MotorDriverCore
from prisma_motor_driver.motor_goals import MoveGoal, MoveGoalRunner
from prisma_motor_driver.node_config import MotorDriverConfig

IDS = {"fingers": 1, "thumb_flexion": 2, "thumb_rotation": 3}


def motor_map():
    return MotorMap.from_lists(list(IDS), list(IDS.values()), [0.0, 0.0, -2.0], [9.0, 7.0, 2.0],
                               [100.0, 100.0, 100.0]).motors


@pytest.fixture
def rig(monkeypatch):
    # The emulated servos answer from a thread of this process: on a loaded machine the process can
    # be off the CPU longer than dynamixel-sdk's status timeout (2 x its 16 ms latency timer + 2 ms),
    # and a status packet the emulator sent on time would count as dropped. These tests count the
    # drops the emulator makes; a 200 ms latency timer keeps the scheduler's out of the count.
    import dynamixel_sdk.port_handler

    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 200)
    clock = ManualClock()
    with DynamixelEmulator(list(IDS.values()), clock=clock) as emu:
        # the manual clock jumps past the driver's 0.1 s bus watchdog between reads: these tests are about
        # motion, so the servos get the longest watchdog (the watchdog's own tests arm the default)
        bus = DynamixelBus(emu.port_name, 1_000_000, motor_map(), retries=2, watchdog_s=2.54)
        bus.open()
        yield emu, bus, clock
        bus.close()


# ---- codec ------------------------------------------------------------------------------------
def test_crc_and_packets_match_the_protocol_spec_examples():
    # e-manual Protocol 2.0: ping ID 1, and the status packet of an XM430 (model 1030, fw 38)
    assert encode(1, INST_PING).hex(" ") == "ff ff fd 00 01 03 00 01 19 4e"
    assert encode_status(1, 0, bytes([0x06, 0x04, 0x26])).hex(" ") == "ff ff fd 00 01 07 00 55 00 06 04 26 65 5d"


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_crc_equals_the_sdk_crc(data):
    assert crc16(data) == sdk.Protocol2PacketHandler().updateCRC(0, list(data), len(data))


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_stuffing_round_trip_and_never_leaves_a_header_inside(params):
    body = bytes([INST_WRITE]) + params
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    i = stuffed.find(b"\xff\xff\xfd")
    while i >= 0:
        assert stuffed[i + 3 : i + 4] == b"\xfd"
        i = stuffed.find(b"\xff\xff\xfd", i + 1)


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=40), st.binary(max_size=40), st.integers(0, 252), st.binary(max_size=60))
def test_decoder_resyncs_after_garbage(garbage_a, garbage_b, packet_id, params):
    wanted = encode(packet_id, INST_WRITE, params)
    decoder = PacketDecoder()
    stream = garbage_a + wanted + garbage_b + wanted
    got = []
    for i in range(0, len(stream), 7):  # arbitrary chunking
        got += decoder.feed(stream[i : i + 7])
    matches = [p for p in got if p.packet_id == packet_id and p.instruction == INST_WRITE and p.params == params]
    assert len(matches) >= 1  # garbage may swallow the first copy only if it ends mid-header
    assert got[-1].params == params


def test_sdk_removes_the_stuffing_the_emulator_adds():
    params = bytes([0x00, 0xFF, 0xFF, 0xFD, 0x12])
    raw = list(encode_status(5, 0, params))
    assert len(raw) == 7 + 2 + len(params) + 1 + 2  # one stuffed FD
    out = sdk.Protocol2PacketHandler().removeStuffing(raw)
    assert bytes(out[8 : 8 + 1 + len(params)]) == bytes([0]) + params


# ---- emulator through the SDK -----------------------------------------------------------------
def test_ping_read_write_with_stuffed_values(rig):
    emu, bus, _ = rig
    port = bus._port
    ph = sdk.PacketHandler(2.0)
    model, result, error = ph.ping(port, 2)
    assert (model, result, error) == (ct.MODEL_XM430_W350, sdk.COMM_SUCCESS, 0)
    # a value whose bytes are FF FF FD: stuffed in the write instruction and in the read status
    value = 0x7FFDFFFF
    assert ph.write4ByteTxRx(port, 2, ct.ADDR_PROFILE_VELOCITY, value) == (sdk.COMM_SUCCESS, 0)
    assert emu.servos[2].read_int(ct.ADDR_PROFILE_VELOCITY, 4) == value
    assert ph.read4ByteTxRx(port, 2, ct.ADDR_PROFILE_VELOCITY) == (value, sdk.COMM_SUCCESS, 0)
    _, result, _ = ph.ping(port, 9)  # nobody there
    assert result == sdk.COMM_RX_TIMEOUT


def test_open_puts_every_motor_in_velocity_mode_with_torque_on(rig):
    emu, bus, _ = rig
    for servo in emu.servos.values():
        assert servo.torque_on and servo.table[ct.ADDR_OPERATING_MODE] == ct.MODE_VELOCITY
    assert bus.model_numbers == {name: ct.MODEL_XM430_W350 for name in IDS}
    assert emu.stats.access_errors == 0


def test_sync_read_returns_positions_velocities_and_currents_of_the_tables(rig):
    emu, bus, _ = rig
    emu.set_position_ticks(1, 5000)
    emu.set_position_ticks(2, -1234)
    emu.set_position_ticks(3, 777)
    emu.set_load(3, 150)
    states = bus.read_state()
    for name, servo_id in IDS.items():
        table = emu.servos[servo_id]
        assert states[name].position_rad == pytest.approx(
            ct.ticks_to_rad(table.read_int(ct.ADDR_PRESENT_POSITION, 4, signed=True)))
        assert states[name].velocity_rpm == pytest.approx(
            ct.units_to_rpm(table.read_int(ct.ADDR_PRESENT_VELOCITY, 4, signed=True)))
        assert states[name].current_ma == pytest.approx(
            ct.current_units_to_ma(table.read_int(ct.ADDR_PRESENT_CURRENT, 2, signed=True)))
    assert states["thumb_flexion"].position_rad == pytest.approx(-1234 * 2 * math.pi / 4096)
    assert states["thumb_rotation"].current_ma == pytest.approx(150 * 2.69)


def test_goal_velocity_is_integrated_into_present_position(rig):
    emu, bus, clock = rig
    bus.set_velocities({"fingers": 60.0, "thumb_rotation": -20.0})
    emu.sync()  # sync write has no status packet: let the servo take it before time moves
    clock.advance(0.5)
    states = bus.read_state()
    units_f, units_r = ct.rpm_to_units(60.0), ct.rpm_to_units(-20.0)
    assert emu.servos[1].read_int(ct.ADDR_GOAL_VELOCITY, 4, signed=True) == units_f
    expected_f = units_f * 0.229 / 60 * 0.5 * 2 * math.pi
    assert states["fingers"].position_rad == pytest.approx(expected_f, abs=2 * math.pi / 4096)
    assert states["thumb_rotation"].position_rad == pytest.approx(units_r * 0.229 / 60 * 0.5 * 2 * math.pi,
                                                                  abs=2 * math.pi / 4096)
    assert states["fingers"].velocity_rpm == pytest.approx(units_f * 0.229)
    assert states["thumb_flexion"].position_rad == 0.0


def test_position_mode_change_is_torque_off_mode_torque_on(rig):
    emu, bus, clock = rig
    bus.set_positions({"thumb_flexion": 1.0}, profile_rpm=30.0)
    emu.sync()
    servo = emu.servos[2]
    assert servo.table[ct.ADDR_OPERATING_MODE] == ct.MODE_EXTENDED_POSITION and servo.torque_on
    assert emu.stats.access_errors == 0  # the mode was never written with torque on
    assert bus.stats.mode_changes == 1
    clock.advance(0.2)  # 30 rpm = pi rad/s: 0.63 rad of the 1.0 rad
    assert bus.read_state()["thumb_flexion"].position_rad == pytest.approx(
        ct.rpm_to_units(30.0) * 0.229 / 60 * 0.2 * 2 * math.pi, abs=2e-3)
    clock.advance(1.0)
    assert bus.read_state()["thumb_flexion"].position_rad == pytest.approx(1.0, abs=2e-3)


def test_hardware_error_aborts_the_goal_naming_motor_and_bit_and_turns_its_torque_off(rig):
    emu, bus, clock = rig
    runner = MoveGoalRunner(bus)
    goal = MoveGoal(["fingers", "thumb_rotation"], "velocity", [40.0, 20.0], timeout_s=5.0)
    assert runner.start(goal, 0) is None
    emu.sync()
    clock.advance(0.1)
    feedback, result = runner.tick(bus.read_state(), 100_000_000)
    assert result is None and feedback.positions[0] > 0
    emu.inject_hardware_error(3, 5)
    feedback, result = runner.tick(bus.read_state(), 110_000_000)
    assert result is not None and not result.success
    assert "thumb_rotation" in result.reason and "id 3" in result.reason and "bit 5 overload" in result.reason
    emu.sync()
    assert not emu.servos[3].torque_on
    assert emu.servos[1].torque_on and emu.servos[1].read_int(ct.ADDR_GOAL_VELOCITY, 4) == 0  # others stopped
    # a new goal on the faulted motor is refused with the same reason
    assert "bit 5 overload" in runner.validate(MoveGoal(["thumb_rotation"], "velocity", [5.0]))
    assert runner.validate(MoveGoal(["fingers"], "velocity", [5.0])) is None


def test_a_cleared_hardware_error_brings_the_motor_back_holding_still_with_torque_on(rig):
    """After the servo's power cycle or reboot clears the error, the runner takes the motor back as
    the bus opened it (velocity mode, goal 0, torque on), and goals on it are accepted again."""
    emu, bus, clock = rig
    runner = MoveGoalRunner(bus)
    assert runner.start(MoveGoal(["fingers"], "velocity", [40.0], timeout_s=5.0), 0) is None
    emu.inject_hardware_error(1, 5)
    _, result = runner.tick(bus.read_state(), 10_000_000)
    assert "bit 5 overload" in result.reason
    emu.sync()
    assert not emu.servos[1].torque_on
    emu.clear_hardware_error(1)
    runner.tick(bus.read_state(), 20_000_000)
    emu.sync()
    servo = emu.servos[1]
    assert servo.torque_on and servo.table[ct.ADDR_OPERATING_MODE] == ct.MODE_VELOCITY
    assert servo.read_int(ct.ADDR_GOAL_VELOCITY, 4) == 0
    assert runner.faults == {} and runner.validate(MoveGoal(["fingers"], "velocity", [5.0])) is None
    position = servo.position_ticks
    clock.advance(0.5)
    emu.update()
    assert servo.position_ticks == position  # holding still


def test_dropped_status_packet_is_retried_and_counted(rig):
    emu, bus, _ = rig
    emu.drop_status(2, 1)
    states = bus.read_state()
    assert set(states) == set(IDS)
    assert bus.stats.dropped_status == 1 and bus.stats.retries == 1 and bus.stats.comm_failures == 0
    assert emu.stats.status_dropped == 1
    # more drops than retries: a clear error naming the operation, counted
    emu.drop_status(1, 10)
    with pytest.raises(BusError, match="sync read present state.*after 3 attempts"):
        bus.read_state()
    assert bus.stats.comm_failures == 1
    emu.drop_status(1, -emu.servos[1].drop_status)
    bus.read_state()


def test_a_late_status_of_an_earlier_instruction_is_retried_not_taken_for_the_present_state(rig):
    """On a busy computer a servo's answer can come after the host gave up on it: the SDK then takes
    that status packet (a ping's 3 bytes here) for the next instruction's. The sync read is read
    again, counted as a corrupt status; it used to end the motor driver with a ValueError."""
    emu, bus, _ = rig
    handle = emu._handle
    late = []

    def answer_late_first(packet):
        reply = handle(packet)
        if late and packet.instruction == sdk.INST_SYNC_READ:
            return late.pop() + reply
        return reply

    emu._handle = answer_late_first
    late.append(encode_status(1, 0, bytes([0x20, 0x04, 46])))  # fingers' answer to a ping
    states = bus.read_state()
    assert set(states) == set(IDS) and not late
    assert (bus.stats.corrupt_status, bus.stats.retries, bus.stats.comm_failures) == (1, 1, 0)
    # every attempt answered so: one clear error naming the servo and the lengths, counted
    emu._handle = lambda packet: encode_status(1, 0, b"\x00\x00\x00") + handle(packet) \
        if packet.instruction == sdk.INST_SYNC_READ else handle(packet)
    # (the SDK's slice of the short packet holds its 3 parameters and its 2 CRC bytes)
    with pytest.raises(BusError, match=r"fingers \(id 1\) answered 5 bytes of present state, not 66 after 3 attempts"):
        bus.read_state()
    assert bus.stats.comm_failures == 1
    emu._handle = handle
    assert set(bus.read_state()) == set(IDS)


def test_dropped_write_status_is_retried(rig):
    emu, bus, _ = rig
    emu.drop_status(3, 1)
    bus.torque_off("thumb_rotation")
    assert not emu.servos[3].torque_on
    assert bus.stats.dropped_status == 1


def test_close_turns_torque_off_everywhere():
    with DynamixelEmulator([1, 2, 3], clock=ManualClock()) as emu:
        for servo_id in (1, 2, 3):
            emu.set_baud(servo_id, 57_600)  # servos answer only at their own rate
        bus = DynamixelBus(emu.port_name, 57_600, motor_map())
        bus.open()
        assert all(s.torque_on for s in emu.servos.values())
        bus.close()
        assert not any(s.torque_on for s in emu.servos.values())


def test_bad_port_and_unsupported_baud_fail_with_the_value():
    with pytest.raises(BusError) as info:
        DynamixelBus("/dev/does-not-exist", 1_000_000, motor_map()).open()
    assert str(info.value) == "cannot open Dynamixel port /dev/does-not-exist: [Errno 2] No such file or directory"
    with DynamixelEmulator([1, 2, 3], clock=ManualClock()) as emu:
        with pytest.raises(BusError, match="baud rate 12345"):
            DynamixelBus(emu.port_name, 12345, motor_map()).open()


def test_missing_motor_fails_open_naming_it():
    with DynamixelEmulator([1, 2], clock=ManualClock()) as emu:
        bus = DynamixelBus(emu.port_name, 1_000_000, motor_map(), retries=0)
        with pytest.raises(BusError, match=r"ping thumb_rotation \(id 3\)"):
            bus.open()


def test_driver_core_says_why_once_per_change_with_the_port(tmp_path):
    """An open failure's port and OS reason reach /diagnostics (message and values) and, once per
    change, take_errors() (what the node logs); so does a bus that is lost."""
    link = tmp_path / "ttyDXL"
    core = MotorDriverCore(MotorDriverConfig(backend="dynamixel", port=str(link), retries=0))
    missing = f"cannot open Dynamixel port {link}: [Errno 2] No such file or directory"
    ms = 1_000_000
    for t_ms in range(0, 3000, 10):
        assert core.tick(t_ms * ms).states is None
    assert core.take_errors() == [missing]  # tried at 0, 0.5 and 1.5 s, said once
    bus = core.diagnostics()[0]
    assert bus.message == f"disconnected: {missing}"
    assert bus.values["port"] == str(link) and bus.values["last_error"] == missing
    with DynamixelEmulator([1, 2, 3], clock=ManualClock()) as emu:
        link.symlink_to(emu.port_name)
        assert core.tick(3500 * ms).states is not None  # the next attempt, 2 s after the last
        assert core.take_errors() == []
    link.unlink()
    assert core.tick(3510 * ms).states is None  # the servos are gone
    [lost] = core.take_errors()
    assert lost.startswith("sync read present state: ") and core.diagnostics()[0].values["last_error"] == lost
    for t_ms in range(3520, 10_000, 10):
        core.tick(t_ms * ms)
    assert core.take_errors() == [missing]  # the same reason again: the bus worked in between
