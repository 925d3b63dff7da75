"""Serial backend: the Arduino hub streams protocol frames over USB serial (pyserial).

The port may vanish (cable pulled, hub reset, USB re-enumeration): any read error closes it, the
partial frame in the parser is dropped, and reopening is retried with exponential backoff until
the port is back. Time enters only through the injected `monotonic` clock (backoff pacing).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import serial

from .backend import HubReading
from .protocol import FrameParser, HubFrame


@dataclass
class LinkCounters:
    opens: int = 0  # successful opens, the first included
    reconnects: int = 0  # successful reopens after the link was lost
    disconnects: int = 0  # read errors that closed the port
    open_failures: int = 0  # failed open attempts (port absent, busy...)
    bytes_read: int = 0
    partial_frames_dropped: int = 0  # a frame cut by a disconnect


class SerialHubBackend:
    def __init__(self, port: str, baud: int = 1_000_000, *, read_timeout_s: float = 0.0,
                 max_read: int = 65536, backoff_initial_s: float = 0.05, backoff_max_s: float = 2.0,
                 monotonic: Callable[[], float] = time.monotonic,
                 serial_factory: Callable[..., serial.Serial] = serial.Serial) -> None:
        if baud <= 0:
            raise ValueError(f"baud must be > 0, got {baud}")
        if not 0 < backoff_initial_s <= backoff_max_s:
            raise ValueError(f"need 0 < backoff_initial_s <= backoff_max_s, got {backoff_initial_s}, {backoff_max_s}")
        self.port, self.baud = port, baud
        self._read_timeout = read_timeout_s
        self._max_read = max_read
        self._backoff_initial, self._backoff_max = backoff_initial_s, backoff_max_s
        self._backoff = backoff_initial_s
        self._monotonic = monotonic
        self._factory = serial_factory
        self._serial: serial.Serial | None = None
        self._next_attempt = float("-inf")
        self._was_connected = False
        self.last_error: str = ""
        self.parser = FrameParser()
        self.link = LinkCounters()

    @property
    def connected(self) -> bool:
        return self._serial is not None

    def _open(self) -> bool:
        now = self._monotonic()
        if now < self._next_attempt:
            return False
        try:
            self._serial = self._factory(self.port, self.baud, timeout=self._read_timeout)
        except (serial.SerialException, OSError, ValueError) as exc:
            self.link.open_failures += 1
            self.last_error = f"open {self.port}: {exc}"
            self._next_attempt = now + self._backoff
            self._backoff = min(2 * self._backoff, self._backoff_max)
            return False
        self.link.opens += 1
        if self._was_connected:
            self.link.reconnects += 1
        self._was_connected = True
        self._backoff = self._backoff_initial
        return True

    def _drop(self, exc: Exception) -> None:
        self.link.disconnects += 1
        self.last_error = f"read {self.port}: {exc}"
        if self.parser.discard_buffer():
            self.link.partial_frames_dropped += 1
        try:
            self._serial.close()
        except (serial.SerialException, OSError):
            pass  # the device is gone; closing its handle cannot fail usefully
        self._serial = None
        self._next_attempt = self._monotonic() + self._backoff
        self._backoff = min(2 * self._backoff, self._backoff_max)

    def poll_frames(self) -> list[HubFrame]:
        """Read what is there (waiting at most read_timeout_s) and parse it; never raises."""
        if self._serial is None and not self._open():
            return []
        try:
            waiting = self._serial.in_waiting
            data = self._serial.read(min(max(waiting, 1), self._max_read))
        except (serial.SerialException, OSError) as exc:
            self._drop(exc)
            return []
        self.link.bytes_read += len(data)
        return self.parser.feed(data) if data else []

    def read(self, stamp_ns: int) -> list[HubReading]:
        return [HubReading(f.sequence, f.by_finger()) for f in self.poll_frames()]

    def counters(self) -> dict[str, int]:
        return {**self.parser.stats.as_dict(), **self.link.__dict__}

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            finally:
                self._serial = None
