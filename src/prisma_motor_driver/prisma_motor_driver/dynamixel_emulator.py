"""Dynamixel X-series servos emulated behind a pseudo-terminal (test and bench support).

The emulator owns the master end of a pty; `port_name` is the slave device that dynamixel-sdk's
PortHandler opens, so the SDK's real read/write/txRx code runs against it. It answers ping (also
broadcast), read, write, sync read, sync write and reboot with Protocol 2.0 status packets (CRC and
byte stuffing from `dynamixel_packets`) and keeps a control table per ID. What it models, after the
X-series e-Manual (XM430-W350):

- Motion, integrated lazily (on every packet, `present()` and `update()`): velocity mode integrates
  Goal Velocity; position, extended position and current-based position modes move toward Goal
  Position at Profile Velocity (0 = Velocity Limit). Moving (122) is 1 while the servo moves.
- Positions: the MECHANICAL position (`mechanical_ticks`, the spool's real angle, continuous) and
  the REPORTED one (Present Position) differ by the multi-turn count lost at power-up: Present
  Position = mechanical - turn_offset + Homing Offset (20), where a power-up puts the turn count so
  that Present Position comes up within one turn (0..4095) plus Homing Offset. Goal Position is in
  reported coordinates.
- Power-up (construction, `power_cycle`, the reboot instruction): RAM to its power-up values (Torque
  Enable 0, LED 0, Bus Watchdog 0, goals 0, Profile Velocity 0, Hardware Error Status 0), EEPROM
  kept (ID, Baud Rate, Operating Mode, limits, Homing Offset, Current Limit).
- EEPROM writes while torque is on get the Access error; Present values are read-only.
- Current Limit (38, default CURRENT_LIMIT_MAX_UNITS, above it: Data Range error): Present Current
  never exceeds it in any mode; Goal Current beyond +-Current Limit gets the Data Limit error, and
  Goal Velocity beyond +-Velocity Limit too (the e-Manual's ranges for both). In current-based
  position mode the pull is min(|Goal Current|, Current Limit).
- Bus Watchdog (98): with Torque Enable 1 and a value 1..127 (x 20 ms), a gap between two
  instruction packets the servo takes part in (addressed to it, a sync read or write naming it, a
  broadcast ping, which it answers) longer than the period stops the servo at that exact instant
  (the integration is split there): velocity mode stops, position modes hold where they were. Bus
  Watchdog then reads -1 and every goal register (GOAL_REGISTERS) refuses writes with the Data
  Range error; writing 0 clears it (writing 1..127 while it reads -1 is refused: clear first), and
  the servo moves again only for a goal written after that. Each firing is kept in
  `watchdog_firings`. Values outside -1..127 get the Data Range error.
- Mechanical end stops (`set_end_stops`, mechanical ticks): motion never passes them; pushing into
  one gives Present Velocity 0 and the stall current, the pull the mode allows. Each servo keeps its
  peak |Present Current| and when it was reached; a stall is logged (`events`, and `log`).
- Baud Rate (8): a servo hears (and answers) only packets sent at its rate (BAUD_RATES); the host's
  rate is read from the pty slave's termios (TCGETS2, so pyserial's custom rates too).
- LED (65): plain storage.

Faults for tests: `inject_hardware_error(id, bit)` sets Hardware Error Status and the alert bit of
every later status packet (`clear_hardware_error` clears the bits alone, as a reboot would without
the rest of the power cycle; `power_cycle` is the whole thing); `drop_status(id, n)` processes the
next n instructions to that ID but sends no status packet (the host sees a timeout);
`set_silent(id, True)` takes the servo off the bus (a cut cable): it neither acts on nor answers
anything until set back (its watchdog, if armed, fires); `set_baud(id, rate)` configures it at
another rate (by another tool): silent at the host's.

Time comes from `clock()` (seconds); tests pass a manual clock so motion is deterministic.
"""
from __future__ import annotations

import array
import collections
import fcntl
import math
import os
import select
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field

from . import control_table as ct
from .dynamixel_packets import (
    BROADCAST_ID,
    ERR_ACCESS,
    ERR_DATA_LENGTH,
    ERR_DATA_LIMIT,
    ERR_DATA_RANGE,
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
POSITION_MODES = (ct.MODE_POSITION, ct.MODE_EXTENDED_POSITION, ct.MODE_CURRENT_BASED_POSITION)
# linux/asm-generic ioctl TCGETS2 (struct termios2, 44 bytes): reads custom (BOTHER) rates as well
_TCGETS2 = 0x802C542A
_SPEEDS = {getattr(termios, f"B{rate}"): rate for rate in ct.BAUD_RATES.values() if hasattr(termios, f"B{rate}")}


class ManualClock:
    """A clock the test advances explicitly."""

    def __init__(self, start_s: float = 0.0) -> None:
        self.now_s = start_s

    def __call__(self) -> float:
        return self.now_s

    def advance(self, dt_s: float) -> None:
        self.now_s += dt_s


@dataclass(frozen=True)
class WatchdogFiring:
    """One Bus Watchdog stop: the instant (clock seconds) and where the servo stopped."""

    servo_id: int
    at_s: float
    position_ticks: float  # reported (Present Position)
    mechanical_ticks: float


@dataclass
class EmulatedServo:
    servo_id: int
    table: bytearray = field(default_factory=lambda: bytearray(ct.CONTROL_TABLE_SIZE))
    mechanical_ticks: float = 0.0  # the spool's real angle, continuous; never reset
    turn_offset: int = 0  # the multi-turn count lost at the last power-up (a multiple of 4096)
    end_stops: tuple[float | None, float | None] = (None, None)  # mechanical ticks, lo and hi
    load_current_units: int = 0  # added to Present Current while torque is on
    drop_status: int = 0
    silent: bool = False  # processes nothing and answers nothing: a servo off the bus
    instructions: int = 0
    last_instruction_s: float = 0.0  # the Bus Watchdog measures from here
    halted: bool = False  # stopped by the Bus Watchdog; a goal written after clearing releases it
    hold_ticks: float = 0.0  # mechanical position held while halted (position modes)
    stalled: bool = False
    peak_current_units: int = 0  # |Present Current|
    peak_current_at_s: float | None = None

    def __post_init__(self) -> None:
        self.write_int(ct.ADDR_MODEL_NUMBER, 2, ct.MODEL_XM430_W350)
        self.write_int(ct.ADDR_FIRMWARE_VERSION, 1, FIRMWARE_VERSION)
        self.write_int(ct.ADDR_ID, 1, self.servo_id)
        self.write_int(ct.ADDR_BAUD_RATE, 1, 3)  # 1 Mbps
        self.write_int(ct.ADDR_OPERATING_MODE, 1, ct.MODE_VELOCITY)
        self.write_int(ct.ADDR_CURRENT_LIMIT, 2, ct.CURRENT_LIMIT_MAX_UNITS)
        self.write_int(ct.ADDR_VELOCITY_LIMIT, 4, ct.VELOCITY_LIMIT_MAX)
        self.write_int(ct.ADDR_MAX_POSITION_LIMIT, 4, 4095)
        self.write_int(ct.ADDR_MIN_POSITION_LIMIT, 4, 0)
        self.power_up(0.0)

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

    @property
    def bus_watchdog(self) -> int:
        return self.read_int(ct.ADDR_BUS_WATCHDOG, 1, signed=True)

    @property
    def current_limit_units(self) -> int:
        return self.read_int(ct.ADDR_CURRENT_LIMIT, 2)

    @property
    def baud_rate(self) -> int:
        return ct.BAUD_RATES.get(self.table[ct.ADDR_BAUD_RATE], 0)

    @property
    def _reported_offset(self) -> int:
        """reported - mechanical."""
        return self.read_int(ct.ADDR_HOMING_OFFSET, 4, signed=True) - self.turn_offset

    @property
    def position_ticks(self) -> float:
        """The REPORTED position, continuous (Present Position is its rounding)."""
        return self.mechanical_ticks + self._reported_offset

    def set_position_ticks(self, ticks: float) -> None:
        """Put the REPORTED position at `ticks` (the mechanical one moves with it, the turn count
        stays): a test's shortcut. Not clamped to the end stops."""
        self.mechanical_ticks = float(ticks) - self._reported_offset
        self.integrate(0.0, self.last_instruction_s)

    def power_up(self, now_s: float) -> None:
        """RAM to its power-up values, EEPROM kept; Present Position within one turn + Homing Offset."""
        eeprom = bytes(self.table[: ct.EEPROM_END])
        self.table[:] = bytes(ct.CONTROL_TABLE_SIZE)
        self.table[: ct.EEPROM_END] = eeprom
        self.write_int(ct.ADDR_PRESENT_TEMPERATURE, 1, 31)
        self.turn_offset = math.floor(round(self.mechanical_ticks) / ct.TICKS_PER_REV) * ct.TICKS_PER_REV
        self.halted = self.stalled = False
        self.last_instruction_s = now_s
        self.integrate(0.0, now_s)

    def watchdog_deadline(self) -> float | None:
        """When the Bus Watchdog fires if no instruction comes, or None (off, fired, torque off)."""
        units = self.bus_watchdog
        if units <= 0 or not self.torque_on:
            return None
        return self.last_instruction_s + units * ct.WATCHDOG_UNIT_S

    def fire_watchdog(self, at_s: float) -> WatchdogFiring:
        self.write_int(ct.ADDR_BUS_WATCHDOG, 1, ct.WATCHDOG_FIRED)
        self.halted, self.hold_ticks = True, self.mechanical_ticks
        self.integrate(0.0, at_s)
        return WatchdogFiring(self.servo_id, at_s, self.position_ticks, self.mechanical_ticks)

    def _pull_units(self, mode: int) -> int:
        """The most current the mode lets the motor draw."""
        limit = self.current_limit_units
        if mode == ct.MODE_CURRENT_BASED_POSITION:
            return min(abs(self.read_int(ct.ADDR_GOAL_CURRENT, 2, signed=True)), limit)
        return limit

    def integrate(self, dt_s: float, now_s: float) -> str | None:
        """Advance the motion by dt_s (>= 0) under the current goals (ideal tracking) and publish the
        Present values at now_s. Returns a log line when the servo has just stalled at an end stop."""
        velocity_units, push = 0, 0  # push: the direction the motor drives in (+1, -1, 0)
        mode = self.table[ct.ADDR_OPERATING_MODE]
        limit = self.read_int(ct.ADDR_VELOCITY_LIMIT, 4)
        if self.torque_on:
            if mode == ct.MODE_VELOCITY:
                goal = 0 if self.halted else self.read_int(ct.ADDR_GOAL_VELOCITY, 4, signed=True)
                velocity_units = max(-limit, min(limit, goal))
                push = (velocity_units > 0) - (velocity_units < 0)
                self.mechanical_ticks += _ticks_per_s(velocity_units) * dt_s
            elif mode in POSITION_MODES:
                profile = self.read_int(ct.ADDR_PROFILE_VELOCITY, 4) or limit
                target = self.hold_ticks if self.halted else (
                    self.read_int(ct.ADDR_GOAL_POSITION, 4, signed=True) - self._reported_offset)
                step = _ticks_per_s(profile) * dt_s
                error = target - self.mechanical_ticks
                push = (error > 0) - (error < 0)
                if abs(error) <= step:
                    self.mechanical_ticks = float(target)
                else:
                    self.mechanical_ticks += step * push
                    velocity_units = profile * push
        lo, hi = self.end_stops
        at_stop = None
        if lo is not None and self.mechanical_ticks <= lo:
            self.mechanical_ticks, at_stop = float(lo), ("lo", -1)
        if hi is not None and self.mechanical_ticks >= hi:
            self.mechanical_ticks, at_stop = float(hi), ("hi", 1)
        pull = self._pull_units(mode)
        stalled = self.torque_on and at_stop is not None and push == at_stop[1]
        if stalled:
            velocity_units, current = 0, pull * push
        elif self.torque_on:
            # moving costs current too: a small speed term keeps the reading plausible
            current = self.load_current_units + int(abs(velocity_units) * 0.5)
            current = max(-pull, min(pull, current))
        else:
            current = 0
        self.write_int(ct.ADDR_PRESENT_POSITION, 4, int(round(self.position_ticks)))
        self.write_int(ct.ADDR_PRESENT_VELOCITY, 4, velocity_units)
        self.write_int(ct.ADDR_PRESENT_CURRENT, 2, current)
        self.write_int(ct.ADDR_MOVING, 1, int(velocity_units != 0))
        if abs(current) > self.peak_current_units:
            self.peak_current_units, self.peak_current_at_s = abs(current), now_s
        line = None
        if stalled and not self.stalled and at_stop is not None:
            line = (f"servo {self.servo_id}: stalled at its {at_stop[0]} end stop (mechanical "
                    f"{self.mechanical_ticks:.0f} ticks) at t={now_s:.3f} s, pulling "
                    f"{ct.current_units_to_ma(pull):.0f} mA ({ct.MODE_NAMES.get(mode, mode)} mode)")
        self.stalled = stalled
        return line


def _ticks_per_s(velocity_units: int) -> float:
    return velocity_units * ct.RPM_PER_VELOCITY_UNIT / 60.0 * ct.TICKS_PER_REV


def _int(table: bytearray, address: int, n: int, signed: bool = False) -> int:
    return int.from_bytes(table[address : address + n], "little", signed=signed)


def _overlaps(address: int, length: int, register: int, size: int) -> bool:
    return address < register + size and register < address + length


@dataclass
class ServoPresent:
    position_ticks: float  # reported: Present Position, continuous
    velocity_rpm: float
    torque_on: bool
    hardware_error: int
    mechanical_ticks: float = 0.0  # the spool's real angle (what the hand's world follows)
    current_units: int = 0
    bus_watchdog: int = 0
    led: int = 0
    peak_current_units: int = 0
    current_limit_units: int = ct.CURRENT_LIMIT_MAX_UNITS


@dataclass
class EmulatorStats:
    instructions: int = 0
    status_sent: int = 0
    status_dropped: int = 0
    access_errors: int = 0
    wrong_baud: int = 0  # instructions a servo did not hear: sent at another rate than its own


class DynamixelEmulator:
    """Servos with the given IDs on one emulated bus. Use as a context manager.

    `log` receives each event line (a stall at an end stop, a watchdog firing) as it happens; the
    last ones are kept in `events` too."""

    def __init__(self, ids: list[int] | tuple[int, ...], clock: Callable[[], float] | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        self.clock = clock or time.monotonic
        self._last_s = self.clock()
        self.servos = {i: EmulatedServo(i) for i in ids}
        for servo in self.servos.values():
            servo.power_up(self._last_s)  # the emulator's start is a power-up
        self.stats = EmulatorStats()
        self.decoder = PacketDecoder()
        self.watchdog_firings: list[WatchdogFiring] = []
        self.events: collections.deque[str] = collections.deque(maxlen=1000)
        self._log = log
        self._host_rate: int | None = None
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
        """Hardware Error Status back to 0 and nothing else (`power_cycle` is the whole power cycle)."""
        with self._lock:
            self.servos[servo_id].write_int(ct.ADDR_HARDWARE_ERROR_STATUS, 1, 0)

    def power_cycle(self, servo_id: int | None = None) -> None:
        """Power off and on (every servo when servo_id is None): RAM to power-up values, EEPROM kept,
        the multi-turn count lost (Present Position within one turn + Homing Offset); the mechanical
        position stays where it is."""
        with self._lock:
            self._integrate()
            for i in ([servo_id] if servo_id is not None else list(self.servos)):
                self.servos[i].power_up(self._last_s)

    def set_silent(self, servo_id: int, silent: bool) -> None:
        with self._lock:
            self.servos[servo_id].silent = silent

    def set_baud(self, servo_id: int, rate: int) -> None:
        """The servo's Baud Rate register set to `rate` (one of BAUD_RATES' rates) by another tool."""
        codes = {r: code for code, r in ct.BAUD_RATES.items()}
        if rate not in codes:
            raise ValueError(f"baud rate {rate}: an X-series servo runs at one of "
                             f"{', '.join(str(r) for r in ct.BAUD_RATES.values())}")
        with self._lock:
            self.servos[servo_id].write_int(ct.ADDR_BAUD_RATE, 1, codes[rate])

    def set_end_stops(self, servo_id: int, lo: float | None, hi: float | None) -> None:
        """Mechanical end stops in mechanical ticks (None: no stop on that side)."""
        if lo is not None and hi is not None and lo > hi:
            raise ValueError(f"end stops {lo}..{hi}: lo must not be above hi")
        with self._lock:
            self._integrate()
            servo = self.servos[servo_id]
            servo.end_stops = (lo, hi)
            self._note(servo.integrate(0.0, self._last_s))

    def present(self) -> dict[int, ServoPresent]:
        """What each servo is doing, integrated to now."""
        with self._lock:
            self._integrate()
            return {i: ServoPresent(s.position_ticks,
                                    ct.units_to_rpm(s.read_int(ct.ADDR_PRESENT_VELOCITY, 4, signed=True)),
                                    s.torque_on, s.hardware_error, s.mechanical_ticks,
                                    s.read_int(ct.ADDR_PRESENT_CURRENT, 2, signed=True), s.bus_watchdog,
                                    s.table[ct.ADDR_LED], s.peak_current_units, s.current_limit_units)
                    for i, s in self.servos.items()}

    def drop_status(self, servo_id: int, count: int = 1) -> None:
        with self._lock:
            self.servos[servo_id].drop_status += count

    def set_load(self, servo_id: int, current_units: int) -> None:
        with self._lock:
            self.servos[servo_id].load_current_units = current_units
            self._note(self.servos[servo_id].integrate(0.0, self._last_s))

    def set_position_ticks(self, servo_id: int, ticks: float) -> None:
        """The REPORTED position set to `ticks` (see EmulatedServo.set_position_ticks)."""
        with self._lock:
            self.servos[servo_id].set_position_ticks(ticks)

    def place(self, servo_id: int, mechanical_ticks: float) -> None:
        """The servo moved there by hand (MECHANICAL ticks; the powered servo's multi-turn count
        follows) and told to stay: goal velocity 0, goal position where it now is (reported)."""
        with self._lock:
            self._integrate()
            servo = self.servos[servo_id]
            servo.mechanical_ticks = float(mechanical_ticks)
            servo.hold_ticks = servo.mechanical_ticks
            servo.write_int(ct.ADDR_GOAL_VELOCITY, 4, 0)
            servo.write_int(ct.ADDR_GOAL_POSITION, 4, int(round(servo.position_ticks)))
            self._note(servo.integrate(0.0, self._last_s))

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

    def host_baud(self) -> int | None:
        """The rate the host set on the pty (None if it cannot be read)."""
        try:
            buf = array.array("I", [0] * 11)
            fcntl.ioctl(self._slave, _TCGETS2, buf)
            return int(buf[10]) or None  # c_ospeed
        except OSError:
            pass
        try:
            return _SPEEDS.get(termios.tcgetattr(self._slave)[5])
        except termios.error:
            return None

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
                self._host_rate = self.host_baud()  # the rate these bytes were sent at
                for packet in self.decoder.feed(data):
                    self._integrate()
                    reply = self._handle(packet)
                    if reply:
                        os.write(self._master, reply)

    def _note(self, line: str | None) -> None:
        if line is None:
            return
        self.events.append(line)
        if self._log is not None:
            self._log(line)

    def _integrate(self) -> None:
        now = self.clock()
        start, self._last_s = self._last_s, now
        for servo in self.servos.values():
            t = start
            deadline = servo.watchdog_deadline()
            if deadline is not None and deadline < now:
                # the servo stops at the instant the period ran out, not at the next packet
                period_s = servo.bus_watchdog * ct.WATCHDOG_UNIT_S
                self._note(servo.integrate(max(0.0, deadline - t), deadline))
                firing = servo.fire_watchdog(deadline)
                self.watchdog_firings.append(firing)
                self._note(f"servo {servo.servo_id}: bus watchdog fired at t={deadline:.3f} s (no instruction "
                           f"for {period_s * 1000:.0f} ms), stopped at {firing.position_ticks:.0f} ticks")
                t = max(t, deadline)
            self._note(servo.integrate(now - t, now))

    def _hears(self, servo: EmulatedServo | None, rate: int | None) -> bool:
        """On the bus, and listening at the rate the packet was sent at (else it hears noise)."""
        if servo is None or servo.silent:
            return False
        if rate is not None and rate != servo.baud_rate:
            self.stats.wrong_baud += 1
            return False
        return True

    def _heard(self, servo: EmulatedServo) -> None:
        servo.instructions += 1
        servo.last_instruction_s = self._last_s

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
        rate = self._host_rate
        inst, p = packet.instruction, packet.params
        if inst == INST_SYNC_READ:
            return self._sync_read(p, rate)
        if inst == INST_SYNC_WRITE:
            self._sync_write(p, rate)
            return b""  # broadcast: no status
        if packet.packet_id == BROADCAST_ID and inst == INST_PING:
            # every servo answers a broadcast ping (in ID order): it takes part, so it feeds the watchdog
            out = b""
            for servo_id in sorted(self.servos):
                each = self.servos[servo_id]
                if self._hears(each, rate):
                    self._heard(each)
                    out += self._ping_status(each)
            return out
        servo = self.servos.get(packet.packet_id)
        if servo is None or not self._hears(servo, rate):
            return b""  # nobody on the bus with that ID, or at that rate
        self._heard(servo)
        if inst == INST_PING:
            return self._ping_status(servo)
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
            status = self._status(servo)  # answered before it restarts
            servo.power_up(self._last_s)
            return status
        return self._status(servo, ERR_INSTRUCTION)

    def _ping_status(self, servo: EmulatedServo) -> bytes:
        model = servo.read_int(ct.ADDR_MODEL_NUMBER, 2)
        return self._status(servo, 0, model.to_bytes(2, "little") + bytes([FIRMWARE_VERSION]))

    def _write(self, servo: EmulatedServo, address: int, data: bytes) -> int:
        """Validate the write against the table as it would be after it; apply it whole or not at all."""
        n = len(data)
        if address + n > ct.CONTROL_TABLE_SIZE:
            return ERR_ACCESS
        if address < ct.EEPROM_END and servo.torque_on:
            self.stats.access_errors += 1
            return ERR_ACCESS  # EEPROM is locked while torque is on
        if address < ct.ADDR_ID or _overlaps(address, n, ct.ADDR_MOVING, 1) \
                or _overlaps(address, n, ct.ADDR_PRESENT_CURRENT, ct.STATE_LENGTH):
            return ERR_ACCESS  # read-only: model number, firmware version, Moving, the Present values
        after = bytearray(servo.table)
        after[address : address + n] = data
        writes_goal = any(_overlaps(address, n, reg, size) for reg, size in ct.GOAL_REGISTERS)
        if writes_goal and servo.bus_watchdog == ct.WATCHDOG_FIRED:
            return ERR_DATA_RANGE  # goals are read-only until Bus Watchdog is written 0
        if _overlaps(address, n, ct.ADDR_BUS_WATCHDOG, 1):
            value = _int(after, ct.ADDR_BUS_WATCHDOG, 1, signed=True)
            if not 0 <= value <= ct.WATCHDOG_MAX_UNITS or (value and servo.bus_watchdog == ct.WATCHDOG_FIRED):
                return ERR_DATA_RANGE
        if _overlaps(address, n, ct.ADDR_CURRENT_LIMIT, 2) \
                and _int(after, ct.ADDR_CURRENT_LIMIT, 2) > ct.CURRENT_LIMIT_MAX_UNITS:
            return ERR_DATA_RANGE
        if _overlaps(address, n, ct.ADDR_GOAL_CURRENT, 2) and abs(
                _int(after, ct.ADDR_GOAL_CURRENT, 2, signed=True)) > _int(after, ct.ADDR_CURRENT_LIMIT, 2):
            return ERR_DATA_LIMIT
        if _overlaps(address, n, ct.ADDR_GOAL_VELOCITY, 4) and abs(
                _int(after, ct.ADDR_GOAL_VELOCITY, 4, signed=True)) > _int(after, ct.ADDR_VELOCITY_LIMIT, 4):
            return ERR_DATA_LIMIT
        servo.table[:] = after
        if writes_goal:
            servo.halted = False  # a new goal after the watchdog was cleared: it moves again
        self._note(servo.integrate(0.0, self._last_s))
        return 0

    def _sync_read(self, p: bytes, rate: int | None) -> bytes:
        address, length = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
        out = bytearray()
        for servo_id in p[4:]:
            servo = self.servos.get(servo_id)
            if servo is None or not self._hears(servo, rate):
                continue
            self._heard(servo)
            out += self._status(servo, 0, bytes(servo.table[address : address + length]))
        return bytes(out)

    def _sync_write(self, p: bytes, rate: int | None) -> None:
        address, length = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
        body = p[4:]
        for offset in range(0, len(body) - length, length + 1):
            servo = self.servos.get(body[offset])
            if servo is not None and self._hears(servo, rate):
                self._heard(servo)
                self._write(servo, address, body[offset + 1 : offset + 1 + length])


def stderr_log(line: str) -> None:
    """A `log` for DynamixelEmulator that prints each event on stderr."""
    print(f"dynamixel emulator: {line}", file=sys.stderr, flush=True)
