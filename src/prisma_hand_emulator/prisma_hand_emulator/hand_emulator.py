"""The hand's hardware emulated in one process, for `hand.launch.py hardware:=emulated`.

Byte-level devices share one hand/world model, so a goal closes the loop through every real driver
path:
- the Dynamixel servos (IDs 1-3, Protocol 2.0) on a pseudo-terminal, `<dir>/servos`: motor_driver's
  dynamixel backend opens it through dynamixel-sdk (servos.py);
- the five pads on the tactile link the hand is wired with (`tactile_link`, as tactile_driver's
  `backend`; tactile_link.py): `serial`, the fingertip hub on a second pseudo-terminal, `<dir>/hub`,
  78-byte frames at the scan rate read by tactile_driver's serial backend through pyserial; or
  `i2c`, the pads' TCA9548A + MAX11617 bus served on `<dir>/i2c.sock`, reached by tactile_driver's
  i2c backend through smbus2 (`i2c_socket`). A robot has one of the two, so the emulator serves one.
Every scan period `tick` reads the servos' MECHANICAL angles, moves the world to them, puts the
pads' contacts through the pad model into counts (a hub frame or the ADC registers) and loads the
servos with the world's tendon torques.

Each device serves its link on its own: the servo emulator answers from its own thread, the I2C
bus from the socket server's, and the hub link is written by the tick under a lock of its own, so
a fault injected into one device (from the control socket's thread, while the tick runs) changes
that device only: an unplugged hub never stops the servos from answering.

Faults are applied by `apply`, as the emulator's control socket receives them (`prisma-hand-fault`;
the commands are fault_table.FAULTS): the hub unplugged and plugged back (a new pty behind the same
link, sequence restarting at 0 as a powered-down Arduino does), garbage bytes and CRC-corrupted
frames on the hub link, a pad's ADC not acknowledging or glitching on I2C, a servo hardware error
bit, a servo off the bus, a servo power cycle (`power-cycle`: RAM reset, the turn count lost, the
hand keeps its pose), a servo at another baud rate (`servo-baud`), a motor turned by hand
(`servo-place`), an external push on the object, a new scenario world (the experimenter placing
another object) and the object the hand let go put back between the open fingers (`replace-object`,
which the emulated hand's tactile_driver forwards its ~/replace_object to). A fault of the tactile
link the hand is not wired with (`i2c-nack` on the serial hub) is refused with the reason.

Nothing here reads ROS. Time is `clock_ns()` (monotonic); the world's time starts at 0 with each
scenario, so the scenarios' disturbances keep their timing.
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.control_socket import done, refused
from prisma_common.hand import FINGERS
from prisma_hand_sim.contact_source import HandWorldContactSource
from prisma_hand_sim.hand_world import Disturbance
from prisma_tactile_driver.i2c_socket import I2CSocketServer
from prisma_tactile_driver.pty_hub import PtyLink
from prisma_tactile_driver.sim_backend import SimHubBackend

from .emulator_control import ControlServer
from .fault_table import FaultError, fault_values
from .servos import EmulatedServos
from .settings import TACTILE_LINKS, EmulatorPaths, EmulatorSettings, world_for
from .tactile_link import HubLink, I2CPads


class EmulatedHand:
    def __init__(self, paths: EmulatorPaths, settings: EmulatorSettings | None = None,
                 clock_ns: Callable[[], int] | None = None, log: Callable[[str], None] | None = None) -> None:
        """`log` gets the servos' event lines (a stall at an end stop, a bus watchdog firing).
        `clock_ns`: a test's manual clock; by default time.monotonic_ns, the wall clock."""
        self.paths = paths
        self.settings = settings or EmulatorSettings()
        if self.settings.rate_hz <= 0:
            raise ValueError(f"rate_hz {self.settings.rate_hz}: must be > 0")
        if self.settings.tactile_link not in TACTILE_LINKS:
            raise ValueError(f"tactile_link {self.settings.tactile_link!r}: choose one of {', '.join(TACTILE_LINKS)}")
        self.tactile_link = self.settings.tactile_link
        wall_clock = clock_ns is None
        clock_ns = clock_ns or time.monotonic_ns
        self.clock_ns = clock_ns
        self.period_ns = int(round(1e9 / self.settings.rate_hz))
        self.lock = threading.Lock()  # world, pads and ADC registers: the tick vs the I2C server
        self.world = world_for(self.settings.world)
        self.world_name = self.settings.world
        self._world_start_ns = clock_ns()
        # the pads as the tactile driver's sim backend samples them, on this world
        self._contacts = HandWorldContactSource(self.world)
        self._pads = SimHubBackend(self._contacts, FINGERS, seed=self.settings.seed)
        self.i2c = I2CPads(self.lock)
        self.servos = EmulatedServos(self.settings.directions, self.settings.zero_ticks, clock_ns, log, wall_clock)
        self.hub = HubLink(paths.hub, self.settings.hub_buffer_bytes, np.random.default_rng(self.settings.seed))
        self._servo_link = PtyLink(paths.servos)
        self._i2c_server: Any = None
        self._control = ControlServer(paths.control, self.request)
        self._made_dirs: list[Path] = []  # the directories start() created, innermost last
        self.servos.pose(self.world.positions)
        self.servos.bus.power_cycle()  # switched on in the world's pose: each count within one turn

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
                self._i2c_server = I2CSocketServer(self.i2c.bus, self.paths.i2c, self.lock).start()
                started.append(self._i2c_server.close)
            else:
                self.hub.open()
                started.append(self.hub.close)
            self.servos.bus.start()
            started.append(self.servos.bus.close)
            self._servo_link.point_at(self.servos.bus.port_name)
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
        self.servos.bus.close()
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
        self.servos.expire_faults(now_ns)
        positions = self.servos.positions()
        with self.lock:
            self._contacts.update_joints(list(positions), list(positions.values()), now_ns - self._world_start_ns)
            [reading] = self._pads.read(now_ns - self._world_start_ns)
            counts = reading.counts
            if self.tactile_link == "i2c":
                self.i2c.load(counts)
            loads = self.world.motor_loads()
        self.servos.load(loads)
        if self.tactile_link == "serial":
            self.hub.send(counts, now_ns)

    # ---- the control socket ----------------------------------------------------------------
    def apply(self, command: str, **args: Any) -> str:
        """Carry out one fault command (`prisma-hand-fault --help`) through its `_fault_<name>`;
        returns what was done. FaultError for an unknown name or a value out of range, naming it."""
        values = fault_values(command, args, self.tactile_link)
        return getattr(self, "_fault_" + command.replace("-", "_"))(**values)

    def request(self, name: str, args: dict[str, Any]) -> dict[str, Any]:
        """One control-socket request: `status`, or a fault command with its arguments."""
        if name == "status":
            return {"ok": True, "status": self.status()}
        try:
            return done(self.apply(name, **args))
        except FaultError as exc:
            return refused(str(exc))
        except TypeError as exc:  # an argument the command does not take, or one it needs missing
            return refused(f"{name}: {exc}")

    def status(self) -> dict[str, Any]:
        """What the emulated hardware is doing, as plain data (JSON-ready)."""
        servos = self.servos.status()
        with self.lock:
            forces = {f: round(v, 4) for f, v in self.world.forces().items()}
            # what holds the object besides the pads: its stand (pinch_ball's lets go once held; the
            # ball then falls when the hand opens, until replace-object puts it back on the stand)
            held_object = {"name": self.world.obj.name,
                           "support_n_per_mm": round(self.world.state.fixture_n_per_mm, 4)}
        link = {"hub": self.hub.status()} if self.tactile_link == "serial" else {"i2c": self.i2c.status()}
        return {"world": self.world_name, "tactile_link": self.tactile_link, "forces_n": forces,
                "object": held_object, "servos": servos, **link}

    # ---- fault commands (fault_table.FAULTS), each carried out by the device it is about -------
    def _fault_hub_unplug(self, seconds: float) -> str:
        return self.hub.unplug(seconds, self.clock_ns())

    def _fault_hub_replug(self) -> str:
        return self.hub.replug()

    def _fault_hub_garbage(self, bytes: int) -> str:  # noqa: A002 (the CLI's option name)
        return self.hub.garbage(bytes)

    def _fault_hub_crc(self, frames: int) -> str:
        return self.hub.corrupt(frames)

    def _fault_i2c_nack(self, finger: str, count: int) -> str:
        return self.i2c.nack(finger, count)

    def _fault_i2c_glitch(self, finger: str, count: int) -> str:
        return self.i2c.glitch(finger, count)

    def _fault_i2c_clear(self) -> str:
        return self.i2c.clear()

    def _fault_servo_error(self, motor: str, bit: int | str) -> str:
        return self.servos.error(motor, bit)

    def _fault_servo_silent(self, motor: str, seconds: float) -> str:
        return self.servos.silent(motor, seconds)

    def _fault_servo_clear(self, motor: str) -> str:
        return self.servos.clear(motor)

    def _fault_power_cycle(self, motor: str) -> str:
        return self.servos.power_cycle(motor)

    def _fault_servo_baud(self, motor: str, rate: int) -> str:
        return self.servos.baud(motor, rate)

    def _fault_servo_place(self, motor: str, rad: float) -> str:
        return self.servos.place(motor, rad)

    def _fault_push(self, dx_mm: float, dy_mm: float, dwidth_mm: float, duration_s: float) -> str:
        values = (dx_mm, dy_mm, dwidth_mm)
        if not all(math.isfinite(v) for v in values):
            raise FaultError(f"push {values}: every displacement must be a finite number of mm")
        with self.lock:
            start_s = self.world.elapsed_s(self.clock_ns() - self._world_start_ns)
            self.world.add_disturbance(Disturbance(start_s, duration_s, dx_mm, dy_mm, dwidth_mm))
        return f"push dx {dx_mm:g} mm, dy {dy_mm:g} mm, width {dwidth_mm:+g} mm over {duration_s:g} s"

    def _fault_replace_object(self) -> str:
        """The world's object back where it was presented (HandWorld.replace_object: refused while a
        finger touches it, or in an empty hand), as the sim hand's tactile_driver does in its world."""
        with self.lock:
            try:
                return self.world.replace_object()
            except ValueError as exc:
                raise FaultError(str(exc)) from None  # the sim hand's words (prisma-hand-fault names the command)

    def _fault_world(self, name: str, pushes: str) -> str:
        try:
            world = world_for(name)
        except ValueError as exc:
            raise FaultError(str(exc)) from None
        pushes_removed = pushes == "off" and bool(world.disturbances)
        if pushes_removed:
            world.remove_disturbances()
        with self.lock:
            self.world, self.world_name = world, name
            self._contacts = self._pads.source = HandWorldContactSource(world)
            self._world_start_ns = self.clock_ns()
        self.servos.pose(world.positions)  # the experimenter posing the hand as that world starts
        timed = " (its timed pushes off)" if pushes_removed else ""
        return f"world {name}{timed}: motors at " + ", ".join(f"{n} {v:.3f} rad" for n, v in world.positions.items())
