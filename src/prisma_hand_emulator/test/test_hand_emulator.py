"""The emulated hand (prisma_hand_emulator: EmulatedHand, its servos, tactile links and fault table,
emulator_cli, emulator_control) without ROS.

One EmulatedHand per test in pytest's tmp_path, on a manual clock (ticks and servo motion are
deterministic), reached through the real host-side driver code: DynamixelBus (dynamixel-sdk) on
<dir>/servos, SerialHubBackend (pyserial + FrameParser) on <dir>/hub (tactile link serial) and
I2CHubBackend over SocketSMBus on <dir>/i2c.sock (tactile link i2c). Covered: device creation and
removal (what start made, and only that) and refusal of a foreign file, one world driving the servos
and either tactile link alike, motion closing the grasp and loading the servos, every fault command
(hub, servo, I2C, push, world) and its bad values, faults of the other tactile link refused, hub
faults injected while the tick runs on the real clock leaving the servos answering, and the two
console scripts as subprocesses.
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import select
import signal
import stat
import subprocess
import threading
import time

import dynamixel_sdk as sdk
import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_hand_emulator.emulator_cli import fault_parser
from prisma_hand_emulator.fault_table import FAULTS, REQUIRED, FaultError
from prisma_hand_emulator.hand_emulator import EmulatedHand
from prisma_hand_emulator.settings import EmulatorPaths, EmulatorSettings
from prisma_hand_emulator.tactile_link import FINGER_CHANNELS
from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import BusError, MotorMap
from prisma_motor_driver.dynamixel_backend import DynamixelBus
from prisma_motor_driver.sim_backend import SimMotorParams
from prisma_tactile_driver.i2c_backend import I2CHubBackend
from prisma_tactile_driver.i2c_socket import SocketSMBus
from prisma_tactile_driver.protocol import ALL_FINGERS_MASK, frame_size
from prisma_tactile_driver.serial_backend import SerialHubBackend
from prisma_testing.ros_harness import console_script

TICK_S = 0.01  # the emulator's 100 Hz scan period
RAD_PER_TICK = 2 * math.pi / ct.TICKS_PER_REV
FRAME_BYTES = frame_size(ALL_FINGERS_MASK)  # 78: a five-finger frame
DEVICES = {"serial": ("control.sock", "hub", "servos"), "i2c": ("control.sock", "i2c.sock", "servos")}


class Clock:
    """Manual monotonic clock in ns; starts away from 0 so world time != clock time."""

    ns = 5_000_000_000

    def __call__(self) -> int:
        return self.ns

    def advance(self, seconds: float) -> None:
        self.ns += int(round(seconds * 1e9))


class Rig:
    """A started EmulatedHand plus the host-side drivers opened on its devices (closed in reverse)."""

    def __init__(self, root, world: str, link: str) -> None:
        self.clock, self.paths = Clock(), EmulatorPaths(root)
        settings = EmulatorSettings(world=world, tactile_link=link)
        self.hand = EmulatedHand(self.paths, settings, clock_ns=self.clock).start()
        self._closers = [self.hand.close]

    def tick(self, n: int = 1, bus: DynamixelBus | None = None) -> None:
        """n scan periods; with `bus`, a read of the servos' state each (the driver's cycle, which
        keeps their bus watchdogs fed)."""
        for _ in range(n):
            self.clock.advance(TICK_S)
            self.hand.tick(self.clock.ns)
            if bus is not None:
                bus.read_state()

    def bus(self) -> DynamixelBus:
        motors = MotorMap.from_lists(["fingers", "thumb_flexion", "thumb_rotation"], [1, 2, 3],
                                     [0.0, 0.0, -2.0], [20.0, 20.0, 2.0], [100.0] * 3).motors
        bus = DynamixelBus(str(self.paths.servos), 1_000_000, motors, retries=1)
        bus.open()
        self._closers.append(bus.close)
        return bus

    def serial(self) -> SerialHubBackend:
        backend = SerialHubBackend(str(self.paths.hub), 1_000_000, read_timeout_s=0.0,
                                   monotonic=lambda: self.clock.ns * 1e-9)
        assert backend.read(self.clock.ns) == [] and backend.connected  # opened (pyserial flushes on open)
        self._closers.append(backend.close)
        return backend

    def i2c(self) -> I2CHubBackend:
        backend = I2CHubBackend(str(self.paths.i2c), dict(FINGER_CHANNELS), bus_factory=SocketSMBus)
        self._closers.append(backend.close)
        return backend

    def close(self) -> None:
        for close in reversed(self._closers):
            with contextlib.suppress(BusError):
                close()


@pytest.fixture
def rig(tmp_path):
    """rig(world="pinch_ball", link="serial", root=tmp_path): a Rig, closed after the test."""
    rigs: list[Rig] = []
    yield lambda world="pinch_ball", link="serial", root=tmp_path: rigs.append(Rig(root, world, link)) or rigs[-1]
    for r in rigs:
        r.close()


def read_frames(backend: SerialHubBackend, clock: Clock, n: int, timeout_s: float = 2.0) -> list:
    """At least n frames (the pty hands bytes over asynchronously), or what came by the deadline."""
    got, deadline = [], time.monotonic() + timeout_s
    while len(got) < n and time.monotonic() < deadline:
        got += backend.read(clock.ns)
        time.sleep(0.001)
    return got


def delta(after: dict, before: dict) -> dict:
    return {k: after[k] - before[k] for k in after}


def run_cli(name: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([console_script(name), *args], capture_output=True, text=True, timeout=60)


# the emulator as hand.launch.py runs it, at the control path's priority (its exit latency below is a
# property of the emulator, not of how busy this machine is); the default priority where not permitted
EMULATOR_ENV = {**os.environ, "PRISMA_RT_PRIORITY": "20", "PRISMA_NICE": "-5"}


# ---- lifecycle --------------------------------------------------------------------------------
@pytest.mark.parametrize("link", ["serial", "i2c"])
def test_start_creates_the_devices_of_its_link_and_close_removes_exactly_them(tmp_path, link):
    (tmp_path / "notes.txt").write_text("mine")
    hand = EmulatedHand(EmulatorPaths(tmp_path), EmulatorSettings(tactile_link=link), clock_ns=Clock()).start()
    try:
        ptys = ("hub", "servos") if link == "serial" else ("servos",)
        for pty in ptys:
            path = tmp_path / pty
            assert path.is_symlink() and os.readlink(path).startswith("/dev/pts/") and path.is_char_device()
        sockets = ("control.sock", "i2c.sock") if link == "i2c" else ("control.sock",)
        assert all(stat.S_ISSOCK(os.lstat(tmp_path / name).st_mode) for name in sockets)
        assert sorted(os.listdir(tmp_path)) == sorted(DEVICES[link] + ("notes.txt",))
        assert hand.status()["tactile_link"] == link and ("hub" in hand.status()) == (link == "serial")
    finally:
        hand.close()
    assert os.listdir(tmp_path) == ["notes.txt"] and (tmp_path / "notes.txt").read_text() == "mine"


def test_the_directories_start_made_are_removed_with_the_devices_and_one_it_found_is_kept(tmp_path):
    made = tmp_path / "a" / "hand"
    hand = EmulatedHand(EmulatorPaths(made), EmulatorSettings(), clock_ns=Clock()).start()
    assert sorted(os.listdir(made)) == sorted(DEVICES["serial"])
    hand.close()
    assert os.listdir(tmp_path) == []
    found = tmp_path / "found"
    found.mkdir()
    EmulatedHand(EmulatorPaths(found), EmulatorSettings(), clock_ns=Clock()).start().close()
    assert os.listdir(tmp_path) == ["found"] and os.listdir(found) == []


def test_a_failed_start_removes_the_directory_it_made(tmp_path):
    """A control socket path too long for a Unix socket: start fails, and leaves nothing."""
    root = tmp_path / ("d" * (110 - len(str(tmp_path))))
    hand = EmulatedHand(EmulatorPaths(root), EmulatorSettings(), clock_ns=Clock())
    with pytest.raises(OSError, match="control.sock"):
        hand.start()
    hand.close()
    assert os.listdir(tmp_path) == []


def test_a_regular_file_at_hub_is_refused_and_nothing_is_created(tmp_path):
    (tmp_path / "hub").write_text("calibration notes")
    hand = EmulatedHand(EmulatorPaths(tmp_path), EmulatorSettings(), clock_ns=Clock())
    with pytest.raises(FileExistsError, match=str(tmp_path / "hub")):
        hand.start()
    assert (tmp_path / "hub").read_text() == "calibration notes" and not (tmp_path / "hub").is_symlink()
    assert os.listdir(tmp_path) == ["hub"]
    hand.close()


def test_close_after_a_failed_start_does_not_raise(tmp_path):
    """close() is safe after a failed start (and twice): it releases the servo pty opened in __init__."""
    (tmp_path / "hub").write_text("x")
    hand = EmulatedHand(EmulatorPaths(tmp_path), EmulatorSettings(), clock_ns=Clock())
    with pytest.raises(FileExistsError):
        hand.start()
    hand.close()
    hand.close()


def test_a_second_hand_on_a_live_dir_is_refused_and_leaves_the_first_alone(rig, tmp_path):
    """A second emulator on a running one's directory is refused (its live socket) before it
    touches the running one's links."""
    first = rig()
    links = {name: os.readlink(tmp_path / name) for name in ("hub", "servos")}
    with pytest.raises(FileExistsError, match="live socket"):
        EmulatedHand(EmulatorPaths(tmp_path), EmulatorSettings(), clock_ns=first.clock).start()
    assert {n: os.readlink(tmp_path / n) if os.path.lexists(tmp_path / n) else None for n in links} == links


# ---- one world, the servos and either tactile link -----------------------------------------------
def test_one_world_drives_the_servos_and_the_pads_alike_on_either_link(rig, tmp_path):
    """Two hands on the same world and seed, one per tactile link: the hub's first frame and the
    I2C bus's first scan carry the same counts, those of the world's pinch."""
    serial_rig = rig("horizontal", "serial", tmp_path / "serial")
    i2c_rig = rig("horizontal", "i2c", tmp_path / "i2c")
    bus, serial, i2c = serial_rig.bus(), serial_rig.serial(), i2c_rig.i2c()
    states = bus.read_state()
    for name, rad in serial_rig.hand.world.positions.items():
        assert states[name].position_rad == pytest.approx(rad, abs=RAD_PER_TICK)
    assert states["fingers"].position_rad > 3.0  # the 1 N pinch pose: beyond the index contact at 3.0 rad
    serial_rig.tick()
    i2c_rig.tick()
    frames = read_frames(serial, serial_rig.clock, 1)
    scan = i2c.scan()  # the i2c hand's first tick: nothing ticks between it and the scan
    assert [f.sequence for f in frames] == [0] and set(frames[0].counts) == set(scan) == set(FINGERS)
    for finger in FINGERS:
        np.testing.assert_array_equal(frames[0].counts[finger], scan[finger], err_msg=finger)
    forces = serial_rig.hand.status()["forces_n"]
    assert forces["thumb"] == pytest.approx(1.0, abs=1e-3) and forces["index"] == pytest.approx(1.0, abs=1e-3)
    assert forces["middle"] == 0.0
    middle = scan["middle"].astype(int)
    for finger in ("thumb", "index"):
        assert (scan[finger].astype(int) - middle).mean() > 300  # pressed vs baseline (~520 counts)
    assert serial.counters()["crc_errors"] == 0


def test_motion_closes_the_grasp_and_loads_the_servos(rig):
    r = rig("pinch_grasp")
    bus = r.bus()
    bus.set_velocities({"fingers": 60.0, "thumb_flexion": 60.0})
    r.hand.servos.bus.sync()  # sync write has no status packet: let the servos take it before time moves
    r.tick(30, bus)  # 0.3 s at 2 pi rad/s: 1.9 rad, short of the thumb contact (2.5) and index (3.0)
    free, free_forces = bus.read_state(), r.hand.status()["forces_n"]
    assert free_forces["thumb"] == free_forces["index"] == 0.0
    r.tick(80, bus)  # 1.1 s: 6.9 rad, short of the end stops (thumb flexion's at 7.2 rad, fingers' at 9.2)
    loaded, forces = bus.read_state(), r.hand.status()["forces_n"]
    assert forces["thumb"] > 0.5 and forces["index"] > 0.5
    assert loaded["fingers"].position_rad == pytest.approx(1.1 * 2 * math.pi, rel=1e-3)
    loads = r.hand.world.motor_loads()
    for name in ("fingers", "thumb_flexion"):
        grown = loaded[name].current_ma - free[name].current_ma  # the speed term is the same in both
        assert grown > 0
        assert grown == pytest.approx(loads[name] / SimMotorParams().torque_constant_nm_per_a * 1e3,
                                      abs=ct.MA_PER_CURRENT_UNIT)
    # on into the fingers' far end stop (0.2 rad past their 9.0 rad maximum): stalled there, pulling
    # the Current Limit, the peak kept and the stall logged
    r.tick(70, bus)
    stalled, status = bus.read_state()["fingers"], r.hand.status()["servos"]["fingers"]
    assert stalled.position_rad == pytest.approx(ct.ticks_to_rad(ct.rad_to_ticks(9.2)))
    assert stalled.velocity_rpm == 0.0 and stalled.current_ma == pytest.approx(status["current_limit_ma"], abs=0.1)
    assert status["peak_current_ma"] == status["current_limit_ma"] <= ct.current_units_to_ma(ct.CURRENT_LIMIT_MAX_UNITS)
    assert any(line.startswith("servo 1: stalled at its hi end stop") for line in r.hand.servos.bus.events)


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


# ---- push and world ---------------------------------------------------------------------------
def test_push_slips_the_contact_across_the_thumb_pad(rig):
    r = rig("horizontal")
    r.tick()
    x0 = r.hand.world.contact("thumb").x_mm
    forces = r.hand.status()["forces_n"]
    r.hand.apply("push", dx_mm=-4.0, duration_s=0.3)
    r.tick(15)  # halfway: the smoothstep is at 0.5
    assert r.hand.world.contact("thumb").x_mm == pytest.approx(x0 - 2.0, abs=1e-6)
    r.tick(20)
    # the object slips dx in the hand (= thumb pad) frame: -4 mm toward the thumb pad's right side;
    # the index pad faces it, so its x (mirrored) moves +4 mm
    assert r.hand.world.contact("thumb").x_mm == pytest.approx(x0 - 4.0, abs=1e-6)
    assert r.hand.world.contact("index").x_mm == pytest.approx(-(x0 - 4.0), abs=1e-6)
    assert r.hand.status()["forces_n"] == forces  # a slip, not a squeeze


def test_world_command_poses_the_servos_and_changes_the_world(rig):
    r = rig("horizontal")
    bus = r.bus()
    assert bus.read_state()["fingers"].position_rad > 3.0
    bus.set_velocities({"fingers": 30.0})
    r.hand.servos.bus.sync()
    assert r.hand.apply("world", name="pinch_grasp").startswith("world pinch_grasp")
    r.clock.advance(0.5)  # posed at rest: the goal velocity was zeroed
    assert all(s.position_rad == pytest.approx(0.0, abs=RAD_PER_TICK) for s in bus.read_state().values())
    r.tick()
    status = r.hand.status()
    assert status["world"] == "pinch_grasp" and all(f == 0.0 for f in status["forces_n"].values())


def test_the_emulator_places_the_sim_graphs_objects_too(rig):
    """One vocabulary for the simulated world (hand.launch.py sim_object:=): the emulated hand takes
    the objects the sim graph presents, an empty hand included, besides the scenarios' starts."""
    from prisma_hand_emulator.settings import WORLDS, world_for

    assert WORLDS[:4] == ("pinch_ball", "power_ball", "lateral_card", "none")
    assert [world_for(name).obj.name for name in WORLDS[:4]] == list(WORLDS[:4])
    r = rig("none")
    r.hand.servos.bus.sync()
    r.hand.apply("servo-place", motor="fingers", rad=8.0)  # closed on nothing
    r.hand.apply("servo-place", motor="thumb_flexion", rad=6.0)
    r.tick()
    status = r.hand.status()
    assert status["world"] == "none" and all(f == 0.0 for f in status["forces_n"].values())
    assert r.hand.apply("world", name="pinch_ball").startswith("world pinch_ball")
    assert r.hand.status()["world"] == "pinch_ball"


def test_one_fault_table_drives_the_emulator_and_the_cli():
    """Each command of FAULTS has its `_fault_` handler (status: the request itself) and none is
    handled that the table lacks; prisma-hand-fault parses each with the table's defaults."""
    handlers = {name[len("_fault_"):].replace("_", "-") for name in dir(EmulatedHand) if name.startswith("_fault_")}
    assert handlers == set(FAULTS) - {"status"}
    parser = fault_parser()
    assert fault_parser().parse_args(["status"]).command == "status"
    for name, fault in FAULTS.items():
        argv = [name]
        for arg in fault.args:
            if arg.default is REQUIRED:
                value = {"finger": "index", "motor": "fingers", "bit": "overload", "name": "hand"}.get(arg.name, "2")
                argv += [value] if arg.positional else [arg.flag, value]
        parsed = vars(parser.parse_args(argv))
        assert {k for k in parsed if k not in ("dir", "command")} == {a.name for a in fault.args}, name
        for arg in fault.args:
            if arg.default is not REQUIRED:
                assert parsed[arg.name] == arg.default, (name, arg.name)


def test_fault_defaults_come_from_the_table(rig):
    r = rig("horizontal", "i2c")
    assert r.hand.apply("i2c-nack", finger="index") == "index ADC does not acknowledge until i2c-clear"
    assert r.hand.apply("push").startswith("push dx 0 mm, dy 0 mm, width +0 mm over 0.3 s")


@pytest.mark.parametrize("command, args, named", [
    ("hub-crc", {"frames": 0}, "frames 0"),
    ("servo-error", {"motor": "wrist", "bit": 5}, "'wrist'"),
    ("servo-error", {"motor": "fingers", "bit": 9}, "bit 9"),
    ("world", {"name": "nope"}, "'nope'"),
    ("nope", {}, "'nope'"),
])
def test_bad_fault_values_raise_fault_error_naming_them(rig, command, args, named):
    r = rig()
    with pytest.raises(FaultError) as info:
        r.hand.apply(command, **args)
    assert named in str(info.value)
    status = r.hand.status()  # nothing was changed
    assert status["world"] == "pinch_ball" and status["servos"]["fingers"]["hardware_error"] == 0
    assert r.hand.hub.state.corrupt_pending == 0


# ---- console scripts --------------------------------------------------------------------------
def test_cli_refuses_a_missing_hand_and_a_file_as_dir(tmp_path):
    done = run_cli("prisma-hand-fault", "--dir", str(tmp_path), "status")  # an empty directory
    assert done.returncode == 2 and "no emulated hand at" in done.stderr and "Traceback" not in done.stderr
    (regular := tmp_path / "a_file").write_text("x")
    done = run_cli("prisma-hand-emulator", "--dir", str(regular), "--seconds", "1")
    assert done.returncode == 2 and str(regular) in done.stderr and "Traceback" not in done.stderr


def test_cli_emulator_refuses_an_occupied_control_socket_path(tmp_path):
    """Something at control.sock: exit 2 naming it, and the devices already made are removed."""
    (tmp_path / "control.sock").write_text("x")
    done = run_cli("prisma-hand-emulator", "--dir", str(tmp_path), "--seconds", "1")
    assert os.listdir(tmp_path) == ["control.sock"]
    assert done.returncode == 2 and "control.sock" in done.stderr and "Traceback" not in done.stderr


def test_cli_running_emulator_answers_faults_and_stops_on_sigint(tmp_path):
    d = str(tmp_path)
    proc = subprocess.Popen([console_script("prisma-hand-emulator"), "--dir", d, "--seconds", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=EMULATOR_ENV)
    try:
        assert select.select([proc.stdout], [], [], 60.0)[0], "the emulator printed nothing in 60 s"
        assert proc.stdout.readline().startswith("emulated hand (pinch_ball, 100 Hz)")
        done = run_cli("prisma-hand-fault", "--dir", d, "status")
        assert done.returncode == 0, done.stderr
        status = json.loads(done.stdout)
        assert status["world"] == "pinch_ball" and status["hub"]["plugged"] is True
        done = run_cli("prisma-hand-fault", "--dir", d, "servo-error", "--motor", "fingers", "--bit", "9")
        assert done.returncode == 2 and "bit 9" in done.stderr and "Traceback" not in done.stderr
        done = run_cli("prisma-hand-fault", "--dir", d, "servo-error", "--motor", "fingers", "--bit", "overload")
        assert done.returncode == 0 and "overload" in done.stdout
        status = json.loads(run_cli("prisma-hand-fault", "--dir", d, "status").stdout)
        assert status["servos"]["fingers"]["hardware_error"] == 0x20
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=5) == 0 and time.monotonic() - start < 2.5  # lingers 1 s by default
        assert "emulated hand stopped after" in proc.stdout.read()
        assert os.listdir(d) == []  # hub, servos and control.sock removed
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def test_cli_on_sigterm_removes_what_it_made_and_refuses_faults_of_the_other_link(tmp_path):
    """`--tactile-link i2c`: the bus socket and no hub; hub-unplug is refused in one line naming the
    link; SIGTERM (what `ros2 launch` sends) removes the devices and the directories it created."""
    d = tmp_path / "made" / "hand"
    proc = subprocess.Popen([console_script("prisma-hand-emulator"), "--dir", str(d), "--tactile-link", "i2c",
                             "--linger", "0", "--seconds", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=EMULATOR_ENV)
    try:
        assert select.select([proc.stdout], [], [], 60.0)[0], "the emulator printed nothing in 60 s"
        assert f"i2c {d / 'i2c.sock'}" in proc.stdout.readline()
        assert sorted(os.listdir(d)) == sorted(DEVICES["i2c"])
        done = run_cli("prisma-hand-fault", "--dir", str(d), "hub-unplug", "--seconds", "1")
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
        assert lines[0].startswith("prisma-hand-fault: error: hub-unplug: ") and "tactile link i2c" in lines[0]
        assert lines[0].count("hub-unplug") == 1, lines[0]  # the command named once, not once per layer
        status = json.loads(run_cli("prisma-hand-fault", "--dir", str(d), "status").stdout)
        assert status["tactile_link"] == "i2c" and "hub" not in status and status["i2c"]["nacks"] == 0
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=5) == 0
        assert os.listdir(tmp_path) == []
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


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
