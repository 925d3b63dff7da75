"""Unix stream sockets at paths the user names, taken and given back without harm to anything else.

The server side never replaces or deletes what it did not create: `bind_unix_socket` takes a free
path or a stale socket (one nobody listens on: connect is refused) and refuses anything else with
FileExistsError naming what is there; `release_unix_socket` removes the socket only while it is still
the one that was bound (same inode and device). `check_path_length` says which path is too long for
a socket address, which connect and bind do not.
"""
from __future__ import annotations

import errno
import os
import socket
import stat
from pathlib import Path

from .os_errors import describe_os_error

MAX_PATH_BYTES = 107  # sockaddr_un.sun_path is 108 bytes with the terminating NUL
PROBE_TIMEOUT_S = 1.0  # a live server with a full backlog would block the probe's connect


def check_path_length(path: str | Path) -> None:
    """OSError(ENAMETOOLONG) naming `path` when it does not fit a Unix socket address (connect
    and bind would only say 'AF_UNIX path too long', without the path)."""
    size = len(os.fsencode(path))
    if size > MAX_PATH_BYTES:
        raise OSError(errno.ENAMETOOLONG, f"{os.strerror(errno.ENAMETOOLONG)}: {path} has {size} bytes, a Unix "
                                          f"socket path at most {MAX_PATH_BYTES}: choose a shorter path")



def _probe(path: Path) -> str | None:
    """None for a stale socket (connect refused); else what the socket at `path` is."""
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    probe.settimeout(PROBE_TIMEOUT_S)
    try:
        probe.connect(str(path))
    except ConnectionRefusedError:
        return None
    except OSError as exc:
        return f"a socket that does not take a connection ({describe_os_error(exc)})"
    finally:
        probe.close()
    return "a live socket (a process is serving it)"


def check_socket_path(path: str | Path) -> os.stat_result | None:
    """The stat of a stale socket at `path` that `start()` may replace, None when the path is free;
    FileExistsError naming the path and what is there otherwise."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    mode = st.st_mode
    if stat.S_ISSOCK(mode):
        what = _probe(path)
        if what is None:
            return st
    elif stat.S_ISLNK(mode):
        what = f"a symlink to {os.readlink(path)}"
    elif stat.S_ISDIR(mode):
        what = "a directory"
    elif stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        what = "a device"
    elif stat.S_ISFIFO(mode):
        what = "a named pipe"
    else:
        what = "an existing file"
    raise FileExistsError(f"{path} is {what}; an emulator replaces nothing there but a stale socket "
                          f"(one nobody listens on): stop whatever serves it or choose another socket path")


def bind_unix_socket(path: Path) -> tuple[socket.socket, tuple[int, int]]:
    """A Unix stream socket bound at `path` (not yet listening) and the (inode, device) it made
    there. Only a free path or a stale socket is taken; FileExistsError otherwise, also for
    anything that appears there between the check and the bind (bind never replaces)."""
    check_path_length(path)
    stale = check_socket_path(path)
    if stale is not None:
        release_unix_socket(path, (stale.st_ino, stale.st_dev))
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        listener.bind(str(path))  # EADDRINUSE if anything is there
        st = os.lstat(path)
    except OSError as exc:
        listener.close()
        if exc.errno == errno.EADDRINUSE:
            raise FileExistsError(f"{path} appeared while the emulator was about to serve there; it is left "
                                  f"alone: choose another socket path") from None
        raise OSError(exc.errno, f"cannot serve at {path}: {exc.strerror or exc}") from None
    return listener, (st.st_ino, st.st_dev)


def release_unix_socket(path: Path, identity: tuple[int, int] | None) -> None:
    """Remove the socket at `path` only while it is the one with that (inode, device)."""
    if identity is None:
        return
    try:
        now = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISSOCK(now.st_mode) and (now.st_ino, now.st_dev) == identity:
        os.unlink(path)
