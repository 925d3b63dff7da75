"""The emulated hand's control socket served: one request per connection, one reply, in the wire
format of prisma_common.control_socket (its clients: prisma-hand-fault, the tactile driver's
~/replace_object). The socket file is created and removed by the emulator.
"""
from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from prisma_common.control_socket import decode_request, encode_reply, read_line, refused
from prisma_common.unix_socket import bind_unix_socket, release_unix_socket


class ControlServer:
    """Serves `handle(command, args) -> reply dict` on a Unix stream socket at `path`."""

    def __init__(self, path: str | Path, handle: Callable[[str, dict[str, Any]], dict[str, Any]]) -> None:
        self.path = Path(path)
        self._handle = handle
        self._socket: socket.socket | None = None
        self._identity: tuple[int, int] | None = None
        self._thread = threading.Thread(target=self._serve, name="emulator-control", daemon=True)

    def bind(self) -> ControlServer:
        """Take the socket path (FileExistsError for anything but a free path or a stale socket, a
        live emulator's included) and listen; requests wait until `serve`."""
        self._socket, self._identity = bind_unix_socket(self.path)
        self._socket.listen(4)
        return self

    def serve(self) -> ControlServer:
        self._thread.start()
        return self

    def start(self) -> ControlServer:
        return self.bind().serve()

    def close(self) -> None:
        if self._socket is None:
            return
        release_unix_socket(self.path, self._identity)
        try:
            self._socket.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._socket.close()
        if self._thread.ident is not None:
            self._thread.join(timeout=2.0)
        self._socket = None

    def _serve(self) -> None:
        listener = self._socket  # close() sets _socket to None: keep the one this thread serves
        assert listener is not None  # the thread starts in start(), once the socket is bound
        while True:
            try:
                connection, _ = listener.accept()
            except OSError:
                return  # closed
            with connection:
                connection.settimeout(5.0)
                try:
                    connection.sendall(encode_reply(self._reply(read_line(connection))))
                except OSError:
                    continue  # the client went away

    def _reply(self, line: bytes) -> dict[str, Any]:
        try:
            command, args = decode_request(line)
        except ValueError as exc:
            return refused(str(exc))
        return self._handle(command, args)
