"""Dynamixel X-series servos emulated behind a pseudo-terminal (test and bench support).

The emulator owns the master end of a pty; `port_name` is the slave device that dynamixel-sdk's
PortHandler opens, so the SDK's real read/write/txRx code runs against it. It answers ping, read,
write, sync read and sync write with Protocol 2.0 status packets (CRC and byte stuffing from
`dynamixel_packets`), keeps a control table per ID, integrates Goal Velocity (velocity mode) or moves
toward Goal Position at Profile Velocity (position modes) into Present Position, and rejects EEPROM
writes while torque is on (Access error), as the firmware does.

Faults for tests: `inject_hardware_error(id, bit)` sets Hardware Error Status and the alert bit of
every later status packet (`clear_hardware_error` is the power cycle that clears it);
`drop_status(id, n)` processes the next n instructions to that ID but sends no status packet (the
host sees a timeout); `set_silent(id, True)` takes the servo off the bus (a cut cable): it neither
acts on nor answers anything until set back.

Time comes from `clock()` (seconds); tests pass a manual clock so motion is deterministic.
"""
from __future__ import annotations

import os
import select
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field

from . import control_table as ct
from .dynamixel_packets import (
    ERR_ACCESS,
    ERR_DATA_LENGTH,
    ERR_INSTRUCTION,
    INST_PING,
    INST_READ,
    INST_REBOOT,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    Packet,
    PacketDecoder,
    encode_status,
)

FIRMWARE_VERSION = 46


class ManualClock:
    """A clock the test advances explicitly."""

    def __init__(self, start_s: float = 0.0) -> None:
        self.now_s = start_s

    def __call__(self) -> float:
        return self.now_s

    def advance(self, dt_s: float) -> None:
        self.now_s += dt_s


@dataclass
class EmulatedServo:
    servo_id: int
    table: bytearray = field(default_factory=lambda: bytearray(ct.CONTROL_TABLE_SIZE))
    position_ticks: float = 0.0  # continuous position; Present Position is its rounding
    load_current_units: int = 0  # added to Present Current while torque is on
    drop_status: int = 0
    silent: bool = False  # processes nothing and answers nothing: a servo off the bus
    instructions: int = 0

    def __post_init__(self) -> None:
        self.write_int(ct.ADDR_MODEL_NUMBER, 2, ct.MODEL_XM430_W350)
        self.write_int(ct.ADDR_ID, 1, self.servo_id)
        self.write_int(ct.ADDR_BAUD_RATE, 1, 3)  # 1 Mbps
        self.write_int(ct.ADDR_OPERATING_MODE, 1, ct.MODE_VELOCITY)
        self.write_int(ct.ADDR_VELOCITY_LIMIT, 4, ct.VELOCITY_LIMIT_MAX)
        self.write_int(ct.ADDR_MAX_POSITION_LIMIT, 4, 4095)
        self.write_int(ct.ADDR_MIN_POSITION_LIMIT, 4, 0)
        self.write_int(ct.ADDR_PRESENT_TEMPERATURE, 1, 31)

    def read_int(self, address: int, n: int, signed: bool = False) -> int:
        return int.from_bytes(self.table[address : address + n], "little", signed=signed)

    def write_int(self, address: int, n: int, value: int) -> None:
        self.table[address : address + n] = ct.to_unsigned(value, n).to_bytes(n, "little")

    @property
    def torque_on(self) -> bool:
        return bool(self.table[ct.ADDR_TORQUE_ENABLE])

    @property
    def hardware_error(self) -> int:
        return self.table[ct.ADDR_HARDWARE_ERROR_STATUS]

    def set_position_ticks(self, ticks: float) -> None:
        self.position_ticks = float(ticks)
        self._publish_present(0)

    def _publish_present(self, velocity_units: int) -> None:
        self.write_int(ct.ADDR_PRESENT_POSITION, 4, int(round(self.position_ticks)))
        self.write_int(ct.ADDR_PRESENT_VELOCITY, 4, velocity_units)
        current = self.load_current_units if self.torque_on else 0
        # moving costs current too: a small speed term keeps the reading plausible
        current += int(abs(velocity_units) * 0.5) if self.torque_on else 0
        self.write_int(ct.ADDR_PRESENT_CURRENT, 2, current)

    def integrate(self, dt_s: float) -> None:
        """Advance the motion by dt_s under the current goals (ideal velocity tracking)."""
        if dt_s <= 0:
            self._publish_present(self.read_int(ct.ADDR_PRESENT_VELOCITY, 4, signed=True) if self.torque_on else 0)
            return
        velocity_units = 0
        limit = self.read_int(ct.ADDR_VELOCITY_LIMIT, 4)
        if self.torque_on:
            mode = self.table[ct.ADDR_OPERATING_MODE]
            if mode == ct.MODE_VELOCITY:
                velocity_units = max(-limit, min(limit, self.read_int(ct.ADDR_GOAL_VELOCITY, 4, signed=True)))
                self.position_ticks += _ticks_per_s(velocity_units) * dt_s
            elif mode in (ct.MODE_POSITION, ct.MODE_EXTENDED_POSITION):
                profile = self.read_int(ct.ADDR_PROFILE_VELOCITY, 4) or limit
                goal = self.read_int(ct.ADDR_GOAL_POSITION, 4, signed=True)
                step = _ticks_per_s(profile) * dt_s
                error = goal - self.position_ticks
                if abs(error) <= step:
                    self.position_ticks = float(goal)
                    velocity_units = 0
                else:
                    self.position_ticks += step if error > 0 else -step
                    velocity_units = profile if error > 0 else -profile
        self._publish_present(velocity_units)


def _ticks_per_s(velocity_units: int) -> float:
    return velocity_units * ct.RPM_PER_VELOCITY_UNIT / 60.0 * ct.TICKS_PER_REV


@dataclass
class ServoPresent:
    position_ticks: float
    velocity_rpm: float
    torque_on: bool
    hardware_error: int


@dataclass
class EmulatorStats:
    instructions: int = 0
    status_sent: int = 0
    status_dropped: int = 0
    access_errors: int = 0


class DynamixelEmulator:
    """Servos with the given IDs on one emulated bus. Use as a context manager."""

    def __init__(self, ids: list[int] | tuple[int, ...], clock: Callable[[], float] | None = None) -> None:
        self.servos = {i: EmulatedServo(i) for i in ids}
        self.clock = clock or time.monotonic
        self.stats = EmulatorStats()
        self.decoder = PacketDecoder()
        self._last_s = self.clock()
        self._lock = threading.Lock()
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        self.port_name = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="dynamixel-emulator", daemon=True)

    # ---- lifecycle -------------------------------------------------------------------------
    def start(self) -> DynamixelEmulator:
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and close the pty; safe to call twice, or without start()."""
        self._stop.set()
        if self._thread.ident is not None:
            self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            if fd < 0:
                continue  # closed before: the number may be another file's by now
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1

    def __enter__(self) -> DynamixelEmulator:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- test controls ---------------------------------------------------------------------
    def inject_hardware_error(self, servo_id: int, bit: int) -> None:
        with self._lock:
            servo = self.servos[servo_id]
            servo.write_int(ct.ADDR_HARDWARE_ERROR_STATUS, 1, servo.hardware_error | (1 << bit))

    def clear_hardware_error(self, servo_id: int) -> None:
        with self._lock:
            self.servos[servo_id].write_int(ct.ADDR_HARDWARE_ERROR_STATUS, 1, 0)

    def set_silent(self, servo_id: int, silent: bool) -> None:
        with self._lock:
            self.servos[servo_id].silent = silent

    def present(self) -> dict[int, ServoPresent]:
        """What each servo is doing, integrated to now."""
        with self._lock:
            self._integrate()
            return {i: ServoPresent(s.position_ticks,
                                    ct.units_to_rpm(s.read_int(ct.ADDR_PRESENT_VELOCITY, 4, signed=True)),
                                    s.torque_on, s.hardware_error) for i, s in self.servos.items()}

    def drop_status(self, servo_id: int, count: int = 1) -> None:
        with self._lock:
            self.servos[servo_id].drop_status += count

    def set_load(self, servo_id: int, current_units: int) -> None:
        with self._lock:
            self.servos[servo_id].load_current_units = current_units
            self.servos[servo_id].integrate(0.0)

    def set_position_ticks(self, servo_id: int, ticks: float) -> None:
        with self._lock:
            self.servos[servo_id].set_position_ticks(ticks)

    def place(self, servo_id: int, ticks: int) -> None:
        """The servo moved there by hand and told to stay: present and goal position at `ticks`,
        goal velocity 0."""
        with self._lock:
            servo = self.servos[servo_id]
            servo.write_int(ct.ADDR_GOAL_VELOCITY, 4, 0)
            servo.write_int(ct.ADDR_GOAL_POSITION, 4, ticks)
            servo.set_position_ticks(ticks)

    def sync(self, timeout_s: float = 1.0) -> None:
        """Block until every byte the host has written so far is processed. Broadcast writes have
        no status packet, so a test with a manual clock calls this before advancing the clock."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                pending, _, _ = select.select([self._master], [], [], 0)
                if not pending:
                    return
            time.sleep(0.0005)
        raise TimeoutError("emulator did not drain its input")

    def update(self) -> None:
        """Integrate motion up to clock() (also done on every received packet)."""
        with self._lock:
            self._integrate()

    # ---- protocol --------------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], 0.05)
            except (OSError, ValueError):
                return
            if not ready:
                continue
            # read under the lock so that `sync()` can tell "nothing in flight" reliably
            with self._lock:
                try:
                    data = os.read(self._master, 4096)
                except OSError:
                    return
                for packet in self.decoder.feed(data):
                    self._integrate()
                    reply = self._handle(packet)
                    if reply:
                        os.write(self._master, reply)

    def _integrate(self) -> None:
        now = self.clock()
        dt = now - self._last_s
        self._last_s = now
        for servo in self.servos.values():
            servo.integrate(dt)

    def _status(self, servo: EmulatedServo, error: int = 0, params: bytes = b"") -> bytes:
        if servo.drop_status > 0:
            servo.drop_status -= 1
            self.stats.status_dropped += 1
            return b""
        if servo.hardware_error:
            error |= ct.STATUS_ALERT_BIT
        self.stats.status_sent += 1
        return encode_status(servo.servo_id, error, params)

    def _handle(self, packet: Packet) -> bytes:
        self.stats.instructions += 1
        inst, p = packet.instruction, packet.params
        if inst == INST_SYNC_READ:
            return self._sync_read(p)
        if inst == INST_SYNC_WRITE:
            self._sync_write(p)
            return b""  # broadcast: no status
        servo = self.servos.get(packet.packet_id)
        if servo is None or servo.silent:
            return b""  # nobody on the bus with that ID
        servo.instructions += 1
        if inst == INST_PING:
            model = servo.read_int(ct.ADDR_MODEL_NUMBER, 2)
            return self._status(servo, 0, model.to_bytes(2, "little") + bytes([FIRMWARE_VERSION]))
        if inst == INST_READ:
            if len(p) != 4:
                return self._status(servo, ERR_DATA_LENGTH)
            address, length = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
            if address + length > ct.CONTROL_TABLE_SIZE:
                return self._status(servo, ERR_ACCESS)
            return self._status(servo, 0, bytes(servo.table[address : address + length]))
        if inst == INST_WRITE:
            if len(p) < 3:
                return self._status(servo, ERR_DATA_LENGTH)
            address = int.from_bytes(p[0:2], "little")
            return self._status(servo, self._write(servo, address, p[2:]))
        if inst == INST_REBOOT:
            servo.write_int(ct.ADDR_HARDWARE_ERROR_STATUS, 1, 0)
            servo.write_int(ct.ADDR_TORQUE_ENABLE, 1, 0)
            return self._status(servo)
        return self._status(servo, ERR_INSTRUCTION)

    def _write(self, servo: EmulatedServo, address: int, data: bytes) -> int:
        if address + len(data) > ct.CONTROL_TABLE_SIZE:
            return ERR_ACCESS
        if address < ct.EEPROM_END and servo.torque_on:
            self.stats.access_errors += 1
            return ERR_ACCESS  # EEPROM is locked while torque is on
        if address <= ct.ADDR_PRESENT_CURRENT < address + len(data):
            return ERR_ACCESS  # read-only area
        servo.table[address : address + len(data)] = data
        if (address <= ct.ADDR_GOAL_POSITION < address + len(data)
                or address <= ct.ADDR_TORQUE_ENABLE < address + len(data)):
            servo.integrate(0.0)
        return 0

    def _sync_read(self, p: bytes) -> bytes:
        address, length = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
        out = bytearray()
        for servo_id in p[4:]:
            servo = self.servos.get(servo_id)
            if servo is None or servo.silent:
                continue
            servo.instructions += 1
            out += self._status(servo, 0, bytes(servo.table[address : address + length]))
        return bytes(out)

    def _sync_write(self, p: bytes) -> None:
        address, length = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
        body = p[4:]
        for offset in range(0, len(body) - length, length + 1):
            servo = self.servos.get(body[offset])
            if servo is not None and not servo.silent:
                servo.instructions += 1
                self._write(servo, address, body[offset + 1 : offset + 1 + length])
