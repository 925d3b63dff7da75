"""The emulated hand's control socket, its wire format defined once for both ends: the emulator
serves it (prisma_hand_emulator.emulator_control), `prisma-hand-fault` and the tactile driver's
`~/replace_object` on `hand.launch.py hardware:=emulated` (its `emulator_control` parameter) send to it.

One request per connection, a line of UTF-8 JSON: `{"command": "<name>", "args": {...}}`. One reply,
a line of JSON: `{"ok": true, "message": "..."}`, `{"ok": true, "status": {...}}` for `status`, or
`{"ok": false, "error": "..."}` naming what was refused and why.
"""
from __future__ import annotations

import json
import socket
from pathlib import Path
from typing import Any

CONTROL_SOCKET_NAME = "control.sock"  # in the emulator's directory (prisma-hand-emulator --dir)
# the request that puts the world's object back between the open fingers (the sim hand's
# tactile_driver does it in its own world; on the emulated hand the world is the emulator's)
REPLACE_OBJECT = "replace-object"
MAX_LINE_BYTES = 65536
REQUEST_SHAPE = '{"command": "<name>", "args": {...}}'


def encode_request(command: str, args: dict[str, Any] | None = None) -> bytes:
    return json.dumps({"command": command, "args": args or {}}).encode() + b"\n"


def decode_request(line: bytes) -> tuple[str, dict[str, Any]]:
    """(command, args) of one request line; ValueError saying what is wrong with it."""
    try:
        request = json.loads(line)
    except ValueError as exc:
        raise ValueError(f"request is not JSON ({exc})") from None
    if not isinstance(request, dict) or not isinstance(request.get("command"), str) \
            or not isinstance(request.get("args", {}), dict):
        raise ValueError(f"request must be {REQUEST_SHAPE}")
    return request["command"], request.get("args", {})


def done(message: str) -> dict[str, Any]:
    return {"ok": True, "message": message}


def refused(error: str) -> dict[str, Any]:
    return {"ok": False, "error": error}


def encode_reply(reply: dict[str, Any]) -> bytes:
    return json.dumps(reply).encode() + b"\n"


def reply_text(reply: dict[str, Any]) -> tuple[bool, str]:
    """(whether it was done, what the emulator said: its message or its reason for refusing)."""
    if reply.get("ok"):
        return True, str(reply.get("message", ""))
    return False, str(reply.get("error", reply))


def send(path: str | Path, command: str, args: dict[str, Any] | None = None,
         timeout_s: float = 5.0) -> dict[str, Any]:
    """One request to the emulator whose control socket is `path`, its reply. ConnectionError
    naming the path and the OS's reason when nobody answers there (the caller says how to start or
    reach one), or when the answer is not a JSON reply; TimeoutError after `timeout_s`."""
    path = Path(path)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as client:
        client.settimeout(timeout_s)
        try:
            client.connect(str(path))
        except (FileNotFoundError, ConnectionRefusedError) as exc:
            raise ConnectionError(f"no emulated hand at {path} ({exc.strerror})") from None
        client.sendall(encode_request(command, args))
        line = read_line(client)
    try:
        reply = json.loads(line)
    except ValueError:
        reply = None
    if not isinstance(reply, dict):
        raise ConnectionError(f"the emulator at {path} answered {line[:80]!r}, not a JSON reply")
    return reply


def read_line(connection: socket.socket) -> bytes:
    """Bytes up to and with the first newline (or the peer's end, or MAX_LINE_BYTES)."""
    data = bytearray()
    while not data.endswith(b"\n") and len(data) < MAX_LINE_BYTES:
        chunk = connection.recv(4096)
        if not chunk:
            break
        data += chunk
    return bytes(data)
