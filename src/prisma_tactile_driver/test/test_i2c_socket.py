"""The emulated I2C bus served over a Unix socket: the I2C backend through SocketSMBus (real smbus2
marshalling) against an I2CSocketServer, its errors, reconnects and the socket path's safety."""
import errno
import os
import socket
import struct
import threading
import time

import numpy as np
import pytest
from smbus2 import i2c_msg

from prisma_common.diagnostics import ERROR, OK
from prisma_common.hand import FINGERS
from prisma_tactile_driver.i2c_backend import I2CHubBackend
from prisma_tactile_driver.i2c_emulator import EmulatedSMBus, five_finger_bus
from prisma_tactile_driver.i2c_socket import (
    FramingError,
    I2CSocketServer,
    SocketSMBus,
    decode_reply,
    decode_request,
    encode_error,
    encode_reply,
    encode_request,
    recv_frame,
)
from prisma_tactile_driver.tactile_driver_core import TactileHub

CHANNELS = {"thumb": 0, "index": 1, "middle": 2, "ring": 3, "little": 4}
RNG = np.random.default_rng(11)
VALUES = {ch: RNG.integers(0, 4096, 12) for ch in range(5)}
MS = 1_000_000
NACK = "[Errno 121] Remote I/O error (no ACK from 0x35)"


@pytest.fixture
def bus():
    return five_finger_bus(VALUES)


@pytest.fixture
def serve(tmp_path):
    """serve(bus, path=None, lock=None): a started server, closed after the test."""
    servers = []

    def start(bus, path=None, lock=None):
        server = I2CSocketServer(bus, path or tmp_path / "i2c.sock", lock).start()
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.close()


@pytest.fixture
def socket_backend():
    """socket_backend(path, **kwargs): an I2CHubBackend over SocketSMBus, closed after the test."""
    backends = []

    def make(path, **kwargs):
        backends.append(I2CHubBackend(str(path), CHANNELS, bus_factory=SocketSMBus, **kwargs))
        return backends[-1]

    yield make
    for backend in backends:
        backend.close()


def assert_exact_counts(counts, channels=CHANNELS):
    assert set(counts) == set(channels)
    for finger, ch in channels.items():
        np.testing.assert_array_equal(counts[finger], VALUES[ch][:9])


# ------------------------------------------------------------------------------------------------
# The backend over the socket


def test_backend_reads_exactly_the_served_adc_values(bus, serve, socket_backend):
    server = serve(bus)
    backend = socket_backend(server.path)
    assert backend.bus_name == str(server.path) and backend.open_error == ""
    [reading] = backend.read(0)
    assert_exact_counts(reading.counts)
    assert bus.transfers == 2 * 5  # per finger: the mux select, then setup + configuration + 18-byte read
    assert bus.adcs[4].setup == 0x82 and bus.adcs[4].config == 0x11 and bus.mux_control == 1 << 4
    # the emulator process changes a value under the shared lock: the next scan reads it
    with server.lock:
        bus.adcs[1].values[5] = 4095
    [reading] = backend.read(10 * MS)
    assert reading.counts["index"][5] == 4095 and reading.counts["index"][4] == VALUES[1][4]
    assert server.connections == 1 and backend._bus.connects == 1


def test_errno_replies_are_the_oserrors_of_the_in_process_bus(bus, serve):
    server = serve(bus)
    with SocketSMBus(server.path) as remote:
        local = EmulatedSMBus(five_finger_bus(VALUES))
        for smbus in (remote, local):  # nothing selected on the mux: the ADC does not acknowledge
            with pytest.raises(OSError) as info:
                smbus.i2c_rdwr(i2c_msg.write(0x35, [0x82, 0x11]))
            assert info.value.errno == errno.EREMOTEIO and str(info.value) == NACK
        remote.i2c_rdwr(i2c_msg.write(0x70, [1 << 3]))
        readback = i2c_msg.read(0x70, 1)
        remote.i2c_rdwr(readback)
        assert bytes(readback) == bytes([0x08])
        # i2c-dev's own limits: more than 42 messages, or one over 8192 bytes -> EINVAL
        with pytest.raises(OSError) as info:
            remote.i2c_rdwr(*[i2c_msg.write(0x70, [0])] * 43)
        assert info.value.errno == errno.EINVAL and "43 messages" in str(info.value)
        with pytest.raises(OSError) as info:
            remote.i2c_rdwr(i2c_msg.read(0x35, 8193))
        assert info.value.errno == errno.EINVAL
        with pytest.raises(OSError) as info:  # SMBus calls need other ioctls, which the bus does not do
            remote.read_byte(0x70)
        assert info.value.errno == errno.ENOTTY
        assert bus.transfers == 3 and remote.connects == 1  # errors keep the connection
    local.close()


def test_failing_adc_gives_eremoteio_counted_per_finger_and_recovers(bus, serve, socket_backend):
    server = serve(bus)
    bus.adcs[2].failing = True  # the middle finger's sensor is unplugged
    backend = socket_backend(server.path, retries=2)
    hub = TactileHub(backend, FINGERS, stale_timeout_ns=100 * MS)
    frames = []
    for step in range(20):  # 200 ms at 100 Hz
        frames += hub.poll(step * 10 * MS)
    assert len(frames) == 4 * 20 and {f.finger for f in frames} == {"thumb", "index", "ring", "little"}
    counters = backend.counters()
    assert counters["middle_errors"] == 3 * 20 and counters["middle_failed_scans"] == 20
    assert counters["middle_reads"] == 0 and counters["thumb_reads"] == 20 and counters["thumb_errors"] == 0
    assert backend.stats["middle"].last_error == f"mux channel 2: {NACK}"
    assert hub.take_errors() == [f"middle: mux channel 2: {NACK}"]
    bus.adcs[2].failing = False  # plugged back in
    assert {f.finger for f in hub.poll(200 * MS)} == set(FINGERS)
    assert hub.stale_fingers(200 * MS) == [] and backend.link_status().error == ""
    # transient trouble within the retries: counted, read all the same
    bus.adcs[3].nack_next = 2
    [reading] = backend.read(210 * MS)
    np.testing.assert_array_equal(reading.counts["ring"], VALUES[3][:9])
    assert backend.stats["ring"].errors == 2 and backend.stats["ring"].failed_scans == 0


def test_glitched_read_is_rejected_as_a_bad_read(bus, serve, socket_backend):
    server = serve(bus)
    backend = socket_backend(server.path, retries=2)
    bus.adcs[1].glitch_next = 1  # one all-zero read of the index finger's ADC
    [reading] = backend.read(0)
    assert_exact_counts(reading.counts)  # the retry read it right
    stats = backend.stats["index"]
    assert stats.errors == 1 and stats.bad_reads == 1 and stats.failed_scans == 0
    bus.adcs[1].glitch_next = 3  # outlasting the retries: left out of that scan
    [reading] = backend.read(10 * MS)
    assert set(reading.counts) == set(FINGERS) - {"index"}
    assert stats.bad_reads == 4 and stats.failed_scans == 1
    assert stats.last_error == ("mux channel 1: bad MAX11617 read: high nibble not 1111 in "
                                "AIN0 0x0000, AIN1 0x0000, AIN2 0x0000 and 6 more")


def test_no_server_says_path_and_reason_and_the_bus_opens_once_served(bus, tmp_path, socket_backend):
    path = tmp_path / "i2c.sock"
    backend = socket_backend(path)
    hub = TactileHub(backend, FINGERS)
    for t_ms in range(0, 2500, 10):
        assert hub.poll(t_ms * MS) == []
    reason = f"cannot open I2C bus {path}: [Errno 2] No such file or directory"
    assert backend.link_status().error == reason and hub.take_errors() == [reason]
    assert backend.counters()["open_failures"] == 4  # at construction, at the first read, then once a second
    status = hub.diagnostics(2500 * MS)[0]
    assert status.level == ERROR and status.values["bus"] == str(path)
    with I2CSocketServer(bus, path):
        assert hub.poll(2990 * MS) == []  # the next try is due at 3 s
        assert {f.finger for f in hub.poll(3000 * MS)} == set(FINGERS)
        assert backend.counters()["open_failures"] == 4 and backend.link_status().error == ""
        assert hub.diagnostics(3000 * MS)[0].level == OK


def test_a_stale_socket_is_refused_by_the_driver_and_replaced_by_the_server(bus, tmp_path, socket_backend):
    path = tmp_path / "i2c.sock"
    stale = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    stale.bind(str(path))  # an emulator killed before it could remove its socket
    stale.close()
    backend = socket_backend(path)
    assert backend.link_status().error == f"cannot open I2C bus {path}: [Errno 111] Connection refused"
    with I2CSocketServer(bus, path):
        [reading] = backend.read(1000 * MS)
        assert_exact_counts(reading.counts)
    assert not os.path.lexists(path)


def test_server_restart_gives_errors_then_recovery(bus, serve, socket_backend):
    server = serve(bus)
    backend = socket_backend(server.path, retries=2)
    hub = TactileHub(backend, FINGERS, stale_timeout_ns=100 * MS)
    assert len(hub.poll(0)) == 5
    server.close()  # the emulator stops (or is restarted)
    assert hub.poll(10 * MS) == []
    counters = backend.counters()
    gone = "[Errno 2] No such file or directory (reconnecting to the emulated bus)"
    for finger in FINGERS:  # every attempt a bus error: the lost connection, then no socket to reconnect to
        assert counters[f"{finger}_errors"] == 3 and counters[f"{finger}_failed_scans"] == 1
        assert backend.stats[finger].last_error == f"mux channel {CHANNELS[finger]}: {gone}"
    assert counters["open_failures"] == 0  # the bus stays open; only its transfers fail
    assert hub.take_errors() == ["; ".join(f"{f}: mux channel {ch}: {gone}" for f, ch in CHANNELS.items())]
    serve(bus, server.path)  # the emulator is back at the same path
    assert {f.finger for f in hub.poll(20 * MS)} == set(FINGERS)
    assert backend._bus.connects == 2 and backend.link_status().error == ""
    assert hub.stale_fingers(20 * MS) == []


def test_a_lost_connection_is_one_error_and_the_next_transfer_reconnects(bus, serve):
    server = serve(bus)
    smbus = SocketSMBus(server.path)
    select = i2c_msg.write(0x70, [1 << 2])
    smbus.i2c_rdwr(select)
    server.close()
    with pytest.raises(OSError) as info:
        smbus.i2c_rdwr(select)
    assert info.value.errno in (errno.EPIPE, errno.ECONNRESET) and str(info.value).endswith("(emulated bus lost)")
    with pytest.raises(OSError) as info:
        smbus.i2c_rdwr(select)
    assert info.value.errno == errno.ENOENT
    serve(bus, server.path)
    smbus.i2c_rdwr(select)
    assert smbus.connects == 2
    smbus.close()


def test_a_silent_emulator_times_out_and_the_connection_starts_afresh(bus, serve):
    lock = threading.Lock()
    server = serve(bus, lock=lock)
    smbus = SocketSMBus(server.path, timeout_s=0.2)
    select = i2c_msg.write(0x70, [1 << 1])
    with lock:  # the emulator's own thread holds the bus
        start = time.monotonic()
        with pytest.raises(OSError) as info:
            smbus.i2c_rdwr(select)
        assert time.monotonic() - start >= 0.2
    assert info.value.errno == errno.ETIMEDOUT
    assert str(info.value) == "[Errno 110] Connection timed out (emulated bus silent for 0.2 s)"
    readback = i2c_msg.read(0x70, 1)
    smbus.i2c_rdwr(select)  # a new connection: the late reply to the first request cannot answer this one
    smbus.i2c_rdwr(readback)
    assert bytes(readback) == bytes([1 << 1]) and smbus.connects == 2
    smbus.close()


# ------------------------------------------------------------------------------------------------
# Framing


def test_framing_round_trip():
    messages = [(0x35, False, 2, b"\x82\x11"), (0x35, True, 18, b""), (0x70, True, 1, b"")]
    frame = encode_request(messages)
    (length,) = struct.unpack_from("<I", frame)
    assert length == len(frame) - 4 == 2 + 5 + 2 + 5 + 5
    assert frame[4:11] == bytes([1, 3, 0x35, 0x00, 0, 2, 0])  # version, count, address, is_read, length
    assert decode_request(frame[4:]) == messages
    reads = [bytes(range(18)), b"\x04"]
    assert decode_reply(encode_reply(reads)[4:], [18, 1]) == reads
    with pytest.raises(OSError) as info:
        decode_reply(encode_error(errno.EREMOTEIO, "Remote I/O error (no ACK from 0x35)")[4:], [18])
    assert info.value.errno == errno.EREMOTEIO and str(info.value) == NACK


@pytest.mark.parametrize("body, problem", [
    (b"\x01", "shorter than its 2-byte header"),
    (b"\x02\x01", "protocol version 2, this emulator speaks 1"),
    (b"\x01\x01\x35\x00", "ends inside the header of message 0 of 1"),
    (b"\x01\x01\x35\x00\x00\x02\x00\x82", "message 0: write of 2 bytes, the request holds 1"),
    (b"\x01\x01\x35\x00\x02\x01\x00", "message 0: is_read must be 0 or 1, got 2"),
    (b"\x01\x01\x35\x00\x01\x01\x00\xff", "1 bytes after the last of 1 messages"),
])
def test_malformed_requests_are_named(body, problem):
    with pytest.raises(FramingError, match=problem):
        decode_request(body)


def test_a_reply_that_does_not_answer_the_request_is_refused():
    with pytest.raises(FramingError, match="reply carries 1 bytes read, the request asked for 18"):
        decode_reply(encode_reply([b"\x00"])[4:], [18])


def test_server_answers_a_malformed_request_eproto_and_keeps_serving(bus, serve):
    server = serve(bus)
    raw = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    raw.settimeout(2.0)
    raw.connect(str(server.path))
    raw.sendall(struct.pack("<I", 2) + b"\x02\x01")
    with pytest.raises(OSError) as info:
        decode_reply(recv_frame(raw), [])
    assert info.value.errno == errno.EPROTO
    assert "request in protocol version 2, this emulator speaks 1" in str(info.value)
    raw.sendall(encode_request([(0x70, False, 1, b"\x01"), (0x70, True, 1, b"")]))
    assert decode_reply(recv_frame(raw), [1]) == [b"\x00"]  # the mux switches at the STOP
    raw.sendall(struct.pack("<I", 1 << 24))  # a frame longer than any transaction: the connection ends
    assert recv_frame(raw) is None
    raw.close()
    assert bus.transfers == 1


# ------------------------------------------------------------------------------------------------
# The socket path: nothing but the server's own socket or a stale one is touched


def test_close_removes_the_servers_socket(bus, tmp_path):
    path = tmp_path / "i2c.sock"
    with I2CSocketServer(bus, path) as server:
        assert path.is_socket()
        with pytest.raises(RuntimeError, match="already started"):
            server.start()
    assert not os.path.lexists(path)
    server.close()  # again: nothing to do


@pytest.mark.parametrize("kind, what", [
    ("file", "an existing file"), ("directory", "a directory"), ("symlink", "a symlink to "),
    ("fifo", "a named pipe"),
])
def test_anything_but_a_socket_at_the_path_is_refused_and_left_alone(bus, tmp_path, kind, what):
    path = tmp_path / "i2c.sock"
    if kind == "file":
        path.write_text("calibration notes\n")
    elif kind == "directory":
        path.mkdir()
        (path / "keep").write_text("x")
    elif kind == "symlink":
        (tmp_path / "target").write_text("x")
        path.symlink_to(tmp_path / "target")
    else:
        os.mkfifo(path)
    before = os.lstat(path)
    with pytest.raises(FileExistsError) as info:
        I2CSocketServer(bus, path).start()
    message = str(info.value)
    assert message.startswith(f"{path} is {what}") and "choose another socket path" in message
    after = os.lstat(path)
    assert (after.st_ino, after.st_mode, after.st_mtime_ns) == (before.st_ino, before.st_mode, before.st_mtime_ns)
    if kind == "file":
        assert path.read_text() == "calibration notes\n"
    if kind == "directory":
        assert (path / "keep").read_text() == "x"


def test_a_live_socket_is_refused_and_keeps_serving(bus, serve, socket_backend):
    first = serve(bus)
    with pytest.raises(FileExistsError, match="is a live socket .*stop whatever serves it"):
        I2CSocketServer(five_finger_bus(), first.path).start()
    [reading] = socket_backend(first.path).read(0)
    assert_exact_counts(reading.counts)


def test_close_leaves_a_path_someone_replaced_alone(bus, tmp_path, socket_backend):
    path = tmp_path / "i2c.sock"
    first = I2CSocketServer(bus, path).start()
    os.unlink(path)
    path.write_text("not yours")
    first.close()
    assert path.read_text() == "not yours"
    path.unlink()
    first = I2CSocketServer(bus, path).start()
    os.unlink(path)  # and a second emulator took the path over
    with I2CSocketServer(bus, path) as second:
        first.close()
        assert path.is_socket()
        [reading] = socket_backend(path).read(0)
        assert_exact_counts(reading.counts)
        assert second.connections == 1
    assert not os.path.lexists(path)


def test_a_path_too_long_for_a_unix_socket_is_named(bus, tmp_path):
    path = tmp_path / ("x" * 120)
    with pytest.raises(OSError, match=f"{path} has {len(os.fsencode(path))} bytes") as info:
        I2CSocketServer(bus, path).start()
    assert info.value.errno == errno.ENAMETOOLONG and not os.path.lexists(path)
    with pytest.raises(OSError, match="choose a shorter path"):
        SocketSMBus(path)
