"""The hub's serial end on a pseudo-terminal, for tests, benchmarks and demos without hardware.

The pty is reached through a stable symlink (like /dev/serial/by-id/... on the robot), so a
hang-up followed by a new pty looks to the driver exactly like a hub that was unplugged and
plugged back in: the same path disappears and comes back.
"""
from __future__ import annotations

import fcntl
import os
import struct
import termios
import time
import tty
from pathlib import Path


class PtyHubPort:
    def __init__(self, link_path: str | Path) -> None:
        self.link_path = Path(link_path)
        self._master: int | None = None
        self._slave: int | None = None

    @property
    def is_open(self) -> bool:
        return self._master is not None

    def open(self) -> str:
        """Create a fresh pty (raw mode, so no byte is translated) and point the link at it."""
        if self.is_open:
            raise RuntimeError("pty already open")
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # the driver reopens with pyserial, which also sets raw mode
        tmp = self.link_path.with_name(self.link_path.name + ".new")
        if tmp.is_symlink():
            tmp.unlink()
        os.symlink(os.ttyname(self._slave), tmp)
        os.replace(tmp, self.link_path)
        return str(self.link_path)

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            written = os.write(self._master, view)
            view = view[written:]

    def pending(self) -> int:
        """Bytes written but not yet read by the other end."""
        raw = fcntl.ioctl(self._slave, termios.FIONREAD, struct.pack("i", 0))
        return struct.unpack("i", raw)[0]

    def drain(self, timeout_s: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while self.pending():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.001)
        return True

    def hang_up(self) -> None:
        """Close both ends and remove the link: readers get EIO, reopening fails until open()."""
        if self.link_path.is_symlink():
            self.link_path.unlink()
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None

    close = hang_up
