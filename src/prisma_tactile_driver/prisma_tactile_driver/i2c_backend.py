"""Direct I2C backend: the host reads the TCA9548A + five MAX11617 itself (smbus2 i2c_rdwr).

Per finger and scan: select the finger's mux channel (one write; the mux switches at STOP), then
one combined transfer writes the MAX11617 setup (0x82) and configuration (0x11: scan AIN0..AIN8,
single-ended) bytes and reads 18 bytes; count = ((b0 & 0x0F) << 8) | b1. An OSError (a NACK,
bus error) is retried a bounded number of times; a finger that still fails is left out of that
scan's reading, and the hub reports it stale once its last good sample is too old, while the
other fingers keep going.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .backend import HubReading
from .taxels import FINGERS, N_TAXELS

MAX11617_SETUP = 0x82  # setup byte: VDD reference, internal clock, unipolar, no reset
MAX11617_CONFIG = 0x11  # configuration: SCAN 00 (AIN0..CS), CS = AIN8, single-ended
READ_BYTES = 2 * N_TAXELS


def decode_max11617(data: bytes) -> np.ndarray:
    """18 bytes -> 9 counts: ((b0 & 0x0F) << 8) | b1 (the first byte's high nibble reads 1111)."""
    raw = np.frombuffer(bytes(data), dtype=np.uint8).reshape(N_TAXELS, 2).astype(np.uint16)
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
    errors: int = 0  # OSErrors, retries included
    failed_scans: int = 0  # scans in which the finger gave up after its retries
    consecutive_failures: int = 0
    last_error: str = ""


class I2CHubBackend:
    def __init__(self, bus: int | str | Any, channels: dict[str, int], *, mux_address: int = 0x70,
                 adc_address: int = 0x35, retries: int = 2,
                 bus_factory: Callable[[int | str], Any] | None = None) -> None:
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        if not 0x08 <= mux_address <= 0x77:
            raise ValueError(f"mux_address must be a 7-bit address 0x08..0x77, got 0x{mux_address:X}")
        self.channels = check_channel_map(channels)
        self.mux_address, self.adc_address, self.retries = mux_address, adc_address, retries
        if bus_factory is None:
            from smbus2 import SMBus
            bus_factory = SMBus
        # an already-open bus object may be passed instead of a number or path
        self._bus = bus if hasattr(bus, "i2c_rdwr") else bus_factory(bus)
        self._sequence = 0
        self.stats = {finger: FingerLinkStats() for finger in self.channels}

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
                except OSError as exc:
                    stats.errors += 1
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
        counts = self.scan()
        self._sequence += 1
        return [HubReading(self._sequence - 1, counts)] if counts else []

    def counters(self) -> dict[str, int]:
        out = {"scans": self._sequence}
        for finger, s in self.stats.items():
            out[f"{finger}_reads"] = s.reads
            out[f"{finger}_errors"] = s.errors
            out[f"{finger}_failed_scans"] = s.failed_scans
        return out

    def close(self) -> None:
        close = getattr(self._bus, "close", None)
        if close:
            close()
