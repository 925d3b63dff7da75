"""Every fault of the emulated hand through the real host-side driver code (`rig`, conftest.py): hub
faults counted exactly by the serial backend, an unplugged and a timed unplug, hub faults injected
while the tick runs on the real clock leaving the servos answering, faults of the other tactile link
refused, servo errors, silence, baud and power cycles (the turn count lost), I2C NACKs and glitches,
and a servo's Bus Watchdog firing on the tick alone when the host stops talking.
"""
from __future__ import annotations

import os
import threading

import dynamixel_sdk as sdk
import pytest

from prisma_common.hand import FINGERS
from prisma_hand_emulator.fault_table import FaultError
from prisma_hand_emulator.hand_emulator import EmulatedHand
from prisma_hand_emulator.settings import EmulatorPaths, EmulatorSettings
from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import BusError, MotorMap
from prisma_motor_driver.dynamixel_backend import DynamixelBus
from prisma_testing.emulator_rig import (
    FRAME_BYTES,
    RAD_PER_TICK,
    delta,
    read_frames,
)


# ---- hub faults -------------------------------------------------------------------------------
def test_hub_crc_and_garbage_are_counted_exactly_by_the_serial_backend(rig):
    r = rig("horizontal")
    serial = r.serial()
    r.tick()
    assert len(read_frames(serial, r.clock, 1)) == 1
    before = serial.counters()
    r.hand.apply("hub-crc", frames=2)
    r.hand.apply("hub-garbage", bytes=50)
    r.tick(3)  # garbage + corrupted #1, corrupted #2, a good frame
    assert [f.sequence for f in read_frames(serial, r.clock, 1)] == [3]
    d = delta(serial.counters(), before)
    assert (d["frames"], d["crc_errors"], d["bad_headers"], d["gaps"], d["missed_frames"]) == (1, 2, 0, 1, 2)
    # each CRC failure skips one byte, the resync skips the rest of the frame: all 78 are garbage
    assert d["garbage_bytes"] == 50 + 2 * FRAME_BYTES and d["resyncs"] == 1
    hub = r.hand.status()["hub"]
    assert (hub["frames_corrupted"], hub["garbage_bytes"]) == (2, 50)


def test_hub_unplug_replug_and_timed_unplug(rig, tmp_path):
    r = rig("horizontal")
    serial = r.serial()
    r.tick(4)
    assert [f.sequence for f in read_frames(serial, r.clock, 4)] == [0, 1, 2, 3]
    r.hand.apply("hub-unplug", seconds=0)
    hub = r.hand.status()["hub"]
    assert not os.path.lexists(tmp_path / "hub") and (hub["plugged"], hub["unplugs"]) == (False, 1)
    assert serial.read(r.clock.ns) == [] and not serial.connected and "lost" in serial.last_error
    sent = r.hand.hub.state.frames_sent
    r.tick(3)
    assert r.hand.hub.state.frames_sent == sent  # nothing goes out while unplugged
    r.hand.apply("hub-replug")
    assert os.readlink(tmp_path / "hub").startswith("/dev/pts/") and r.hand.status()["hub"]["plugged"]
    r.clock.advance(0.1)  # past the backend's reopen backoff (0.05 s on the same clock)
    assert serial.read(r.clock.ns) == [] and serial.connected
    r.tick(2)
    assert [f.sequence for f in read_frames(serial, r.clock, 2)] == [0, 1]  # the Nano restarted
    counters = serial.counters()
    assert (counters["restarts"], counters["reconnects"], counters["missed_frames"]) == (1, 1, 0)
    # a timed unplug plugs back by itself after 0.5 s of clock time
    r.hand.apply("hub-unplug", seconds=0.5)
    r.tick(49)
    assert not os.path.lexists(tmp_path / "hub") and r.hand.status()["hub"]["plugged"] is False
    r.tick()
    hub = r.hand.status()["hub"]
    assert (tmp_path / "hub").is_symlink() and (hub["plugged"], hub["unplugs"]) == (True, 2)


def test_hub_faults_while_the_tick_runs_leave_the_servos_answering(tmp_path):
    """The hub unplugged and plugged back 100 times, with garbage and corrupted frames, from another
    thread while the emulator ticks on the real clock (as the control socket does while it runs):
    every servo transaction succeeds and the tick goes on. The hub's pty used to be closed under a
    frame being written, which ended the tick and with it the whole emulator, servos included."""
    hand = EmulatedHand(EmulatorPaths(tmp_path), EmulatorSettings(world="horizontal")).start()
    stop, failures = threading.Event(), []

    def run() -> None:
        try:
            hand.run(stop)
        except BaseException as exc:  # the regression: anything the tick raised
            failures.append(exc)

    ticker = threading.Thread(target=run)
    ticker.start()
    try:
        motors = MotorMap.from_lists(["fingers", "thumb_flexion", "thumb_rotation"], [1, 2, 3],
                                     [0.0, 0.0, -2.0], [20.0, 20.0, 2.0], [100.0] * 3).motors
        bus = DynamixelBus(str(tmp_path / "servos"), 1_000_000, motors, retries=3)
        bus.open()
        reads = 0
        for _ in range(100):
            hand.apply("hub-garbage", bytes=10)
            hand.apply("hub-crc", frames=1)
            hand.apply("hub-unplug", seconds=0.0)
            bus.read_state()
            hand.apply("hub-replug")
            bus.read_state()
            reads += 2
        assert ticker.is_alive() and failures == []
        assert (bus.stats.reads, bus.stats.comm_failures) == (reads, 0)
        assert hand.status()["hub"]["unplugs"] == 100
        bus.close()
    finally:
        stop.set()
        ticker.join(5.0)
        hand.close()
    assert failures == []


@pytest.mark.parametrize("link, command, args, other", [
    ("serial", "i2c-nack", {"finger": "index"}, "i2c"),
    ("serial", "i2c-glitch", {"finger": "index", "count": 1}, "i2c"),
    ("serial", "i2c-clear", {}, "i2c"),
    ("i2c", "hub-unplug", {"seconds": 1.0}, "serial"),
    ("i2c", "hub-replug", {}, "serial"),
    ("i2c", "hub-garbage", {"bytes": 10}, "serial"),
    ("i2c", "hub-crc", {"frames": 1}, "serial"),
])
def test_a_fault_of_the_other_tactile_link_is_refused_with_the_reason(rig, link, command, args, other):
    r = rig("horizontal", link)
    before = r.hand.status()
    with pytest.raises(FaultError) as info:
        r.hand.apply(command, **args)
    message = str(info.value)
    assert message.startswith(f"{command}: ") and f"tactile link {link}" in message
    assert f"--tactile-link {other}" in message and f"tactile_backend:={other}" in message
    assert r.hand.status() == before  # nothing changed
    assert r.hand.request(command, args) == {"ok": False, "error": message}  # as prisma-hand-fault gets it


# ---- servo and I2C faults ---------------------------------------------------------------------
def test_servo_error_silent_and_clear_through_the_dynamixel_bus(rig):
    r = rig()
    bus = r.bus()
    r.hand.apply("servo-error", motor="fingers", bit="overload")
    states = bus.read_state()
    assert states["fingers"].hardware_error == 0x20 and states["thumb_flexion"].hardware_error == 0
    assert r.hand.status()["servos"]["fingers"]["hardware_error"] == 0x20
    r.hand.apply("servo-silent", motor="thumb_flexion")
    with pytest.raises(BusError):
        bus.read_state()
    assert r.hand.status()["servos"]["thumb_flexion"]["silent"] is True
    r.hand.apply("servo-clear")
    assert {name: s.hardware_error for name, s in bus.read_state().items()} == dict.fromkeys(states, 0)
    assert not any(s["silent"] for s in r.hand.status()["servos"].values())


def test_i2c_nack_clear_and_glitch_through_the_i2c_backend(rig):
    r = rig("horizontal", "i2c")
    i2c = r.i2c()
    r.tick()
    assert set(i2c.scan()) == set(FINGERS)
    before = i2c.counters()
    r.hand.apply("i2c-nack", finger="index")
    assert set(i2c.scan()) == set(FINGERS) - {"index"}
    d = delta(i2c.counters(), before)
    assert (d["index_errors"], d["index_failed_scans"], d["thumb_errors"]) == (3, 1, 0)  # 1 try + 2 retries
    assert r.hand.status()["i2c"]["failing"] == ["index"]
    r.hand.apply("i2c-clear")
    assert set(i2c.scan()) == set(FINGERS) and r.hand.status()["i2c"]["failing"] == []
    before = i2c.counters()
    r.hand.apply("i2c-glitch", finger="index", count=1)
    scan = i2c.scan()
    d = delta(i2c.counters(), before)
    assert "index" in scan and (d["index_bad_reads"], d["index_errors"], d["index_reads"]) == (1, 1, 1)
    assert d["index_failed_scans"] == 0


# ---- servo power, baud, place and bus watchdog ------------------------------------------------------
def test_servo_place_then_power_cycle_loses_the_turn_count_and_the_world_keeps_the_pose(rig):
    """The fingers turned by hand 7.0 rad closed (past one turn) and the servos power-cycled: the
    servo reports within one turn, the world (the mechanical angle) keeps 7.0 rad."""
    r = rig()
    assert r.hand.apply("servo-place", motor="fingers", rad=7.0).startswith("fingers (ID 1) turned")
    assert r.hand.apply("power-cycle").startswith("fingers, thumb_flexion, thumb_rotation: power-cycled")
    r.tick()
    fingers = r.hand.status()["servos"]["fingers"]
    mechanical = ct.rad_to_ticks(7.0)
    assert (fingers["mechanical_ticks"], fingers["present_position_ticks"]) == (mechanical, mechanical - 4096)
    assert fingers["position_rad"] == pytest.approx(7.0, abs=RAD_PER_TICK) and r.hand.world.positions["fingers"] == \
        pytest.approx(7.0, abs=RAD_PER_TICK)
    assert (fingers["torque_on"], fingers["led"], fingers["bus_watchdog"], fingers["watchdog_firings"]) == \
        (False, 0, 0, [])
    assert fingers["current_limit_ma"] == pytest.approx(ct.current_units_to_ma(ct.CURRENT_LIMIT_MAX_UNITS), abs=0.1)
    with pytest.raises(FaultError, match="rad 9.5: fingers moves between its end stops, 0..9.2 rad"):
        r.hand.apply("servo-place", motor="fingers", rad=9.5)
    with pytest.raises(FaultError, match="'wrist'"):
        r.hand.apply("power-cycle", motor="wrist")


def test_servo_baud_silences_one_servo_at_the_drivers_rate_until_set_back(rig):
    r = rig()
    port = sdk.PortHandler(str(r.paths.servos))
    assert port.openPort() and port.setBaudRate(1_000_000)
    try:
        ph = sdk.PacketHandler(2.0)
        assert r.hand.apply("servo-baud", motor="thumb_flexion", rate=57600) == "thumb_flexion (ID 2) set to 57600 baud"
        assert ph.ping(port, 2)[1] == sdk.COMM_RX_TIMEOUT and ph.ping(port, 1)[1] == sdk.COMM_SUCCESS
        assert r.hand.status()["servos"]["thumb_flexion"]["baud_rate"] == 57600
        with pytest.raises(FaultError, match="baud rate 12345"):
            r.hand.apply("servo-baud", motor="thumb_flexion", rate=12345)
        r.hand.apply("servo-baud", motor="thumb_flexion", rate=1_000_000)
        assert ph.ping(port, 2)[1] == sdk.COMM_SUCCESS
    finally:
        port.closePort()


def test_a_watchdog_fires_on_the_tick_alone_when_the_host_stops_talking(rig):
    """Armed (100 ms), 30 rpm, then no packet at all (a SIGKILLed driver): the tick's own look at the
    servos stops the fingers 100 ms after the last packet, and status says where and when."""
    r = rig()
    port = sdk.PortHandler(str(r.paths.servos))
    assert port.openPort() and port.setBaudRate(1_000_000)
    try:
        ph = sdk.PacketHandler(2.0)
        assert ph.write1ByteTxRx(port, 1, ct.ADDR_TORQUE_ENABLE, 1) == (sdk.COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, 1, ct.ADDR_BUS_WATCHDOG, 5) == (sdk.COMM_SUCCESS, 0)
        assert ph.write4ByteTxRx(port, 1, ct.ADDR_GOAL_VELOCITY, ct.rpm_to_units(30.0)) == (sdk.COMM_SUCCESS, 0)
    finally:
        port.closePort()
    last_s = r.clock.ns * 1e-9
    r.tick(50)
    fingers = r.hand.status()["servos"]["fingers"]
    ticks = 0.1 * ct.rpm_to_units(30.0) * ct.RPM_PER_VELOCITY_UNIT / 60.0 * ct.TICKS_PER_REV
    assert fingers["bus_watchdog"] == -1 and fingers["velocity_rpm"] == 0.0
    assert fingers["watchdog_firings"] == [{"at_s": round(last_s + 0.1, 4), "position_ticks": round(ticks, 1)}]
    assert fingers["position_rad"] == pytest.approx(ct.ticks_to_rad(ticks), abs=1e-4)  # (status rounds)
