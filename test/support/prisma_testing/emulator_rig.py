"""The emulated hand on a manual clock, reached through the real host-side driver code: `Rig`
starts an EmulatedHand (prisma_hand_emulator) in a directory and opens DynamixelBus (dynamixel-sdk)
on its servos, SerialHubBackend (pyserial + FrameParser) on its hub or I2CHubBackend over
SocketSMBus on its I2C socket, and closes them in reverse. Ticks and servo motion are deterministic.
Shared by prisma_hand_emulator's tests (their `rig` fixture, conftest.py)."""
from __future__ import annotations

import contextlib
import math
import os
import subprocess
import time

from prisma_hand_emulator.hand_emulator import EmulatedHand
from prisma_hand_emulator.settings import EmulatorPaths, EmulatorSettings
from prisma_hand_emulator.tactile_link import FINGER_CHANNELS
from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import BusError, MotorMap
from prisma_motor_driver.dynamixel_backend import DynamixelBus
from prisma_tactile_driver.i2c_backend import I2CHubBackend
from prisma_tactile_driver.i2c_socket import SocketSMBus
from prisma_tactile_driver.protocol import ALL_FINGERS_MASK, frame_size
from prisma_tactile_driver.serial_backend import SerialHubBackend

from .node_process import console_script

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
