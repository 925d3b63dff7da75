"""Serial backend on a pseudo-terminal with a readout-board emulator in a thread: real pyserial
code path, corrupt bytes, unplug and reconnect with backoff."""
import os
import threading
import time

import numpy as np
import pytest

from stag_glove.protocol import encode_frame
from stag_glove.serial_backend import SerialGloveBackend

NS = 1_000_000_000


class BoardEmulator:
    """Writes protocol frames (optionally with garbage between them) to the master side of a pty."""

    def __init__(self):
        self.master, slave = os.openpty()
        self.port = os.ttyname(slave)
        self._slave = slave  # keep the slave open so the pty exists until we close it
        self.frames = []

    def send(self, raw, sequence, garbage=b""):
        self.frames.append(raw)
        os.write(self.master, garbage + encode_frame(raw, sequence))

    def send_in_thread(self, items):
        thread = threading.Thread(target=lambda: [self.send(*item) for item in items])
        thread.start()
        return thread

    def unplug(self):
        os.close(self.master)
        os.close(self._slave)


def poll_until(backend, count, now_ns, timeout_s=5.0):
    got, deadline = [], time.monotonic() + timeout_s
    while len(got) < count and time.monotonic() < deadline:
        got += backend.poll(now_ns)
        time.sleep(0.002)
    return got


def poll_until_disconnected(backend, now_ns, timeout_s=5.0):
    """Poll until the backend notices its device gone (a read fails), at most `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    while backend.connected and time.monotonic() < deadline:
        backend.poll(now_ns)
        time.sleep(0.002)


def frame(seed):
    return np.random.default_rng(seed).integers(0, 1024, (32, 32)).astype(np.uint16)


def test_frames_arrive_through_pyserial_with_garbage_counted():
    board = BoardEmulator()
    backend = SerialGloveBackend(board.port, baudrate=250000)
    try:
        backend.poll(0)  # open first: opening a port flushes what arrived before
        thread = board.send_in_thread([(frame(0), 0, b""), (frame(1), 1, b"\x00\xa5\x13noise"), (frame(2), 3, b"")])
        got = poll_until(backend, 3, now_ns=42)
        thread.join()
        assert [f.sequence for f in got] == [0, 1, 3]
        for f, seed in zip(got, (0, 1, 2)):
            np.testing.assert_array_equal(f.raw, frame(seed))
        assert all(f.stamp_ns == 42 for f in got)
        status = backend.status()
        assert status.connected
        assert status.values["discarded_bytes"] == "8"
        assert status.values["dropped_frames"] == "1"
    finally:
        backend.close()
        board.unplug()


def test_missing_port_is_retried_with_exponential_backoff(tmp_path):
    link = tmp_path / "ttyGLOVE"
    backend = SerialGloveBackend(str(link), backoff_initial_s=0.5, backoff_max_s=2.0)
    assert backend.poll(0) == [] and backend.stats.open_failures == 1
    assert backend.poll(int(0.4 * NS)) == [] and backend.stats.open_failures == 1  # still backing off
    backend.poll(int(0.5 * NS))
    assert backend.stats.open_failures == 2  # retried at 0.5 s, next wait 1 s
    backend.poll(int(1.4 * NS))
    assert backend.stats.open_failures == 2
    backend.poll(int(1.5 * NS))
    assert backend.stats.open_failures == 3  # next wait 2 s (capped)
    assert "cannot open" in backend.status().message
    board = BoardEmulator()
    try:
        link.symlink_to(board.port)
        backend.poll(int(3.4 * NS))
        assert backend.stats.opens == 0
        backend.poll(int(3.5 * NS))
        assert backend.stats.opens == 1  # opening flushes stale input, so the board talks after this
        board.send(frame(5), 7)
        got = poll_until(backend, 1, now_ns=int(3.6 * NS))
        assert [f.sequence for f in got] == [7]
    finally:
        backend.close()
        board.unplug()


def test_unplugged_board_reconnects_and_frames_resume(tmp_path):
    link = tmp_path / "ttyGLOVE"
    first = BoardEmulator()
    link.symlink_to(first.port)
    backend = SerialGloveBackend(str(link), backoff_initial_s=0.1)
    try:
        backend.poll(0)
        assert backend.connected
        first.send(frame(0), 0)
        assert len(poll_until(backend, 1, 0)) == 1
        first.unplug()
        link.unlink()
        poll_until_disconnected(backend, NS)
        assert not backend.connected and backend.stats.disconnects == 1
        assert "read failed" in backend.last_error
        second = BoardEmulator()
        link.symlink_to(second.port)
        backend.poll(2 * NS)
        assert backend.connected
        second.send(frame(1), 100)
        got = poll_until(backend, 1, 2 * NS)
        assert [f.sequence for f in got] == [100]
        assert backend.stats.opens == 2
        assert backend.parser.stats.dropped_frames == 0  # sequence history restarts after a reconnect
        second.unplug()
    finally:
        backend.close()


def test_bad_configuration_is_rejected_with_the_value():
    with pytest.raises(ValueError, match="port"):
        SerialGloveBackend("")
    with pytest.raises(ValueError, match="-5"):
        SerialGloveBackend("/dev/null", baudrate=-5)


def test_open_and_read_failures_are_said_once_with_the_port_and_os_reason(tmp_path):
    link = tmp_path / "ttyGLOVE"
    backend = SerialGloveBackend(str(link), backoff_initial_s=0.1, backoff_max_s=0.1)
    missing = f"cannot open {link}: [Errno 2] No such file or directory"
    for step in range(10):
        backend.poll(step * NS // 10)
    assert backend.stats.open_failures == 10  # retried every 0.1 s...
    assert backend.take_errors() == [missing]  # ...said once
    status = backend.status()
    assert not status.connected and status.message == f"disconnected: {missing}"
    assert status.values["port"] == str(link) and status.values["last_error"] == missing
    board = BoardEmulator()
    try:
        link.symlink_to(board.port)
        backend.poll(NS)
        assert backend.connected and backend.take_errors() == []
        board.unplug()
        link.unlink()
        poll_until_disconnected(backend, NS)
        [lost] = backend.take_errors()
        assert lost.startswith(f"read failed on {link}: ")
        backend.poll(2 * NS)
        assert backend.take_errors() == [missing]  # the same reason again: the port worked since
    finally:
        backend.close()
