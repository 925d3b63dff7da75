"""The emulated hand's control socket: one JSON request per connection, one JSON reply.

Request: `{"command": "<name>", "args": {...}}` (a line of UTF-8 JSON). Reply:
`{"ok": true, "message": "..."}`, `{"ok": true, "status": {...}}` for `status`, or
`{"ok": false, "error": "..."}` naming what was refused and why. The socket file is created and
removed by the emulator; `send` is the client `prisma-hand-fault` uses.
"""
from __future__ import annotations

import json
import socket
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from prisma_common.unix_socket import bind_unix_socket, release_unix_socket

MAX_REQUEST_BYTES = 65536


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
                    reply = self._reply(_read_line(connection))
                    connection.sendall(json.dumps(reply).encode() + b"\n")
                except OSError:
                    continue  # the client went away

    def _reply(self, line: bytes) -> dict[str, Any]:
        try:
            request = json.loads(line)
        except ValueError as exc:
            return {"ok": False, "error": f"request is not JSON ({exc})"}
        if not isinstance(request, dict) or not isinstance(request.get("command"), str) \
                or not isinstance(request.get("args", {}), dict):
            return {"ok": False, "error": 'request must be {"command": "<name>", "args": {...}}'}
        return self._handle(request["command"], request.get("args", {}))


def send(path: str | Path, command: str, args: dict[str, Any] | None = None,
         timeout_s: float = 5.0) -> dict[str, Any]:
    """One request to the emulator at `path`; ConnectionError naming the path when nobody answers."""
    path = Path(path)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as client:
        client.settimeout(timeout_s)
        try:
            client.connect(str(path))
        except (FileNotFoundError, ConnectionRefusedError) as exc:
            raise ConnectionError(f"no emulated hand at {path} ({exc.strerror}): start one with "
                                  f"`prisma-hand-emulator --dir {path.parent}` or "
                                  f"`ros2 launch prisma_bringup hand.launch.py hardware:=emulated`") from None
        client.sendall(json.dumps({"command": command, "args": args or {}}).encode() + b"\n")
        reply = _read_line(client)
    try:
        return json.loads(reply)
    except ValueError:
        raise ConnectionError(f"the emulator at {path} answered {reply[:80]!r}, not JSON") from None


def _read_line(connection: socket.socket) -> bytes:
    data = bytearray()
    while not data.endswith(b"\n") and len(data) < MAX_REQUEST_BYTES:
        chunk = connection.recv(4096)
        if not chunk:
            break
        data += chunk
    return bytes(data)
