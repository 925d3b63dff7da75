"""The emulated I2C bus (`i2c_emulator`) served to another process over a Unix stream socket.

The hand emulator process owns the `EmulatedI2CBus` and serves it with `I2CSocketServer`; the
tactile driver (`backend: i2c`, `i2c_socket: <path>`) opens it with `SocketSMBus`, a real
smbus2.SMBus whose I2C_RDWR ioctl travels over the socket, so the I2C backend runs the same
smbus2 code as on /dev/i2c-N and sees the same errors: OSError(errno) from the far end's
`transfer` (EREMOTEIO for a NACK), OSError of connect() when nobody serves the path.

Framing (docs/protocols.md, "Emulated I2C bus socket"); integers little-endian:

    frame    = u32 length of body, then body
    request  = u8 version (1), u8 count (1..42), count x message
    message  = u16 address, u8 is_read (0 | 1), u16 length, then `length` bytes for a write
    reply    = u8 version (1), u16 errno, then
               errno 0: the bytes read by each read message, in order, each as long as asked
               else:    the error's message, UTF-8

One request is one I2C_RDWR transaction and gets one reply; a connection carries any number of
them, one at a time. A malformed request is answered EPROTO (the length prefix keeps the stream
in step); a frame longer than MAX_BODY ends the connection.

Paths are the user's to name: `start()` takes a free path or a stale socket and nothing else, and
`close()` removes only the socket this server bound (`prisma_common.unix_socket`).
"""
from __future__ import annotations

import errno
import os
import socket
import struct
import threading
from pathlib import Path
from typing import Any

import smbus2

from prisma_common.unix_socket import bind_unix_socket, check_path_length, release_unix_socket

from .i2c_emulator import EmulatedI2CBus, Messages, check_messages, i2c_rdwr_ioctl, route_ioctl, unroute_ioctl

VERSION = 1
MAX_BODY = 1 << 20  # > 42 messages of 8192 bytes: the largest transaction i2c-dev accepts
TIMEOUT_S = 1.0  # like an I2C adapter's default timeout: past it a transfer fails with ETIMEDOUT

_FRAME = struct.Struct("<I")
_REQUEST = struct.Struct("<BB")
_MESSAGE = struct.Struct("<HBH")
_REPLY = struct.Struct("<BH")


class FramingError(ValueError):
    """Bytes on the socket that are not a frame of this protocol."""


# ------------------------------------------------------------------------------------------------
# Framing


def encode_request(messages: Messages) -> bytes:
    """One I2C_RDWR transaction as a frame: (address, is_read, length, write data) per message."""
    if not 0 < len(messages) < 256:
        raise ValueError(f"a request carries 1..255 messages, got {len(messages)}")
    parts = [_REQUEST.pack(VERSION, len(messages))]
    for address, is_read, length, data in messages:
        parts.append(_MESSAGE.pack(address, 1 if is_read else 0, length))
        if not is_read:
            if len(data) != length:
                raise ValueError(f"write to 0x{address:02X}: {len(data)} data bytes for length {length}")
            parts.append(bytes(data))
    body = b"".join(parts)
    return _FRAME.pack(len(body)) + body


def decode_request(body: bytes) -> Messages:
    """A request body -> its messages; FramingError says what is wrong with it."""
    if len(body) < _REQUEST.size:
        raise FramingError(f"request of {len(body)} bytes, shorter than its {_REQUEST.size}-byte header")
    version, count = _REQUEST.unpack_from(body)
    if version != VERSION:
        raise FramingError(f"request in protocol version {version}, this emulator speaks {VERSION}")
    offset, messages = _REQUEST.size, []
    for index in range(count):
        if offset + _MESSAGE.size > len(body):
            raise FramingError(f"request ends inside the header of message {index} of {count}")
        address, is_read, length = _MESSAGE.unpack_from(body, offset)
        offset += _MESSAGE.size
        if is_read not in (0, 1):
            raise FramingError(f"message {index}: is_read must be 0 or 1, got {is_read}")
        data = b""
        if not is_read:
            data = bytes(body[offset:offset + length])
            if len(data) != length:
                raise FramingError(f"message {index}: write of {length} bytes, the request holds {len(data)}")
            offset += length
        messages.append((address, bool(is_read), length, data))
    if offset != len(body):
        raise FramingError(f"{len(body) - offset} bytes after the last of {count} messages")
    return messages


def encode_reply(reads: list[bytes]) -> bytes:
    body = _REPLY.pack(VERSION, 0) + b"".join(reads)
    return _FRAME.pack(len(body)) + body


def encode_error(number: int, message: str) -> bytes:
    body = _REPLY.pack(VERSION, number) + message.encode("utf-8")
    return _FRAME.pack(len(body)) + body


def decode_reply(body: bytes, read_lengths: list[int]) -> list[bytes]:
    """The data of each read message, OSError(errno, message) for an error reply (as i2c-dev
    raises it), FramingError for a reply that does not answer the request."""
    if len(body) < _REPLY.size:
        raise FramingError(f"reply of {len(body)} bytes, shorter than its {_REPLY.size}-byte header")
    version, number = _REPLY.unpack_from(body)
    if version != VERSION:
        raise FramingError(f"reply in protocol version {version}, this driver speaks {VERSION}")
    payload = body[_REPLY.size:]
    if number:
        raise OSError(number, payload.decode("utf-8", "replace") or os.strerror(number))
    if len(payload) != sum(read_lengths):
        raise FramingError(f"reply carries {len(payload)} bytes read, the request asked for {sum(read_lengths)}")
    reads, offset = [], 0
    for length in read_lengths:
        reads.append(bytes(payload[offset:offset + length]))
        offset += length
    return reads


def _recv_exact(sock: socket.socket, size: int) -> bytes | None:
    """`size` bytes; None when the peer closed before the first of them."""
    buffer = bytearray(size)
    view, got = memoryview(buffer), 0
    while got < size:
        n = sock.recv_into(view[got:])
        if n == 0:
            if got == 0:
                return None
            raise ConnectionResetError(errno.ECONNRESET, "connection closed inside a frame")
        got += n
    return bytes(buffer)


def recv_frame(sock: socket.socket) -> bytes | None:
    """The body of the next frame; None when the peer closed the connection between frames."""
    header = _recv_exact(sock, _FRAME.size)
    if header is None:
        return None
    (size,) = _FRAME.unpack(header)
    if size > MAX_BODY:
        raise FramingError(f"frame of {size} bytes, at most {MAX_BODY}")
    body = _recv_exact(sock, size)
    if body is None and size:
        raise ConnectionResetError(errno.ECONNRESET, "connection closed inside a frame")
    return body or b""


# ------------------------------------------------------------------------------------------------
# Server




class I2CSocketServer:
    """Serves `bus` on a Unix stream socket at `path`, one thread per connection.

    `lock` (one is made if not given) is held around each `bus.transfer`: the emulator process
    changes the ADC values from its own thread, and several connections share the bus."""

    def __init__(self, bus: EmulatedI2CBus, path: str | Path, lock: threading.Lock | None = None) -> None:
        self.bus = bus
        self.path = Path(path)
        self.lock = lock if lock is not None else threading.Lock()
        self.connections = 0  # accepted so far
        self._listener: socket.socket | None = None
        self._identity: tuple[int, int] | None = None  # (st_ino, st_dev) of the socket this server bound
        self._state = threading.Lock()
        self._closed = False
        self._accept_thread: threading.Thread | None = None
        self._clients: dict[socket.socket, threading.Thread] = {}

    def start(self) -> I2CSocketServer:
        with self._state:
            if self._closed or self._listener is not None:
                raise RuntimeError(f"I2C socket server {self.path} was already started; a server serves once: "
                                   f"make a new I2CSocketServer")
            listener, identity = bind_unix_socket(self.path)
            try:
                listener.listen(8)
            except OSError:
                listener.close()
                release_unix_socket(self.path, identity)
                raise
            self._listener, self._identity = listener, identity
            self._accept_thread = threading.Thread(target=self._accept_loop, args=(listener,),
                                                   name=f"i2c-socket {self.path}", daemon=True)
            self._accept_thread.start()
        return self

    def _accept_loop(self, listener: socket.socket) -> None:
        while True:
            try:
                conn, _ = listener.accept()
            except OSError:
                return  # close() shut the listener down
            with self._state:
                if self._closed:
                    conn.close()
                    return
                self.connections += 1
                thread = threading.Thread(target=self._serve, args=(conn,),
                                          name=f"i2c-socket {self.path} #{self.connections}", daemon=True)
                self._clients[conn] = thread
            thread.start()

    def _serve(self, conn: socket.socket) -> None:
        try:
            while True:
                body = recv_frame(conn)
                if body is None:
                    return
                conn.sendall(self._answer(body))
        except (OSError, FramingError):
            return  # the client went away or lost step with the framing: only this connection ends
        finally:
            with self._state:
                self._clients.pop(conn, None)
            conn.close()

    def _answer(self, body: bytes) -> bytes:
        try:
            messages = decode_request(body)
            check_messages(messages)  # what i2c-dev refuses (EINVAL) is refused here too
        except FramingError as exc:
            return encode_error(errno.EPROTO, f"{os.strerror(errno.EPROTO)} ({exc})")
        except OSError as exc:  # check_messages: always EINVAL with its reason
            return encode_error(exc.errno or errno.EINVAL, exc.strerror or str(exc))
        try:
            with self.lock:
                reads = self.bus.transfer(messages)
        except OSError as exc:  # a NACK (EREMOTEIO): the driver gets it as i2c-dev would give it
            return encode_error(exc.errno or errno.EIO, exc.strerror or str(exc))
        return encode_reply(reads)

    def close(self) -> None:
        """Stop serving, end every connection, remove the socket if it is still this server's."""
        with self._state:
            if self._closed:
                return
            self._closed = True
            clients = dict(self._clients)
        release_unix_socket(self.path, self._identity)
        self._identity = None
        if self._listener is not None:
            try:
                self._listener.shutdown(socket.SHUT_RDWR)  # wakes accept() (Linux)
            except OSError:
                pass
            self._listener.close()
        for conn in clients:
            try:
                conn.shutdown(socket.SHUT_RDWR)  # the serving thread closes it
            except OSError:
                pass
        threads = ([self._accept_thread] if self._accept_thread else []) + list(clients.values())
        for thread in threads:
            if thread is not threading.current_thread():
                thread.join(timeout=2.0)

    def __enter__(self) -> I2CSocketServer:
        return self if self._listener is not None else self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()


# ------------------------------------------------------------------------------------------------
# Client


def _connect(path: Path, timeout_s: float) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout_s)
    try:
        sock.connect(str(path))
    except BaseException:
        sock.close()
        raise
    return sock


class SocketSMBus(smbus2.SMBus):
    """A real smbus2.SMBus (its own i2c_msg marshalling and i2c_rdwr) whose I2C_RDWR ioctl reaches
    an `I2CSocketServer` at `path` instead of /dev/i2c-N.

    Opening fails with connect()'s OSError (ENOENT: nobody serves the path, ECONNREFUSED: a stale
    socket), as opening a missing /dev/i2c-N does. A transfer raises OSError(errno, message) for an
    error reply (EREMOTEIO for a NACK), and for a broken connection (the emulator restarted) or
    one silent for `timeout_s` (ETIMEDOUT); the next transfer then connects again."""

    def __init__(self, path: str | Path, timeout_s: float = TIMEOUT_S) -> None:
        super().__init__(None)
        self.path = Path(path)
        check_path_length(self.path)
        self.timeout_s = timeout_s
        self.connects = 0
        self._sock: socket.socket | None = _connect(self.path, timeout_s)
        self.connects += 1
        self._io = threading.Lock()  # one transaction at a time on the connection, as i2c-dev does
        self.funcs = smbus2.I2cFunc.I2C  # what I2C_FUNCS reports for an adapter that does I2C_RDWR
        self.fd = route_ioctl(self._ioctl)

    def _ioctl(self, fd: int, request: int, arg: Any) -> int:
        return i2c_rdwr_ioctl(self._transfer, request, arg)

    def _drop(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _transfer(self, messages: Messages) -> list[bytes]:
        request = encode_request(messages)
        with self._io:
            if self._sock is None:
                try:
                    self._sock = _connect(self.path, self.timeout_s)
                except OSError as exc:
                    number = exc.errno or errno.EIO
                    raise OSError(number, f"{os.strerror(number)} (reconnecting to the emulated bus)") from None
                self.connects += 1
            try:
                self._sock.sendall(request)
                body = recv_frame(self._sock)
                if body is None:
                    raise ConnectionResetError(errno.ECONNRESET, "closed by the emulator")
            except FramingError as exc:
                self._drop()  # out of step with the emulator: start afresh
                raise OSError(errno.EPROTO, f"{os.strerror(errno.EPROTO)} (emulated bus: {exc})") from None
            except TimeoutError:
                self._drop()  # a late reply would answer the next request
                raise OSError(errno.ETIMEDOUT, f"{os.strerror(errno.ETIMEDOUT)} (emulated bus silent for "
                                               f"{self.timeout_s:g} s)") from None
            except OSError as exc:
                self._drop()
                number = exc.errno or errno.ECONNRESET
                raise OSError(number, f"{os.strerror(number)} (emulated bus lost)") from None
            try:
                return decode_reply(body, [length for _, is_read, length, _ in messages if is_read])
            except FramingError as exc:
                self._drop()
                raise OSError(errno.EPROTO, f"{os.strerror(errno.EPROTO)} (emulated bus: {exc})") from None

    def close(self) -> None:
        unroute_ioctl(self.fd)  # SMBus.close would os.close() the pseudo descriptor
        self.fd = None
        with self._io:
            self._drop()
