"""Serial backend: the Arduino hub streams protocol frames over USB serial (pyserial).

The port may vanish (cable pulled, hub reset, USB re-enumeration): any read error closes it, the
partial frame in the parser is dropped, and reopening is retried with exponential backoff until
the port is back. Time enters only through the injected `monotonic` clock (backoff pacing) and
the `stamp_ns` of each read, the host time the frames it drains were received by: the hub clock
estimator (hub_clock.py) turns that and the frames' sequence numbers into one stamp per frame.
Why the link is down (the port and the OS reason) is kept in `last_error` and `link_status()`.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

from prisma_common.os_errors import describe_os_error

from . import hub_clock
from .backend import HubReading, LinkStatus
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
                 serial_factory: Callable[..., serial.Serial] = serial.Serial,
                 clock: hub_clock.HubClockConfig = hub_clock.DEFAULT_CONFIG) -> None:
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
        self.last_error: str = ""  # the latest failure, kept after the link recovers
        self.parser = FrameParser()
        self.link = LinkCounters()
        self.clock_config = clock
        self.clock = hub_clock.HubClockState()

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
            self.last_error = f"cannot open serial port {self.port}: {describe_os_error(exc)}"
            self._next_attempt = now + self._backoff
            self._backoff = min(2 * self._backoff, self._backoff_max)
            return False
        self.link.opens += 1
        if self._was_connected:
            self.link.reconnects += 1
        self._was_connected = True
        self._backoff = self._backoff_initial
        # opening resets a Nano (DTR) and frames may have been lost meanwhile: anchor afresh
        self.clock = hub_clock.reanchor(self.clock)
        return True

    def _drop(self, exc: Exception) -> None:
        self.link.disconnects += 1
        self.last_error = f"serial port {self.port} lost: {describe_os_error(exc)}"
        if self.parser.discard_buffer():
            self.link.partial_frames_dropped += 1
        try:
            if self._serial is not None:
                self._serial.close()
        except (serial.SerialException, OSError):
            pass  # the device is gone; closing its handle cannot fail usefully
        self._serial = None
        self._next_attempt = self._monotonic() + self._backoff
        self._backoff = min(2 * self._backoff, self._backoff_max)

    def poll_frames(self) -> list[HubFrame]:
        """Read what is there (waiting at most read_timeout_s) and parse it; never raises."""
        if self._serial is None and not self._open():
            # a port that is not open answers as late as an open one with nothing to read: a caller
            # that reads in a loop (the node's reader thread) does not spin while the hub is away
            time.sleep(self._read_timeout)
            return []
        port = self._serial
        assert port is not None  # open, or just opened by _open()
        try:
            waiting = port.in_waiting
            data = port.read(min(max(waiting, 1), self._max_read))
        except (serial.SerialException, OSError) as exc:
            self._drop(exc)
            return []
        self.link.bytes_read += len(data)
        return self.parser.feed(data) if data else []

    def read(self, stamp_ns: int) -> list[HubReading]:
        """Frames drained now, stamped from the hub's sequence numbers (all received by stamp_ns)."""
        frames = self.poll_frames()
        if not frames:
            return []
        result = hub_clock.update(self.clock, [f.sequence for f in frames], stamp_ns, self.clock_config)
        self.clock = result.state
        return [HubReading(f.sequence, f.by_finger(), stamp)
                for f, stamp in zip(frames, result.stamps_ns)]

    def counters(self) -> dict[str, int]:
        # missed_frames (the parser's sequence gaps) are the dropped frames; the clock adds anchors
        return {**self.parser.stats.as_dict(), **self.link.__dict__, "stamp_anchors": self.clock.anchors}

    def link_status(self) -> LinkStatus:
        error = "" if self.connected else self.last_error or f"serial port {self.port} not opened yet"
        period = hub_clock.estimated_period_ns(self.clock, self.clock_config)
        return LinkStatus(error, {"port": self.port, "last_error": self.last_error,
                                  "stamp_period_us": f"{period / 1e3:.3f}"})

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            finally:
                self._serial = None
