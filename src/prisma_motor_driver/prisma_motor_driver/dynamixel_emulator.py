"""Dynamixel X-series servos emulated behind a pseudo-terminal (test and bench support).

The emulator owns the master end of a pty; `port_name` is the slave device that dynamixel-sdk's
PortHandler opens, so the SDK's real read/write/txRx code runs against it. A thread decodes what the
host writes (`dynamixel_packets`) and hands each packet to a `ServoBus` (`servo_bus`: ping, also
broadcast, read, write, sync read, sync write and reboot; which servo hears what and what it
answers) of `EmulatedServo`s (`emulated_servo`: the control table and what the e-Manual says a servo
does with it), with the rate the host set on the pty: read from the slave's termios (TCGETS2, so
pyserial's custom rates too), since a servo hears only packets sent at its own Baud Rate. Motion is
integrated up to the clock on every packet, `present()` and `update()`; power-ups are construction,
`power_cycle` and the reboot instruction. A stall at an end stop and a watchdog firing are logged
(`events`, and `log`).

Faults for tests: `inject_hardware_error(id, bit)` sets Hardware Error Status and the alert bit of
every later status packet (`clear_hardware_error` clears the bits alone, as a reboot would without
the rest of the power cycle; `power_cycle` is the whole thing); `drop_status(id, n)` processes the
next n instructions to that ID but sends no status packet (the host sees a timeout);
`set_silent(id, True)` takes the servo off the bus (a cut cable): it neither acts on nor answers
anything until set back (its watchdog, if armed, fires); `set_baud(id, rate)` configures it at
another rate (by another tool): silent at the host's.

Time comes from `clock()` (seconds); tests pass a manual clock so motion is deterministic. On real
time the emulator can be held up (this process not running) while packets wait in the pty: a Bus
Watchdog deadline that passed meanwhile is judged by those packets once read, as a servo, which
hears every packet as it comes, would have judged it (and the event logged).
"""
from __future__ import annotations

import array
import fcntl
import os
import select
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass

from . import control_table as ct
from .dynamixel_packets import Packet, PacketDecoder
from .servo_bus import ServoBus

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


class DynamixelEmulator:
    """Servos with the given IDs on one emulated bus (`ServoBus`) behind a pty. Use as a context
    manager. `log` receives each event line (a stall at an end stop, a watchdog firing) as it
    happens; the last ones are kept in `events` too."""

    def __init__(self, ids: list[int] | tuple[int, ...], clock: Callable[[], float] | None = None,
                 log: Callable[[str], None] | None = None, wall_clock: bool | None = None) -> None:
        self.clock = clock or time.monotonic
        # `wall_clock` (default: no clock given): the clock runs on while this process is held up
        # (a busy computer) with packets waiting in the pty, which a real servo would have heard as
        # they came; a manual clock stands still meanwhile
        self._real_time = clock is None if wall_clock is None else wall_clock
        self._seen_empty_s = self.clock()  # when the pty was last found with nothing to read
        self.bus = ServoBus(ids, self.clock(), log)  # the emulator's start is a power-up
        # the bus's own containers (mutated in place, never rebound), read by tests and the hand emulator
        self.servos, self.stats = self.bus.servos, self.bus.stats
        self.watchdog_firings, self.events = self.bus.watchdog_firings, self.bus.events
        self.decoder = PacketDecoder()
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
                self.servos[i].power_up(self.bus.last_s)

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
            self.bus.note(servo.integrate(0.0, self.bus.last_s))

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
            self.bus.note(self.servos[servo_id].integrate(0.0, self.bus.last_s))

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
            self.bus.note(servo.integrate(0.0, self.bus.last_s))

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
                waiting = self._pending()
                if not waiting:
                    self._seen_empty_s = self.clock()
                ready = waiting or select.select([self._master], [], [], 0.05)[0]
            except (OSError, ValueError):
                return
            if not ready:
                continue
            # the bytes came after the pty was last found empty, which is all this thread knows: woken
            # by them, it may have waited for a core or the interpreter lock before it looked at the
            # clock (a deadline judged by that later instant fired watchdogs that the bytes had met),
            # and the lock below can hold it up longer still
            unread_since = self._seen_empty_s
            # read under the lock so that `sync()` can tell "nothing in flight" reliably
            with self._lock:
                try:
                    data = os.read(self._master, 4096)
                except OSError:
                    return
                self._host_rate = self.host_baud()  # the rate these bytes were sent at
                for packet in self.decoder.feed(data):
                    self._integrate(unread_since if self._real_time else None)
                    reply = self._handle(packet)
                    if reply:
                        os.write(self._master, reply)

    def _handle(self, packet: Packet) -> bytes:
        return self.bus.handle(packet, self._host_rate)

    def _pending(self) -> bool:
        """Bytes from the host wait in the pty, unread."""
        return self._master >= 0 and bool(select.select([self._master], [], [], 0)[0])

    def _integrate(self, unread_since: float | None = None) -> None:
        """Motion up to clock(). Called between packets (`unread_since`: see ServoBus.integrate_to)
        or by another thread, which finds the bytes this one has not read yet."""
        if unread_since is None and self._real_time and self._pending():
            unread_since = self._seen_empty_s
        self.bus.integrate_to(self.clock(), unread_since)


def stderr_log(line: str) -> None:
    """A `log` for DynamixelEmulator that prints each event on stderr."""
    print(f"dynamixel emulator: {line}", file=sys.stderr, flush=True)
