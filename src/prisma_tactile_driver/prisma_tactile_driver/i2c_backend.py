"""Direct I2C backend: the host reads the TCA9548A + five MAX11617 itself (smbus2 i2c_rdwr).

Per finger and scan: select the finger's mux channel (one write; the mux switches at STOP), then
one combined transfer writes the MAX11617 setup (0x82) and configuration (0x11: scan AIN0..AIN8,
single-ended) bytes and reads 18 bytes; count = ((b0 & 0x0F) << 8) | b1. The MAX11617 sends
the first byte of each result with its four high bits set (datasheet, "Reading a Conversion"),
so a result whose high nibble is not 1111 (a glitched bus reading all zeros, say) is rejected
as a bus error, like an OSError (a NACK): retried a bounded number of times; a finger that still
fails is left out of that scan's reading, and the hub reports it stale once its last good sample
is too old, while the other fingers keep going. Frames are stamped with the host's scan time.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from prisma_common.hand import FINGERS, N_TAXELS
from prisma_common.os_errors import describe_os_error

from .backend import HubReading, LinkStatus

MAX11617_SETUP = 0x82  # setup byte: VDD reference, internal clock, unipolar, no reset
MAX11617_CONFIG = 0x11  # configuration: SCAN 00 (AIN0..CS), CS = AIN8, single-ended
READ_BYTES = 2 * N_TAXELS
REOPEN_PERIOD_NS = 1_000_000_000  # a bus that could not be opened is tried again this often


class BadReadError(ValueError):
    """A MAX11617 read that cannot be a conversion result (a high nibble other than 1111)."""


def decode_max11617(data: bytes) -> np.ndarray:
    """18 bytes -> 9 counts: ((b0 & 0x0F) << 8) | b1. The first byte's high nibble must read
    1111; BadReadError names the results where it does not."""
    raw = np.frombuffer(bytes(data), dtype=np.uint8).reshape(N_TAXELS, 2).astype(np.uint16)
    bad = np.flatnonzero(raw[:, 0] >> 4 != 0x0F)
    if bad.size:
        shown = ", ".join(f"AIN{i} 0x{int(raw[i, 0]):02X}{int(raw[i, 1]):02X}" for i in bad[:3])
        more = f" and {bad.size - 3} more" if bad.size > 3 else ""
        raise BadReadError(f"bad MAX11617 read: high nibble not 1111 in {shown}{more}")
    return ((raw[:, 0] & 0x0F) << 8) | raw[:, 1]


def check_channel_map(channels: dict[str, int]) -> dict[str, int]:
    """finger -> mux channel 0..7, each finger known and each channel used once."""
    unknown = sorted(set(channels) - set(FINGERS))
    if unknown:
        raise ValueError(f"finger_channels: unknown finger(s) {unknown}; expected names from {FINGERS}")
    for finger, ch in channels.items():
        if not isinstance(ch, (int, np.integer)) or not 0 <= ch <= 7:
            raise ValueError(f"finger_channels: channel of {finger} must be 0..7, got {ch!r}")
    seen: dict[int, str] = {}
    for finger, ch in channels.items():
        if ch in seen:
            raise ValueError(f"finger_channels: duplicate mux channel {ch} for {seen[ch]} and {finger}")
        seen[ch] = finger
    return dict(channels)


@dataclass
class FingerLinkStats:
    reads: int = 0  # good reads
    errors: int = 0  # bus errors (OSErrors and bad reads), retries included
    bad_reads: int = 0  # reads rejected for a high nibble other than 1111 (also in errors)
    failed_scans: int = 0  # scans in which the finger gave up after its retries
    consecutive_failures: int = 0
    last_error: str = ""


class I2CHubBackend:
    def __init__(self, bus: int | str | Any, channels: dict[str, int], *, mux_address: int = 0x70,
                 adc_address: int = 0x35, retries: int = 2,
                 bus_factory: Callable[[Any], Any] | None = None) -> None:  # called with `bus`
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        if not 0x08 <= mux_address <= 0x77:
            raise ValueError(f"mux_address must be a 7-bit address 0x08..0x77, got 0x{mux_address:X}")
        self.channels = check_channel_map(channels)
        self.mux_address, self.adc_address, self.retries = mux_address, adc_address, retries
        if bus_factory is None:
            from smbus2 import SMBus
            bus_factory = SMBus
        self._sequence = 0
        self.stats = {finger: FingerLinkStats() for finger in self.channels}
        self.open_failures = 0
        self.open_error = ""  # why the bus could not be opened, "" once it is open
        self._next_open_ns: int | None = None
        self._bus: Any = None
        if hasattr(bus, "i2c_rdwr"):  # an already-open bus object instead of a number or path
            self._bus, self.bus_name = bus, type(bus).__name__
        else:
            self._bus_arg, self._factory = bus, bus_factory
            self.bus_name = f"/dev/i2c-{bus}" if isinstance(bus, int) else str(bus)
            self._open()  # at once, so a missing bus shows from the start; read() retries

    def _open(self) -> bool:
        try:
            self._bus = self._factory(self._bus_arg)
        except OSError as exc:
            self.open_failures += 1
            self.open_error = f"cannot open I2C bus {self.bus_name}: {describe_os_error(exc)}"
            return False
        self.open_error = ""
        return True

    def _read_finger(self, channel: int) -> np.ndarray:
        from smbus2 import i2c_msg
        self._bus.i2c_rdwr(i2c_msg.write(self.mux_address, [1 << channel]))
        config = i2c_msg.write(self.adc_address, [MAX11617_SETUP, MAX11617_CONFIG])
        result = i2c_msg.read(self.adc_address, READ_BYTES)
        self._bus.i2c_rdwr(config, result)
        return decode_max11617(bytes(result))

    def scan(self) -> dict[str, np.ndarray]:
        """One pass over every finger; fingers that failed all attempts are absent."""
        counts: dict[str, np.ndarray] = {}
        for finger, channel in self.channels.items():
            stats = self.stats[finger]
            for _attempt in range(self.retries + 1):
                try:
                    counts[finger] = self._read_finger(channel)
                except (OSError, BadReadError) as exc:
                    stats.errors += 1
                    stats.bad_reads += isinstance(exc, BadReadError)
                    stats.last_error = f"mux channel {channel}: {exc}"
                    continue
                stats.reads += 1
                stats.consecutive_failures = 0
                break
            else:
                stats.failed_scans += 1
                stats.consecutive_failures += 1
        return counts

    def read(self, stamp_ns: int) -> list[HubReading]:
        if self._bus is None:
            if self._next_open_ns is not None and stamp_ns < self._next_open_ns:
                return []
            if not self._open():
                self._next_open_ns = stamp_ns + REOPEN_PERIOD_NS
                return []
        counts = self.scan()
        self._sequence += 1
        return [HubReading(self._sequence - 1, counts)] if counts else []

    def counters(self) -> dict[str, int]:
        out = {"scans": self._sequence, "open_failures": self.open_failures}
        for finger, s in self.stats.items():
            out[f"{finger}_reads"] = s.reads
            out[f"{finger}_errors"] = s.errors
            out[f"{finger}_bad_reads"] = s.bad_reads
            out[f"{finger}_failed_scans"] = s.failed_scans
        return out

    def link_status(self) -> LinkStatus:
        """The bus that cannot be opened, or the fingers whose last scan failed with their error."""
        values = {"bus": self.bus_name}
        values.update({f"{finger}_last_error": s.last_error for finger, s in self.stats.items() if s.last_error})
        if self.open_error:
            return LinkStatus(self.open_error, values)
        failing = [f"{finger}: {s.last_error}" for finger, s in self.stats.items() if s.consecutive_failures]
        return LinkStatus("; ".join(failing), values)

    def close(self) -> None:
        close = getattr(self._bus, "close", None)
        if close:
            close()
