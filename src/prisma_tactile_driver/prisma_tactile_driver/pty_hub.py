"""The hub's serial end on a pseudo-terminal, for tests, benchmarks and demos without hardware.

The pty is reached through a stable symlink (like /dev/serial/by-id/... on the robot), so a
hang-up followed by a new pty looks to the driver exactly like a hub that was unplugged and
plugged back in: the same path disappears and comes back.

The link path is the user's to name, so nothing but an emulator's own link is ever replaced or
removed there: `open()` replaces only a symlink to a /dev/pts/* pseudo-terminal (an earlier run's
link, live or left dangling by a killed emulator) and refuses anything else with FileExistsError;
`hang_up()` removes the link only while it still points at the pty this port opened.
"""
from __future__ import annotations

import fcntl
import os
import stat
import struct
import termios
import time
import tty
from pathlib import Path

PTS_DIR = "/dev/pts/"
# what a USB-serial adapter holds for a host that does not read (the emulators drop frames beyond it)
ADAPTER_BUFFER_BYTES = 4096


def is_pty_link(path: str | Path) -> bool:
    """A symlink to a /dev/pts/* pseudo-terminal, live or dangling: what this emulator creates."""
    path = Path(path)
    if not path.is_symlink():
        return False
    target = os.readlink(path)
    if not target.startswith(PTS_DIR):
        return False
    try:
        return stat.S_ISCHR(os.stat(target).st_mode)
    except FileNotFoundError:
        return True  # the pty of a run that ended or was killed


def check_link_path(path: str | Path) -> None:
    """FileExistsError unless `path` is free or an emulator link that `open()` may replace."""
    path = Path(path)
    if path.is_symlink():
        if is_pty_link(path):
            return
        what = f"a symlink to {os.readlink(path)}"
    elif path.exists():
        mode = path.stat().st_mode
        what = ("a directory" if stat.S_ISDIR(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "an existing file")
    else:
        return
    raise FileExistsError(f"{path} is {what}; only an emulator's own link (a symlink to a {PTS_DIR}* "
                          f"pseudo-terminal) is replaced there: choose another link path")


class PtyLink:
    """A symlink at a path the user names, pointing at a pseudo-terminal this process opened.

    `point_at` goes through a temporary link and a rename, so a reader never sees the path missing
    or half made; it replaces only an emulator's link (`check_link_path`). `remove` deletes the link
    only while it still points at this process's pty (someone may have replaced it meanwhile)."""

    def __init__(self, link_path: str | Path) -> None:
        self.link_path = Path(link_path)
        self.target: str | None = None

    def point_at(self, target: str) -> None:
        check_link_path(self.link_path)
        tmp = self.link_path.with_name(f"{self.link_path.name}.new-{os.getpid()}")
        if is_pty_link(tmp):
            tmp.unlink()  # this pid's own leftover
        os.symlink(target, tmp)  # FileExistsError if anything else is there
        try:
            check_link_path(self.link_path)  # again, just before the rename
            os.replace(tmp, self.link_path)
        except BaseException:
            tmp.unlink()
            raise
        self.target = target

    def remove(self) -> None:
        if self.target is not None and self.link_path.is_symlink() and os.readlink(self.link_path) == self.target:
            self.link_path.unlink()
        self.target = None


class PtyHubPort:
    def __init__(self, link_path: str | Path) -> None:
        self.link_path = Path(link_path)
        self._link = PtyLink(link_path)
        self._master: int | None = None
        self._slave: int | None = None

    @property
    def is_open(self) -> bool:
        return self._master is not None

    def open(self) -> str:
        """Create a fresh pty (raw mode, so no byte is translated) and point the link at it."""
        if self.is_open:
            raise RuntimeError("pty already open")
        check_link_path(self.link_path)
        master, slave = os.openpty()
        try:
            tty.setraw(slave)  # the driver reopens with pyserial, which also sets raw mode
            self._link.point_at(os.ttyname(slave))
        except BaseException:
            os.close(master)
            os.close(slave)
            raise
        self._master, self._slave = master, slave
        return str(self.link_path)

    def _open_fds(self) -> tuple[int, int]:
        if self._master is None or self._slave is None:
            raise RuntimeError("pty not open")
        return self._master, self._slave

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            written = os.write(self._open_fds()[0], view)
            view = view[written:]

    def offer(self, data: bytes, buffer_bytes: int) -> bool:
        """Write `data` unless the other end already holds more than `buffer_bytes` - len(data)
        unread bytes; False (nothing written) then. A USB-serial adapter buffers only so much for
        a host that does not read, and an emulator must not block on a link nobody reads: its
        other devices and its own shutdown would wait behind it."""
        if self.pending() + len(data) > buffer_bytes:
            return False
        self.write(data)
        return True

    def pending(self) -> int:
        """Bytes written but not yet read by the other end."""
        _, slave = self._open_fds()
        raw = fcntl.ioctl(slave, termios.FIONREAD, struct.pack("i", 0))
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
        self._link.remove()
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None

    close = hang_up
