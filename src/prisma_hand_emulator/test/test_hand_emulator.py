"""The emulated hand (prisma_hand_emulator: EmulatedHand, its servos, tactile links and fault table)
without ROS, one per test in pytest's tmp_path on a manual clock (`rig`, conftest.py), reached
through the real host-side driver code: device creation and removal (what start made, and only
that) and refusal of a foreign file, one world driving the servos and either tactile link alike,
motion closing the grasp and loading the servos, push, world and replace-object commands, and the one fault table
behind the emulator and its CLI (faults themselves: test_emulator_faults.py; the console scripts:
test_emulator_cli.py).
"""
from __future__ import annotations

import math
import os
import stat

import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_hand_emulator.emulator_cli import fault_parser
from prisma_hand_emulator.fault_table import FAULTS, REQUIRED, FaultError
from prisma_hand_emulator.hand_emulator import EmulatedHand
from prisma_hand_emulator.settings import EmulatorPaths, EmulatorSettings
from prisma_motor_driver import control_table as ct
from prisma_motor_driver.sim_backend import SimMotorParams
from prisma_testing.emulator_rig import (
    DEVICES,
    RAD_PER_TICK,
    Clock,
    read_frames,
)


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


def test_a_world_without_its_timed_pushes_is_pushed_by_the_push_command(rig):
    """`world combined --pushes off`: the scenario's start without its push at 0.5 s (the grip width
    narrows, the thumb's force drops), so that a test can push once its goal runs, however late
    that goal starts."""
    r = rig("horizontal")

    def thumb_force_after(seconds: float) -> float:
        r.clock.advance(seconds)
        r.tick()
        return r.hand.status()["forces_n"]["thumb"]

    assert r.hand.apply("world", name="combined").startswith("world combined: ")
    held = thumb_force_after(0.01)
    assert held > 0.5 and thumb_force_after(1.0) < held - 0.1  # its push came at 0.5 s
    assert r.hand.apply("world", name="combined", pushes="off").startswith("world combined (its timed pushes off): ")
    assert thumb_force_after(0.01) == pytest.approx(held, abs=0.01)
    assert thumb_force_after(1.0) == pytest.approx(held, abs=0.01)  # no push
    assert r.hand.apply("push", dx_mm=-4.0, dwidth_mm=-6.0).startswith("push dx -4 mm, dy 0 mm, width -6 mm")
    assert thumb_force_after(0.5) < held - 0.1


def test_replace_object_puts_the_rolled_ball_back_and_is_refused_while_touched(rig, tmp_path):
    """`replace-object` over the control socket (prisma-hand-fault's request, and the one the emulated
    hand's tactile_driver forwards its ~/replace_object as): refused with the touching fingers named
    while the ball is held, then the ball the thumb rolled 3 mm off the pad's middle is put back there."""
    from prisma_common.control_socket import REPLACE_OBJECT, send
    from prisma_hand_emulator.emulator_cli import fault_request

    r = rig("pinch_ball")
    pose = r.hand.world.grasp_pose(1.0)  # a balanced 1 N pinch

    def place(**positions: float) -> None:
        for motor, rad in positions.items():
            r.hand.apply("servo-place", motor=motor, rad=rad)
        r.tick()

    place(**pose)
    assert r.hand.world.contact("thumb").x_mm == pytest.approx(0.0, abs=1e-9)
    assert r.hand.status()["object"] == {"name": "pinch_ball", "support_n_per_mm": 1.0}  # on its stand
    assert send(r.paths.control, REPLACE_OBJECT) == {
        "ok": False, "error": "the object cannot be re-placed while index, thumb touch it: open the hand first "
                              "(GripperCommand position 0)"}
    for step in range(1, 101):  # the thumb turns 1 rad under the ball: it rolls toward the pad's edge
        place(thumb_rotation=step * 0.01)
    # 3 mm per rad of the thumb's rotation, to the servo's resolution (0.0015 rad a tick)
    assert r.hand.world.contact("thumb").x_mm == pytest.approx(3.0, abs=0.01)
    # held 1 s: the stand let go of it after 0.5 s, its support fading with 0.2 s toward 0.01 N/mm
    assert r.hand.status()["object"]["support_n_per_mm"] < 0.1
    place(fingers=0.0, thumb_flexion=0.0, thumb_rotation=0.0)  # opened and turned back: the ball stays
    place(fingers=pose["fingers"], thumb_flexion=pose["thumb_flexion"])
    assert r.hand.world.contact("thumb").x_mm == pytest.approx(-3.0, abs=0.01)  # met off-centre

    place(fingers=0.0, thumb_flexion=0.0)
    assert fault_request(["--dir", str(tmp_path), REPLACE_OBJECT]) == \
        "pinch_ball re-placed at the thumb pad's middle (thumb rotation +0.000 rad)"
    place(fingers=pose["fingers"], thumb_flexion=pose["thumb_flexion"])
    assert r.hand.world.contact("thumb").x_mm == pytest.approx(0.0, abs=1e-9)
    assert r.hand.status()["forces_n"]["thumb"] == pytest.approx(1.0, rel=0.01)
    assert r.hand.status()["object"]["support_n_per_mm"] == 1.0  # back on its stand


def test_replace_object_in_an_empty_hand_says_how_to_start_one_with_an_object(rig):
    from prisma_common.control_socket import REPLACE_OBJECT, send

    r = rig("none")
    assert send(r.paths.control, REPLACE_OBJECT) == {
        "ok": False, "error": "no object to put back: the hand is empty (object 'none'); start it with one: "
                              "sim_object:=pinch_ball|power_ball|lateral_card"}


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
    ("world", {"name": "combined", "pushes": "maybe"}, "pushes 'maybe'"),
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
