"""The hand's hardware emulated in one process, for `hand.launch.py hardware:=emulated`.

Byte-level devices share one hand/world model, so a goal closes the loop through every real driver
path:
- the Dynamixel servos (IDs 1-3, Protocol 2.0) on a pseudo-terminal, `<dir>/servos`: motor_driver's
  dynamixel backend opens it through dynamixel-sdk;
- the five pads on the tactile link the hand is wired with (`tactile_link`, as tactile_driver's
  `backend`): `serial`, the fingertip hub on a second pseudo-terminal, `<dir>/hub`, 78-byte frames
  at the scan rate read by tactile_driver's serial backend through pyserial; or `i2c`, the pads'
  TCA9548A + MAX11617 bus served on `<dir>/i2c.sock`, reached by tactile_driver's i2c backend
  through smbus2 (`i2c_socket`). A robot has one of the two, so the emulator serves one.
Every scan period `tick` reads the servos' MECHANICAL angles (a servo's reported position loses
whole turns at a power-up; the spools do not), moves the world to them, puts the
pads' contacts through the pad model into counts (a hub frame or the ADC registers) and loads the
servos with the world's tendon torques.

Each device serves its link on its own: the servo emulator answers from its own thread, the I2C
bus from the socket server's, and the hub link is written by the tick under a lock of its own, so
a fault injected into one device (from the control socket's thread, while the tick runs) changes
that device only: an unplugged hub never stops the servos from answering.

Faults are applied by `apply`, as the emulator's control socket receives them (`prisma-hand-fault`):
the hub unplugged and plugged back (a new pty behind the same link, sequence restarting at 0 as a
powered-down Arduino does), garbage bytes and CRC-corrupted frames on the hub link, a pad's ADC not
acknowledging or glitching on I2C, a servo hardware error bit, a servo off the bus, a servo power
cycle (`power-cycle`: RAM reset, the turn count lost, the hand keeps its pose), a servo at another baud
rate (`servo-baud`), a motor turned by hand (`servo-place`), an external push on the object, and a new
scenario world (the experimenter placing another object). A fault of the
tactile link the hand is not wired with (`i2c-nack` on the serial hub) is refused with the reason.

Each motor has mechanical end stops (END_STOPS_RAD): its configured minimum, and 0.2 rad past its
maximum; a servo driven into one stalls there at the current its mode allows (logged via `log`).

Nothing here reads ROS. Time is `clock_ns()` (monotonic); the world's time starts at 0 with each
scenario, so the scenarios' disturbances keep their timing.
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.cli_args import non_negative_float, non_negative_int, positive_int
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_hand_sim.hand_world import OBJECTS, Disturbance, HandWorld, HandWorldContactSource
from prisma_manipulation.scenarios import SCENARIO_NAMES, scenario_world
from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import DEFAULT_MAX_POSITIONS, DEFAULT_MIN_POSITIONS
from prisma_motor_driver.dynamixel_emulator import DynamixelEmulator, ServoPresent
from prisma_motor_driver.sim_backend import SimMotorParams
from prisma_tactile_driver.i2c_emulator import five_finger_bus
from prisma_tactile_driver.i2c_socket import I2CSocketServer
from prisma_tactile_driver.protocol import SEQUENCE_MODULO, encode_frame
from prisma_tactile_driver.pty_hub import ADAPTER_BUFFER_BYTES, PtyHubPort, PtyLink
from prisma_tactile_driver.sim_backend import SimHubBackend

from .emulator_control import ControlServer

# The hand's wiring as config/motor_driver.yaml and config/tactile_driver.yaml have it.
MOTOR_IDS = dict(zip(MOTOR_NAMES, (1, 2, 3)))
FINGER_CHANNELS = dict(zip(FINGERS, range(5)))
# the fingertip pads reach the host through the Arduino hub (serial) or its own I2C bus (i2c)
TACTILE_LINKS = ("serial", "i2c")
# One vocabulary with the sim graph (hand.launch.py sim_object:=): an object presented to the open
# hand as sim:=true presents it (pinch_ball, the default: a foam ball let go once held; none: an empty
# hand), or a prisma-sim scenario's start, the hand posed and the object held
# (prisma_manipulation.scenarios.scenario_world).
WORLDS = tuple(OBJECTS) + SCENARIO_NAMES
DEFAULT_WORLD = "pinch_ball"
DEFAULT_DIR = Path("/tmp/prisma_hand_emulator")


REQUIRED: Any = None  # a FaultArg without a default: the command needs it


@dataclass(frozen=True)
class FaultArg:
    """One argument of a fault command: the control request's key and prisma-hand-fault's option
    (`dx_mm` -> `--dx-mm`; a positional one keeps its name)."""
    name: str
    type: Callable[[str], Any]  # the CLI's parser of the text; it also picks the emulator's check
    help: str
    default: Any = REQUIRED
    positional: bool = False

    @property
    def flag(self) -> str:
        return self.name if self.positional else "--" + self.name.replace("_", "-")


@dataclass(frozen=True)
class Fault:
    """A command of the control socket: what it does, its arguments and the tactile link it needs
    (None: any). EmulatedHand.apply dispatches on this table to `_fault_<name>`; prisma-hand-fault
    builds its subcommands from it."""
    help: str
    args: tuple[FaultArg, ...] = ()
    link: str | None = None


def _one_of(names: tuple[str, ...]) -> str:
    return ", ".join(names[:-1]) + " or " + names[-1]


_FINGER = FaultArg("finger", str, _one_of(FINGERS))
_MOTOR = FaultArg("motor", str, _one_of(MOTOR_NAMES))
_ONE_MOTOR = FaultArg("motor", str, "one motor (default: all)", "")
FAULTS: dict[str, Fault] = {
    "status": Fault("what the emulated hardware is doing (JSON)"),
    "hub-unplug": Fault("unplug the fingertip hub's USB cable (tactile link serial)", (
        FaultArg("seconds", non_negative_float, "plug it back after this long (0 = at hub-replug)", 0.0),),
        link="serial"),
    "hub-replug": Fault("plug the hub back in (a new pty behind the same link; tactile link serial)", link="serial"),
    "hub-garbage": Fault("write garbage bytes on the hub link before the next frame (tactile link serial)", (
        FaultArg("bytes", positive_int, "how many"),), link="serial"),
    "hub-crc": Fault("corrupt the CRC of the next hub frames (tactile link serial)", (
        FaultArg("frames", positive_int, "how many"),), link="serial"),
    "i2c-nack": Fault("a finger's ADC stops acknowledging on the I2C bus (tactile link i2c)", (
        _FINGER,
        FaultArg("count", non_negative_int, "this many addressings, then it recovers (0 = until i2c-clear)", 0)),
        link="i2c"),
    "i2c-glitch": Fault("a finger's next I2C reads return all-zero bytes (tactile link i2c)", (
        _FINGER, FaultArg("count", positive_int, "how many")), link="i2c"),
    "i2c-clear": Fault("every ADC answers again (tactile link i2c)", link="i2c"),
    "servo-error": Fault("set a Hardware Error Status bit on a servo", (
        _MOTOR, FaultArg("bit", str, "0-7 or " + ", ".join(ct.HARDWARE_ERROR_BITS.values())))),
    "servo-silent": Fault("a servo stops answering (off the bus)", (
        _MOTOR, FaultArg("seconds", non_negative_float, "back after this long (0 = at servo-clear)", 0.0))),
    "servo-clear": Fault("hardware error bits cleared and servos answering again (no power cycle)", (_ONE_MOTOR,)),
    "power-cycle": Fault("switch servos off and on: torque off, RAM (LED, bus watchdog, goals) reset, the position "
                         "reported within one turn again; the hand keeps its pose", (_ONE_MOTOR,)),
    "servo-baud": Fault("a servo configured at another baud rate (by another tool): silent at the driver's", (
        _MOTOR, FaultArg("rate", positive_int, "its baud rate (1000000 restores it)"))),
    "servo-place": Fault("turn a motor by hand to an angle (rad of its shaft, between its end stops)", (
        _MOTOR, FaultArg("rad", float, "the angle (rad)"))),
    "push": Fault("push the object across the pads / to a narrower section", (
        FaultArg("dx_mm", float, "slip toward the thumb pad's left side (mm)", 0.0),
        FaultArg("dy_mm", float, "slip toward the thumb pad's top row (mm)", 0.0),
        FaultArg("dwidth_mm", float, "change of the grip width (mm, negative = narrower)", 0.0),
        FaultArg("duration_s", non_negative_float, "over this long (s)", 0.3))),
    "world": Fault("place another object: the hand is posed as that world starts", (
        FaultArg("name", str, ", ".join(WORLDS), positional=True),)),
}
# Each motor's mechanical end stops (rad of the motor shaft from its zero): the open end is its
# configured minimum, the far one this far past its configured maximum.
END_STOP_MARGIN_RAD = 0.2
END_STOPS_RAD = {name: (lo, hi + END_STOP_MARGIN_RAD)
                 for name, lo, hi in zip(MOTOR_NAMES, DEFAULT_MIN_POSITIONS, DEFAULT_MAX_POSITIONS)}


def world_for(name: str) -> HandWorld:
    if name in OBJECTS:
        return HandWorld(obj=name)
    if name not in SCENARIO_NAMES:
        raise ValueError(f"unknown world {name!r}; choose one of {', '.join(WORLDS)}")
    return scenario_world(name)


@dataclass(frozen=True)
class EmulatorPaths:
    """Where the emulated devices appear: the drivers' `port` / `i2c_socket` parameters name these."""

    root: Path

    @property
    def hub(self) -> Path:
        return self.root / "hub"

    @property
    def servos(self) -> Path:
        return self.root / "servos"

    @property
    def i2c(self) -> Path:
        return self.root / "i2c.sock"

    @property
    def control(self) -> Path:
        return self.root / "control.sock"

    def tactile(self, link: str) -> Path:
        """Where the pads' link appears: the hub's pty or the I2C bus socket."""
        return self.hub if link == "serial" else self.i2c


@dataclass(frozen=True)
class EmulatorSettings:
    rate_hz: float = 100.0  # hub scans per second (the Arduino firmware's rate)
    world: str = DEFAULT_WORLD  # one of WORLDS
    seed: int = 0  # pad noise
    tactile_link: str = "serial"  # serial | i2c: how the pads reach the host (TACTILE_LINKS)
    directions: tuple[int, ...] = (1, 1, 1)  # as motor_driver's `directions`, per MOTOR_NAMES
    zero_ticks: tuple[int, ...] = (0, 0, 0)  # as motor_driver's `zero_ticks`
    # a USB-serial adapter buffers only so much for a host that does not read: frames beyond this
    # are lost at the adapter, as on the robot (and the emulator never blocks on its pty)
    hub_buffer_bytes: int = ADAPTER_BUFFER_BYTES


@dataclass
class HubState:
    plugged: bool = True
    replug_at_ns: int | None = None  # a timed unplug ends here
    sequence: int = 0
    garbage_pending: int = 0
    corrupt_pending: int = 0
    frames_sent: int = 0
    frames_unread: int = 0  # dropped at the "adapter": nobody read the link
    frames_corrupted: int = 0
    garbage_sent: int = 0
    unplugs: int = 0


class FaultError(ValueError):
    """A fault command that names something the emulator does not have; the message says what."""


class HubLink:
    """The fingertip hub's serial end: one frame per scan on a pty behind `path`, and its faults.

    The tick sends and the control socket's thread unplugs, replugs and corrupts: every use of the
    pty and of the counters is under this link's own lock, so a fault never pulls the pty from under
    a frame being written, and nothing the hub does holds up the servos or the I2C bus."""

    def __init__(self, path: Path, buffer_bytes: int, rng: np.random.Generator) -> None:
        self.state = HubState()
        self._port = PtyHubPort(path)
        self._buffer_bytes = buffer_bytes
        self._rng = rng
        self._lock = threading.Lock()

    def open(self) -> None:
        with self._lock:
            self._port.open()

    def close(self) -> None:
        with self._lock:
            if self._port.is_open:
                self._port.hang_up()

    def send(self, counts: dict[str, np.ndarray], now_ns: int) -> None:
        """One scan's frame (a timed unplug that is over first plugs the hub back in)."""
        with self._lock:
            hub = self.state
            if not hub.plugged and hub.replug_at_ns is not None and now_ns >= hub.replug_at_ns:
                self._replug()
            frame = bytearray(encode_frame(hub.sequence, counts))
            hub.sequence = (hub.sequence + 1) % SEQUENCE_MODULO
            if not hub.plugged:
                return
            out = bytearray()
            if hub.garbage_pending:
                # no sync pattern in it: garbage that forms a false frame start would only delay the
                # next real frame, and the count of skipped bytes must equal what was sent
                garbage = self._rng.integers(0, 256, hub.garbage_pending, dtype=np.uint8)
                garbage[garbage == 0xA5] = 0xA4
                out += garbage.tobytes()
                hub.garbage_sent += hub.garbage_pending
                hub.garbage_pending = 0
            if hub.corrupt_pending:
                frame[-1] ^= 0xFF  # the CRC's high byte
                hub.corrupt_pending -= 1
                hub.frames_corrupted += 1
            out += frame
            if self._port.offer(bytes(out), self._buffer_bytes):
                hub.frames_sent += 1
            else:
                hub.frames_unread += 1

    def unplug(self, seconds: float, now_ns: int) -> str:
        with self._lock:
            hub = self.state
            if hub.plugged:
                self._port.hang_up()
                hub.plugged = False
                hub.unplugs += 1
            hub.replug_at_ns = now_ns + int(seconds * 1e9) if seconds else None
        return f"hub unplugged{f' for {seconds:g} s' if seconds else ' until hub-replug'}"

    def replug(self) -> str:
        with self._lock:
            if self.state.plugged:
                return "hub already plugged in"
            self._replug()
        return "hub plugged in"

    def _replug(self) -> None:
        self._port.open()
        self.state.plugged = True
        self.state.replug_at_ns = None
        self.state.sequence = 0  # the Nano is powered from USB: it restarts with the link

    def garbage(self, count: int) -> str:
        with self._lock:
            self.state.garbage_pending += int(count)
        return f"{count} garbage bytes before the next frame"

    def corrupt(self, frames: int) -> str:
        with self._lock:
            self.state.corrupt_pending += int(frames)
        return f"CRC of the next {frames} frame(s) corrupted"

    def status(self) -> dict[str, Any]:
        with self._lock:
            hub = self.state
            return {"plugged": hub.plugged, "frames_sent": hub.frames_sent, "frames_unread": hub.frames_unread,
                    "frames_corrupted": hub.frames_corrupted, "garbage_bytes": hub.garbage_sent,
                    "unplugs": hub.unplugs, "sequence": hub.sequence}


class EmulatedHand:
    def __init__(self, paths: EmulatorPaths, settings: EmulatorSettings | None = None,
                 clock_ns: Callable[[], int] = time.monotonic_ns, log: Callable[[str], None] | None = None) -> None:
        """`log` gets the servos' event lines (a stall at an end stop, a bus watchdog firing)."""
        self.paths = paths
        self.settings = settings or EmulatorSettings()
        if self.settings.rate_hz <= 0:
            raise ValueError(f"rate_hz {self.settings.rate_hz}: must be > 0")
        if self.settings.tactile_link not in TACTILE_LINKS:
            raise ValueError(f"tactile_link {self.settings.tactile_link!r}: choose one of {', '.join(TACTILE_LINKS)}")
        self.tactile_link = self.settings.tactile_link
        self.clock_ns = clock_ns
        self.period_ns = int(round(1e9 / self.settings.rate_hz))
        self.lock = threading.Lock()  # world, pads and ADC registers: the tick vs the I2C server
        self.world = world_for(self.settings.world)
        self.world_name = self.settings.world
        self._world_start_ns = clock_ns()
        # the pads as the tactile driver's sim backend samples them, on this world
        self._contacts = HandWorldContactSource(self.world)
        self._pads = SimHubBackend(self._contacts, FINGERS, seed=self.settings.seed)
        self.i2c_bus = five_finger_bus()
        self.servos = DynamixelEmulator(list(MOTOR_IDS.values()), clock=lambda: clock_ns() * 1e-9, log=log)
        for name, (lo, hi) in END_STOPS_RAD.items():
            self.servos.set_end_stops(MOTOR_IDS[name], *sorted((self._mechanical_ticks(name, lo),
                                                                self._mechanical_ticks(name, hi))))
        self.hub = HubLink(paths.hub, self.settings.hub_buffer_bytes, np.random.default_rng(self.settings.seed))
        self._servo_faults_lock = threading.Lock()  # the tick expires them, the control thread sets them
        self._silent_until_ns: dict[str, int | None] = {}  # None = until servo-clear
        self._servo_link = PtyLink(paths.servos)
        self._i2c_server: Any = None
        self._control = ControlServer(paths.control, self.request)
        self._made_dirs: list[Path] = []  # the directories start() created, innermost last
        self._place_servos()
        self.servos.power_cycle()  # switched on in the world's pose: each count within one turn

    # ---- lifecycle -------------------------------------------------------------------------
    def start(self) -> EmulatedHand:
        """Create the directory (and its missing parents), the control socket (`request` answers it:
        prisma-hand-fault) and the devices. FileExistsError (naming the path) if one of the paths
        holds something that is not an earlier emulator's link or socket; nothing is replaced then,
        and whatever this call made is removed again."""
        missing = []
        directory = self.paths.root
        while not directory.exists() and not directory.is_symlink():
            missing.append(directory)
            directory = directory.parent
        started: list[Callable[[], None]] = []
        try:
            for directory in reversed(missing):
                directory.mkdir()
                self._made_dirs.append(directory)
            # the control socket first: a live one (another emulator on this dir) is refused, and
            # the pty links, which an earlier run's may replace, are then left alone
            self._control.bind()
            started.append(self._control.close)
            if self.tactile_link == "i2c":
                self._i2c_server = I2CSocketServer(self.i2c_bus, self.paths.i2c, self.lock).start()
                started.append(self._i2c_server.close)
            else:
                self.hub.open()
                started.append(self.hub.close)
            self.servos.start()
            started.append(self.servos.close)
            self._servo_link.point_at(self.servos.port_name)
        except BaseException:
            for undo in reversed(started):
                undo()
            self._i2c_server = None
            self._remove_made_dirs()
            raise
        self._control.serve()
        return self

    def close(self) -> None:
        """Remove what start() made, and only that: the sockets and links (each only while it is
        still this emulator's) and the directories start() created, while they are empty."""
        self._control.close()
        if self._i2c_server is not None:
            self._i2c_server.close()
            self._i2c_server = None
        self._servo_link.remove()
        self.servos.close()
        self.hub.close()
        self._remove_made_dirs()

    def _remove_made_dirs(self) -> None:
        while self._made_dirs:
            try:
                self._made_dirs.pop().rmdir()  # only while empty: someone else's files stay, and so does it
            except OSError:
                self._made_dirs.clear()

    def __enter__(self) -> EmulatedHand:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def run(self, stop: threading.Event, progress: Callable[[str], None] | None = None) -> int:
        """Tick at the scan rate until `stop` is set; returns the ticks run. A tick that comes late
        (the machine was busy) is run at once and the schedule kept, as the hub's timer does."""
        next_ns = self.clock_ns()
        ticks = 0
        while not stop.is_set():
            self.tick(self.clock_ns())
            ticks += 1
            next_ns += self.period_ns
            delay = (next_ns - self.clock_ns()) * 1e-9
            if delay > 0:
                stop.wait(delay)
            elif delay < -1.0:  # more than a second behind (suspended): start the schedule afresh
                next_ns = self.clock_ns()
        return ticks

    # ---- one scan period -------------------------------------------------------------------
    def tick(self, now_ns: int) -> None:
        self._expire_servo_faults(now_ns)
        present = self.servos.present()
        with self.lock:
            positions = self._motor_positions(present)
            self._contacts.update_joints(list(positions), list(positions.values()), now_ns - self._world_start_ns)
            [reading] = self._pads.read(now_ns - self._world_start_ns)
            counts = reading.counts
            if self.tactile_link == "i2c":
                for finger, channel in FINGER_CHANNELS.items():
                    self.i2c_bus.adcs[channel].values[: len(counts[finger])] = counts[finger]
            loads = self.world.motor_loads()
        for name, servo_id in MOTOR_IDS.items():
            self.servos.set_load(servo_id, _current_units(loads[name]))
        if self.tactile_link == "serial":
            self.hub.send(counts, now_ns)

    def _motor_positions(self, present: dict[int, ServoPresent]) -> dict[str, float]:
        """The joints' motor angles: the world follows the spools' MECHANICAL angles (what a servo
        reports loses whole turns at a power-up)."""
        s = self.settings
        return {name: s.directions[i] * ct.ticks_to_rad(present[MOTOR_IDS[name]].mechanical_ticks - s.zero_ticks[i])
                for i, name in enumerate(MOTOR_NAMES)}

    def _mechanical_ticks(self, motor: str, rad: float) -> float:
        i = MOTOR_NAMES.index(motor)
        return self.settings.zero_ticks[i] + ct.rad_to_ticks(self.settings.directions[i] * rad)

    def _expire_servo_faults(self, now_ns: int) -> None:
        with self._servo_faults_lock:
            over = [name for name, until in self._silent_until_ns.items() if until is not None and now_ns >= until]
        for name in over:
            self._servo_back(name)

    # ---- faults ----------------------------------------------------------------------------
    def apply(self, command: str, **args: Any) -> str:
        """Carry out one fault command (`prisma-hand-fault --help`); returns what was done.
        FaultError for an unknown name or a value out of range, naming it."""
        fault = FAULTS.get(command)
        handler = getattr(self, "_fault_" + command.replace("-", "_"), None) if fault else None
        if fault is None or handler is None:  # `status` is a request, not a fault
            raise FaultError(f"unknown command {command!r}")
        link = fault.link
        if link is not None and link != self.tactile_link:
            raise FaultError(f"{command}: the pads are on the {_LINK_NAMES[self.tactile_link]} here "
                             f"(tactile link {self.tactile_link}), which has no such fault; it needs the "
                             f"{_LINK_NAMES[link]} (prisma-hand-emulator --tactile-link {link}, "
                             f"hand.launch.py tactile_backend:={link})")
        values = {a.name: a.default for a in fault.args if a.default is not REQUIRED} | args
        for arg in fault.args:  # the socket takes any JSON: the CLI's bounds checked again here
            check = _VALUE_CHECKS.get(arg.type)
            if check is not None and arg.name in values:
                check(arg.name, values[arg.name])
        return handler(**values)

    def request(self, name: str, args: dict[str, Any]) -> dict[str, Any]:
        """One control-socket request: `status`, or a fault command with its arguments."""
        if name == "status":
            return {"ok": True, "status": self.status()}
        try:
            return {"ok": True, "message": self.apply(name, **args)}
        except FaultError as exc:
            return {"ok": False, "error": str(exc)}
        except TypeError as exc:  # an argument the command does not take, or one it needs missing
            return {"ok": False, "error": f"{name}: {exc}"}

    def status(self) -> dict[str, Any]:
        """What the emulated hardware is doing, as plain data (JSON-ready)."""
        present = self.servos.present()
        positions = self._motor_positions(present)
        servos = {}
        for i, (name, servo_id) in enumerate(MOTOR_IDS.items()):
            servo, emulated = present[servo_id], self.servos.servos[servo_id]
            servos[name] = {"id": servo_id, "position_rad": round(positions[name], 4),
                            "velocity_rpm": round(self.settings.directions[i] * servo.velocity_rpm, 3),
                            "torque_on": servo.torque_on, "hardware_error": servo.hardware_error,
                            "silent": emulated.silent, "baud_rate": emulated.baud_rate,
                            "present_position_ticks": int(round(servo.position_ticks)),
                            "mechanical_ticks": round(servo.mechanical_ticks, 1), "led": servo.led,
                            "bus_watchdog": servo.bus_watchdog,
                            "watchdog_firings": [
                                {"at_s": round(f.at_s, 4), "position_ticks": round(f.position_ticks, 1)}
                                for f in self.servos.watchdog_firings if f.servo_id == servo_id],
                            "current_ma": round(ct.current_units_to_ma(servo.current_units), 1),
                            "peak_current_ma": round(ct.current_units_to_ma(servo.peak_current_units), 1),
                            "current_limit_ma": round(ct.current_units_to_ma(servo.current_limit_units), 1)}
        with self.lock:
            forces = {f: round(v, 4) for f, v in self.world.forces().items()}
            i2c = {"transfers": self.i2c_bus.transfers, "nacks": self.i2c_bus.nacks,
                   "failing": [f for f, ch in FINGER_CHANNELS.items() if self.i2c_bus.adcs[ch].failing]}
        link = {"hub": self.hub.status()} if self.tactile_link == "serial" else {"i2c": i2c}
        return {"world": self.world_name, "tactile_link": self.tactile_link, "forces_n": forces,
                "servos": servos, **link}

    def _fault_hub_unplug(self, seconds: float) -> str:
        return self.hub.unplug(seconds, self.clock_ns())

    def _fault_hub_replug(self) -> str:
        return self.hub.replug()

    def _fault_hub_garbage(self, bytes: int) -> str:  # noqa: A002 (the CLI's option name)
        return self.hub.garbage(bytes)

    def _fault_hub_crc(self, frames: int) -> str:
        return self.hub.corrupt(frames)

    def _adc(self, finger: str):
        if finger not in FINGER_CHANNELS:
            raise FaultError(f"finger {finger!r}: choose one of {', '.join(FINGERS)}")
        return self.i2c_bus.adcs[FINGER_CHANNELS[finger]]

    def _fault_i2c_nack(self, finger: str, count: int) -> str:
        adc = self._adc(finger)
        with self.lock:
            if count:
                adc.nack_next += int(count)
            else:
                adc.failing = True
        return f"{finger} ADC does not acknowledge{f' {count} time(s)' if count else ' until i2c-clear'}"

    def _fault_i2c_glitch(self, finger: str, count: int) -> str:
        with self.lock:
            self._adc(finger).glitch_next += int(count)
        return f"the next {count} read(s) of the {finger} ADC return all-zero bytes"

    def _fault_i2c_clear(self) -> str:
        with self.lock:
            for adc in self.i2c_bus.adcs.values():
                adc.failing, adc.nack_next, adc.glitch_next = False, 0, 0
        return "every ADC answers again"

    def _servo_id(self, motor: str) -> int:
        if motor not in MOTOR_IDS:
            raise FaultError(f"motor {motor!r}: choose one of {', '.join(MOTOR_NAMES)}")
        return MOTOR_IDS[motor]

    def _fault_servo_error(self, motor: str, bit: int | str) -> str:
        servo_id = self._servo_id(motor)
        names = {name: b for b, name in ct.HARDWARE_ERROR_BITS.items()}
        if isinstance(bit, str) and not bit.isdigit():
            if bit not in names:
                raise FaultError(f"bit {bit!r}: choose a number 0-7 or one of {', '.join(names)}")
            bit = names[bit]
        bit = int(bit)
        if not 0 <= bit <= 7:
            raise FaultError(f"bit {bit}: Hardware Error Status has bits 0-7")
        self.servos.inject_hardware_error(servo_id, bit)
        return f"{motor} (ID {servo_id}): {ct.describe_hardware_error(1 << bit)}"

    def _fault_servo_silent(self, motor: str, seconds: float) -> str:
        servo_id = self._servo_id(motor)
        with self._servo_faults_lock:
            self.servos.set_silent(servo_id, True)
            self._silent_until_ns[motor] = self.clock_ns() + int(seconds * 1e9) if seconds else None
        return f"{motor} (ID {servo_id}) off the bus{f' for {seconds:g} s' if seconds else ' until servo-clear'}"

    def _servo_back(self, motor: str) -> None:
        with self._servo_faults_lock:
            self.servos.set_silent(MOTOR_IDS[motor], False)
            self._silent_until_ns.pop(motor, None)

    def _fault_servo_clear(self, motor: str) -> str:
        motors = [motor] if motor else list(MOTOR_NAMES)
        for name in motors:
            servo_id = self._servo_id(name)
            self.servos.clear_hardware_error(servo_id)
            self._servo_back(name)
        return f"{', '.join(motors)}: hardware error cleared, answering"

    def _fault_power_cycle(self, motor: str) -> str:
        motors = [motor] if motor else list(MOTOR_NAMES)
        ids = [self._servo_id(name) for name in motors]
        for servo_id in ids:
            self.servos.power_cycle(servo_id)
        return (f"{', '.join(motors)}: power-cycled (torque off, RAM reset, position within one turn; "
                "the hand kept its pose)")

    def _fault_servo_baud(self, motor: str, rate: int) -> str:
        servo_id = self._servo_id(motor)
        try:
            self.servos.set_baud(servo_id, int(rate))
        except (TypeError, ValueError) as exc:
            raise FaultError(str(exc)) from None
        return f"{motor} (ID {servo_id}) set to {int(rate)} baud"

    def _fault_servo_place(self, motor: str, rad: float) -> str:
        servo_id = self._servo_id(motor)
        lo, hi = END_STOPS_RAD[motor]
        if not isinstance(rad, (int, float)) or isinstance(rad, bool) or not lo <= rad <= hi:
            raise FaultError(f"rad {rad!r}: {motor} moves between its end stops, {lo:g}..{hi:g} rad")
        self.servos.place(servo_id, self._mechanical_ticks(motor, rad))
        return f"{motor} (ID {servo_id}) turned by hand to {rad:g} rad (power-cycle to lose its turn count)"

    def _fault_push(self, dx_mm: float, dy_mm: float, dwidth_mm: float, duration_s: float) -> str:
        values = (dx_mm, dy_mm, dwidth_mm)
        if not all(math.isfinite(v) for v in values):
            raise FaultError(f"push {values}: every displacement must be a finite number of mm")
        with self.lock:
            start_s = self.world.elapsed_s(self.clock_ns() - self._world_start_ns)
            self.world.add_disturbance(Disturbance(start_s, duration_s, dx_mm, dy_mm, dwidth_mm))
        return f"push dx {dx_mm:g} mm, dy {dy_mm:g} mm, width {dwidth_mm:+g} mm over {duration_s:g} s"

    def _fault_world(self, name: str) -> str:
        try:
            world = world_for(name)
        except ValueError as exc:
            raise FaultError(str(exc)) from None
        with self.lock:
            self.world, self.world_name = world, name
            self._contacts = self._pads.source = HandWorldContactSource(world)
            self._world_start_ns = self.clock_ns()
        self._place_servos()
        return f"world {name}: motors at " + ", ".join(f"{n} {v:.3f} rad" for n, v in world.positions.items())

    def _place_servos(self) -> None:
        """Put the servos where the world's hand is, at rest: the experimenter posing the hand."""
        for name in MOTOR_NAMES:
            self.servos.place(MOTOR_IDS[name], self._mechanical_ticks(name, self.world.positions[name]))


_LINK_NAMES = {"serial": "fingertip hub's serial link", "i2c": "host's I2C bus"}


def _current_units(load_nm: float, params: SimMotorParams = SimMotorParams()) -> int:
    """Present Current (units of 2.69 mA) for a load torque on the shaft."""
    return int(round(load_nm / params.torque_constant_nm_per_a * 1000.0 / ct.MA_PER_CURRENT_UNIT))


def _check_positive(name: str, value: Any) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
        raise FaultError(f"{name} {value!r}: must be a number > 0")


def _check_non_negative(name: str, value: Any) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not value >= 0 or not math.isfinite(value):
        raise FaultError(f"{name} {value!r}: must be a number >= 0")


# a FaultArg's CLI type -> the emulator's check of a value that came over the socket
_VALUE_CHECKS: dict[Callable[[str], Any], Callable[[str, Any], None]] = {
    positive_int: _check_positive, non_negative_int: _check_non_negative, non_negative_float: _check_non_negative}


