"""Serial backend on a pseudo-terminal: corruption, garbage, gaps and a hang-up mid-stream."""
import threading
import time

import numpy as np
import pytest

from prisma_tactile_driver.protocol import encode_frame
from prisma_tactile_driver.pty_hub import PtyHubPort
from prisma_tactile_driver.serial_backend import SerialHubBackend

N_FRAMES = 10_000
CORRUPT_P = 0.01
HANG_UP_AT = 5_000


class Script:
    """What the emulated hub sends, and the ground truth of which frames arrive intact."""

    def __init__(self, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.chunks: list[bytes] = []  # one per sequence number sent (with garbage before it)
        self.intact: list[int] = []
        self.damaged: list[int] = []
        self.skipped: list[int] = []
        self.garbage_bytes = 0
        self.garbage_bursts = 0
        self.deliberate_crc = 0
        self.corrupted_bytes = 0
        self.total_bytes = 0
        self.counts = {}
        skip = set(rng.choice(np.arange(100, N_FRAMES - 100), 20, replace=False).tolist())
        for seq in range(N_FRAMES):
            if seq in skip:  # the hub never sends it: a sequence gap
                self.skipped.append(seq)
                self.chunks.append(b"")
                continue
            counts = rng.integers(0, 4096, (5, 9))
            self.counts[seq] = counts
            frame = bytearray(encode_frame(seq, counts))
            damaged = False
            last = seq >= N_FRAMES - 5  # the tail stays clean so the final gap is observed
            if seq == HANG_UP_AT:
                damaged = True  # cut in half by the hang-up
            elif not last:
                if rng.random() < 0.002:  # a wrong CRC
                    frame[-1] ^= 0x5A
                    self.deliberate_crc += 1
                    damaged = True
                flips = np.flatnonzero(rng.random(len(frame)) < CORRUPT_P)
                for i in flips:
                    frame[i] ^= int(rng.integers(1, 256))
                self.corrupted_bytes += len(flips)
                damaged |= len(flips) > 0
            garbage = b""
            if not last and seq != HANG_UP_AT and rng.random() < 0.005:
                garbage = rng.integers(0, 256, int(rng.integers(1, 40))).astype(np.uint8).tobytes()
                self.garbage_bytes += len(garbage)
                self.garbage_bursts += 1
            (self.damaged if damaged else self.intact).append(seq)
            self.chunks.append(garbage + bytes(frame))
            self.total_bytes += len(frame)


def run_hub(port: PtyHubPort, script: Script, backend: SerialHubBackend, errors: list) -> None:
    written = 0
    try:
        for seq, chunk in enumerate(script.chunks):
            if seq == HANG_UP_AT:
                half = chunk[:len(chunk) // 2]
                port.write(half)
                written += len(half)
                # Hang up only once the driver has read every byte sent so far: a pty's FIONREAD
                # does not count bytes still in the kernel's flip buffer, so port.drain() alone
                # can return early under load and the hang-up would discard whole frames.
                deadline = time.monotonic() + 10
                while backend.link.bytes_read < written:
                    assert time.monotonic() < deadline, "driver stopped reading"
                    time.sleep(0.001)
                port.hang_up()
                time.sleep(0.05)  # unplugged for a while: the driver's open attempts fail
                port.open()
                deadline = time.monotonic() + 10
                while backend.link.reconnects < 1:  # the driver reopened the port
                    assert time.monotonic() < deadline, "driver never reconnected"
                    time.sleep(0.001)
                continue
            port.write(chunk)
            written += len(chunk)
    except Exception as exc:  # surfaced by the test thread
        errors.append(exc)


def test_ten_thousand_frames_with_corruption_and_a_hang_up(tmp_path):
    script = Script(seed=0)
    assert 0.009 < script.corrupted_bytes / script.total_bytes < 0.011
    port = PtyHubPort(tmp_path / "ttyHUB")
    port.open()
    backend = SerialHubBackend(str(port.link_path), 1_000_000, read_timeout_s=0.005,
                               backoff_initial_s=0.01, backoff_max_s=0.2)
    # pyserial flushes the input buffer when it opens the port, so the hub starts streaming only
    # once the driver has opened it (the first poll does); frame 0 is then intact on the link.
    assert backend.poll_frames() == []
    errors: list = []
    writer = threading.Thread(target=run_hub, args=(port, script, backend, errors), daemon=True)
    writer.start()
    delivered = []
    deadline = time.monotonic() + 120
    while not delivered or delivered[-1].sequence != N_FRAMES - 1:
        assert time.monotonic() < deadline and not errors, errors
        delivered += backend.poll_frames()
    writer.join(5)
    port.close()
    backend.close()

    # every intact frame exactly once, in order, with its data; nothing else
    assert [f.sequence for f in delivered] == script.intact
    for frame in delivered[::97]:
        np.testing.assert_array_equal(frame.counts, script.counts[frame.sequence])
    c = backend.counters()
    lost = len(script.damaged) + len(script.skipped)
    assert len(script.damaged) > 4000  # 1% of bytes hits about half of the 78-byte frames
    assert c["frames"] == len(script.intact)
    assert c["missed_frames"] == lost  # every damaged or never-sent frame is counted
    runs = np.sum(np.diff(np.flatnonzero(np.isin(np.arange(N_FRAMES), script.intact))) > 1)
    assert c["gaps"] == runs
    assert script.deliberate_crc <= c["crc_errors"] <= len(script.damaged)
    assert c["crc_errors"] + c["bad_headers"] > 0.8 * len(script.damaged)
    # the bytes of a damaged frame are always skipped: each run of misses holding one loses sync
    missing = np.setdiff1d(np.arange(N_FRAMES), script.intact)
    run_ids = np.cumsum(np.diff(missing, prepend=-2) > 1)
    damaged_runs = len(np.unique(run_ids[np.isin(missing, script.damaged)]))
    assert damaged_runs <= c["resyncs"] <= c["crc_errors"] + c["bad_headers"] + damaged_runs + script.garbage_bursts
    assert c["garbage_bytes"] >= script.garbage_bytes
    assert c["restarts"] == 0
    assert c["disconnects"] == 1 and c["reconnects"] == 1 and c["opens"] == 2
    assert c["partial_frames_dropped"] == 1
    assert c["open_failures"] >= 1  # the port was absent for a while


def test_absent_port_backs_off_exponentially(tmp_path):
    now = [0.0]
    backend = SerialHubBackend(str(tmp_path / "missing"), 115200, backoff_initial_s=0.1,
                               backoff_max_s=0.4, monotonic=lambda: now[0])
    attempts = []
    for step in range(120):
        now[0] = step * 0.01
        before = backend.link.open_failures
        assert backend.read(0) == []
        if backend.link.open_failures > before:
            attempts.append(round(now[0], 2))
    # waits of 0.1, 0.2, 0.4, then capped at 0.4 (polled every 10 ms)
    np.testing.assert_allclose(attempts[:5], [0.0, 0.1, 0.3, 0.7, 1.1], atol=0.0101)
    assert "missing" in backend.last_error
    with pytest.raises(ValueError, match="baud"):
        SerialHubBackend("x", 0)


def test_open_failure_says_why_once_per_change(tmp_path):
    """The port and the OS reason reach /diagnostics (message and values) and, once per change,
    take_errors() (what the node logs)."""
    from prisma_common.diagnostics import ERROR, OK
    from prisma_common.hand import FINGERS
    from prisma_tactile_driver.tactile_driver_core import TactileHub

    link = tmp_path / "ttyHUB"
    now = [0.0]
    backend = SerialHubBackend(str(link), 1_000_000, backoff_initial_s=0.01, backoff_max_s=0.01,
                               monotonic=lambda: now[0])
    hub = TactileHub(backend, FINGERS)

    def poll_for(seconds, start):
        for step in range(int(seconds / 0.002)):
            now[0] = start + step * 0.002
            hub.poll(int(now[0] * 1e9))

    missing = f"cannot open serial port {link}: [Errno 2] No such file or directory"
    poll_for(0.1, 0.0)
    assert backend.link.open_failures == 10  # retried every 10 ms...
    assert hub.take_errors() == [missing]  # ...said once
    status = hub.diagnostics(int(0.1e9))[0]
    assert status.level == ERROR
    assert status.message == f"stale: {', '.join(FINGERS)}; {missing}"
    assert status.values["port"] == str(link) and status.values["last_error"] == missing
    link.mkdir()  # a different reason is said again
    poll_for(0.05, 0.1)
    assert hub.take_errors() == [f"cannot open serial port {link}: [Errno 21] Is a directory"]
    link.rmdir()
    port = PtyHubPort(link)
    port.open()
    try:
        poll_for(0.02, 0.2)
        assert backend.connected and hub.take_errors() == []
        port.write(encode_frame(0, np.zeros((5, 9), dtype=int)))
        deadline = time.monotonic() + 5
        while backend.parser.stats.frames == 0:
            assert time.monotonic() < deadline
            poll_for(0.002, 0.3)
        status = hub.diagnostics(int(now[0] * 1e9))[0]
        assert status.level == OK and status.values["last_error"].endswith("Is a directory")
        port.hang_up()
        deadline = time.monotonic() + 5
        while backend.connected:
            assert time.monotonic() < deadline
            poll_for(0.002, 0.4)
        lost = hub.take_errors()
        assert len(lost) == 1 and lost[0].startswith(f"serial port {link} lost: ")
        poll_for(0.1, 0.5)
        assert hub.take_errors() == [missing]  # the same reason as before, but the link worked since
    finally:
        port.close()
        hub.close()
