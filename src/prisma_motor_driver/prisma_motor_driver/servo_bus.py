"""Emulated servos on one Protocol 2.0 bus: which servo hears an instruction packet, what it does
with it and which status packets come back (bytes in, bytes out; `DynamixelEmulator` carries them
over a pty).

A servo hears a packet when it is on the bus (not `silent`) and listens at the rate the packet was
sent at. It takes part in (and feeds its Bus Watchdog with) packets addressed to it, sync reads and
writes naming it and broadcast pings, which every servo answers in ID order. Motion is integrated
up to each packet; a servo whose Bus Watchdog period ran out between two packets is stopped at that
exact instant (the integration is split there) and the firing kept in `watchdog_firings`, unless
the emulator itself was held up with packets waiting (`integrate_to`'s `unread_since`). A servo
told to drop n status packets processes the instructions but answers none of them.
"""
from __future__ import annotations

import collections
from collections.abc import Callable
from dataclasses import dataclass

from . import control_table as ct
from .dynamixel_packets import (
    BROADCAST_ID,
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
    encode_status,
)
from .emulated_servo import FIRMWARE_VERSION, EmulatedServo, WatchdogFiring


@dataclass
class EmulatorStats:
    instructions: int = 0
    status_sent: int = 0
    status_dropped: int = 0
    access_errors: int = 0
    wrong_baud: int = 0  # instructions a servo did not hear: sent at another rate than its own


class ServoBus:
    """Servos with the given IDs, powered up at `now_s`. `log` receives each event line (a stall at
    an end stop, a watchdog firing) as it happens; the last ones are kept in `events` too."""

    def __init__(self, ids: list[int] | tuple[int, ...], now_s: float,
                 log: Callable[[str], None] | None = None) -> None:
        self.last_s = now_s
        self.servos = {i: EmulatedServo(i) for i in ids}
        for servo in self.servos.values():
            servo.power_up(now_s)
        self.stats = EmulatorStats()
        self.watchdog_firings: list[WatchdogFiring] = []
        self.events: collections.deque[str] = collections.deque(maxlen=1000)
        self._log = log
        self._held_deadline: dict[int, float] = {}  # servo ID -> the deadline last judged by unread bytes

    def note(self, line: str | None) -> None:
        if line is None:
            return
        self.events.append(line)
        if self._log is not None:
            self._log(line)

    def integrate_to(self, now: float, unread_since: float | None = None) -> None:
        """Every servo's motion from the last integration up to `now`, watchdog stops included.

        `unread_since`: instruction bytes are waiting that the emulator (not the servo) was too late
        to read, and came some time after this instant. A real servo hears a packet as it arrives,
        so a watchdog deadline after that instant may have been met: it fires only if the packets,
        once read, do not feed it (the next integration stops the servo at the deadline)."""
        start, self.last_s = self.last_s, now
        for servo in self.servos.values():
            t = start
            deadline = servo.watchdog_deadline()
            if deadline is not None and deadline < now and unread_since is not None and deadline > unread_since:
                if self._held_deadline.get(servo.servo_id) != deadline:
                    self._held_deadline[servo.servo_id] = deadline
                    self.note(f"servo {servo.servo_id}: bus watchdog deadline t={deadline:.3f} s passed while "
                              f"instructions waited unread since t={unread_since:.3f} s (the emulator was held "
                              f"up {(now - unread_since) * 1000:.0f} ms): judged by those instructions")
            elif deadline is not None and deadline < now:
                # the servo stops at the instant the period ran out, not at the next packet
                period_s = servo.bus_watchdog * ct.WATCHDOG_UNIT_S
                self.note(servo.integrate(max(0.0, deadline - t), deadline))
                firing = servo.fire_watchdog(deadline)
                self.watchdog_firings.append(firing)
                self.note(f"servo {servo.servo_id}: bus watchdog fired at t={deadline:.3f} s (no instruction "
                          f"for {period_s * 1000:.0f} ms), stopped at {firing.position_ticks:.0f} ticks")
                t = max(t, deadline)
            self.note(servo.integrate(now - t, now))

    def handle(self, packet: Packet, rate: int | None) -> bytes:
        """One instruction packet sent at `rate` (None: unknown, every servo hears it); the status
        packets it gets back, if any."""
        self.stats.instructions += 1
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
            servo.power_up(self.last_s)
            return status
        return self._status(servo, ERR_INSTRUCTION)

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
        servo.last_instruction_s = self.last_s

    def _status(self, servo: EmulatedServo, error: int = 0, params: bytes = b"") -> bytes:
        if servo.drop_status > 0:
            servo.drop_status -= 1
            self.stats.status_dropped += 1
            return b""
        if servo.hardware_error:
            error |= ct.STATUS_ALERT_BIT
        self.stats.status_sent += 1
        return encode_status(servo.servo_id, error, params)

    def _ping_status(self, servo: EmulatedServo) -> bytes:
        model = servo.read_int(ct.ADDR_MODEL_NUMBER, 2)
        return self._status(servo, 0, model.to_bytes(2, "little") + bytes([FIRMWARE_VERSION]))

    def _write(self, servo: EmulatedServo, address: int, data: bytes) -> int:
        if servo.eeprom_locked(address, len(data)):
            self.stats.access_errors += 1
        error = servo.write(address, data)
        if not error:
            self.note(servo.integrate(0.0, self.last_s))
        return error

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
