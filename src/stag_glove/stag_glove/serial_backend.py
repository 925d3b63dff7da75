"""The readout board over pyserial: frames parsed as they arrive, reconnect with backoff."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import serial

from prisma_common.os_errors import describe_os_error

from .backend import NS, BackendFrame, BackendStatus
from .protocol import GloveStreamParser, ParserStats


@dataclass
class SerialStats:
    opens: int = 0
    open_failures: int = 0
    disconnects: int = 0
    bytes_read: int = 0


class SerialGloveBackend:
    """Reads protocol frames from the readout board over pyserial.

    A port that is missing or drops out is retried with exponential backoff (backoff_initial_s
    doubling up to backoff_max_s); corrupt bytes resynchronise in the parser and are counted. Frames
    are stamped with the poll time (the board has no clock). Why the port is down (the port and
    the OS reason) is in `last_error`, `status()` and, once per change, `take_errors()`."""

    def __init__(self, port: str, baudrate: int = 250_000, rows: int = 32, cols: int = 32,
                 backoff_initial_s: float = 0.5, backoff_max_s: float = 8.0, max_read: int = 1 << 16,
                 opener: Callable[..., serial.SerialBase] = serial.serial_for_url) -> None:
        if not port:
            raise ValueError("serial backend needs a port (parameter 'port'), got an empty string")
        if baudrate <= 0:
            raise ValueError(f"baudrate must be > 0, got {baudrate}")
        if not 0 < backoff_initial_s <= backoff_max_s:
            raise ValueError(f"need 0 < backoff_initial_s <= backoff_max_s, got {backoff_initial_s}, {backoff_max_s}")
        self.port, self.baudrate = port, baudrate
        self.parser = GloveStreamParser(rows, cols)
        self.stats = SerialStats()
        self._opener = opener
        self._serial: serial.SerialBase | None = None
        self._backoff_initial_ns = int(backoff_initial_s * NS)
        self._backoff_max_ns = int(backoff_max_s * NS)
        self._backoff_ns = self._backoff_initial_ns
        self._next_attempt_ns: int | None = None
        self._max_read = max_read
        self.last_error = ""  # the latest failure, kept after the port recovers
        self._reported_error = ""  # the error last handed out by take_errors()
        self._new_errors: list[str] = []

    @property
    def connected(self) -> bool:
        return self._serial is not None

    def poll(self, now_ns: int) -> list[BackendFrame]:
        frames = self._poll(now_ns)
        error = "" if self.connected else self.last_error
        if error != self._reported_error:
            if error:  # a new reason; the same one again only after the port worked in between
                self._new_errors.append(error)
            self._reported_error = error
        return frames

    def _poll(self, now_ns: int) -> list[BackendFrame]:
        if self._serial is None and not self._try_open(now_ns):
            return []
        port = self._serial
        assert port is not None  # open, or just opened by _try_open()
        try:
            data = port.read(self._max_read)
        except (serial.SerialException, OSError) as exc:
            self._lost(now_ns, f"read failed on {self.port}: {describe_os_error(exc)}")
            return []
        self.stats.bytes_read += len(data)
        return [BackendFrame(now_ns, f.sequence, f.raw) for f in self.parser.feed(data)]

    def take_errors(self) -> list[str]:
        errors, self._new_errors = self._new_errors, []
        return errors

    def _try_open(self, now_ns: int) -> bool:
        if self._next_attempt_ns is not None and now_ns < self._next_attempt_ns:
            return False
        try:
            # timeout=0: read() returns what is there without blocking the node's executor
            self._serial = self._opener(self.port, baudrate=self.baudrate, timeout=0)
        except (serial.SerialException, OSError, ValueError) as exc:
            self.stats.open_failures += 1
            self.last_error = f"cannot open {self.port}: {describe_os_error(exc)}"
            self._schedule_retry(now_ns)
            return False
        self.stats.opens += 1
        self.parser.reset()
        self._backoff_ns = self._backoff_initial_ns
        self._next_attempt_ns = None
        return True

    def _lost(self, now_ns: int, reason: str) -> None:
        self.stats.disconnects += 1
        self.last_error = reason
        self.close()
        self._next_attempt_ns = now_ns  # first retry at once, then back off
        self._backoff_ns = self._backoff_initial_ns

    def _schedule_retry(self, now_ns: int) -> None:
        self._next_attempt_ns = now_ns + self._backoff_ns
        self._backoff_ns = min(2 * self._backoff_ns, self._backoff_max_ns)

    @property
    def retry_in_s(self) -> float | None:
        return None if self._next_attempt_ns is None else self._backoff_ns / NS

    def status(self) -> BackendStatus:
        p: ParserStats = self.parser.stats
        values = {"port": self.port, "baudrate": str(self.baudrate), "frames": str(p.frames),
                  "crc_errors": str(p.crc_errors), "bad_headers": str(p.bad_headers),
                  "discarded_bytes": str(p.discarded_bytes), "dropped_frames": str(p.dropped_frames),
                  "opens": str(self.stats.opens), "open_failures": str(self.stats.open_failures),
                  "disconnects": str(self.stats.disconnects), "last_error": self.last_error}
        message = "connected" if self.connected else f"disconnected: {self.last_error or 'not opened yet'}"
        return BackendStatus(self.connected, message, values)

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            except (serial.SerialException, OSError):
                pass
            self._serial = None
