"""The pads' link to the host, the one a hand is wired with: the fingertip hub's serial end
(HubLink: one frame per scan on a pty) or the five pads' ADCs on the host's I2C bus (I2CPads, served
on a socket by the I2C socket server), and the faults of each."""
from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.hand import FINGERS
from prisma_tactile_driver.i2c_emulator import EmulatedI2CBus, Max11617, five_finger_bus
from prisma_tactile_driver.protocol import SEQUENCE_MODULO, encode_frame
from prisma_tactile_driver.pty_hub import PtyHubPort

from .fault_table import FaultError

# the pads' I2C mux channels as config/tactile_driver.yaml has them
FINGER_CHANNELS = dict(zip(FINGERS, range(5)))


@dataclass
class HubState:
    plugged: bool = True
    replug_at_ns: int | None = None  # a timed unplug ends here
    sequence: int = 0
    garbage_pending: int = 0
    corrupt_pending: int = 0
    frames_sent: int = 0
    frames_unread: int = 0  # dropped at the "adapter": nobody read the link
    frames_corrupted: int = 0
    garbage_sent: int = 0
    unplugs: int = 0


class HubLink:
    """The fingertip hub's serial end: one frame per scan on a pty behind `path`, and its faults.

    The tick sends and the control socket's thread unplugs, replugs and corrupts: every use of the
    pty and of the counters is under this link's own lock, so a fault never pulls the pty from under
    a frame being written, and nothing the hub does holds up the servos or the I2C bus."""

    def __init__(self, path: Path, buffer_bytes: int, rng: np.random.Generator) -> None:
        self.state = HubState()
        self._port = PtyHubPort(path)
        self._buffer_bytes = buffer_bytes
        self._rng = rng
        self._lock = threading.Lock()

    def open(self) -> None:
        with self._lock:
            self._port.open()

    def close(self) -> None:
        with self._lock:
            if self._port.is_open:
                self._port.hang_up()

    def send(self, counts: dict[str, np.ndarray], now_ns: int) -> None:
        """One scan's frame (a timed unplug that is over first plugs the hub back in)."""
        with self._lock:
            hub = self.state
            if not hub.plugged and hub.replug_at_ns is not None and now_ns >= hub.replug_at_ns:
                self._replug()
            frame = bytearray(encode_frame(hub.sequence, counts))
            hub.sequence = (hub.sequence + 1) % SEQUENCE_MODULO
            if not hub.plugged:
                return
            out = bytearray()
            if hub.garbage_pending:
                # no sync pattern in it: garbage that forms a false frame start would only delay the
                # next real frame, and the count of skipped bytes must equal what was sent
                garbage = self._rng.integers(0, 256, hub.garbage_pending, dtype=np.uint8)
                garbage[garbage == 0xA5] = 0xA4
                out += garbage.tobytes()
                hub.garbage_sent += hub.garbage_pending
                hub.garbage_pending = 0
            if hub.corrupt_pending:
                frame[-1] ^= 0xFF  # the CRC's high byte
                hub.corrupt_pending -= 1
                hub.frames_corrupted += 1
            out += frame
            if self._port.offer(bytes(out), self._buffer_bytes):
                hub.frames_sent += 1
            else:
                hub.frames_unread += 1

    def unplug(self, seconds: float, now_ns: int) -> str:
        with self._lock:
            hub = self.state
            if hub.plugged:
                self._port.hang_up()
                hub.plugged = False
                hub.unplugs += 1
            hub.replug_at_ns = now_ns + int(seconds * 1e9) if seconds else None
        return f"hub unplugged{f' for {seconds:g} s' if seconds else ' until hub-replug'}"

    def replug(self) -> str:
        with self._lock:
            if self.state.plugged:
                return "hub already plugged in"
            self._replug()
        return "hub plugged in"

    def _replug(self) -> None:
        self._port.open()
        self.state.plugged = True
        self.state.replug_at_ns = None
        self.state.sequence = 0  # the Nano is powered from USB: it restarts with the link

    def garbage(self, count: int) -> str:
        with self._lock:
            self.state.garbage_pending += int(count)
        return f"{count} garbage bytes before the next frame"

    def corrupt(self, frames: int) -> str:
        with self._lock:
            self.state.corrupt_pending += int(frames)
        return f"CRC of the next {frames} frame(s) corrupted"

    def status(self) -> dict[str, Any]:
        with self._lock:
            hub = self.state
            return {"plugged": hub.plugged, "frames_sent": hub.frames_sent, "frames_unread": hub.frames_unread,
                    "frames_corrupted": hub.frames_corrupted, "garbage_bytes": hub.garbage_sent,
                    "unplugs": hub.unplugs, "sequence": hub.sequence}



class I2CPads:
    """The five pads' ADCs (TCA9548A + MAX11617) on the host's I2C bus. The tick writes their
    registers and the I2C socket server reads them under `lock` (the emulator's world lock); the
    control socket's thread sets their faults under it too."""

    def __init__(self, lock: threading.Lock) -> None:
        self.bus: EmulatedI2CBus = five_finger_bus()
        self.lock = lock

    def load(self, counts: dict[str, np.ndarray]) -> None:
        """One scan's counts into the ADC registers; the caller holds `lock`."""
        for finger, channel in FINGER_CHANNELS.items():
            self.bus.adcs[channel].values[: len(counts[finger])] = counts[finger]

    def _adc(self, finger: str) -> Max11617:
        if finger not in FINGER_CHANNELS:
            raise FaultError(f"finger {finger!r}: choose one of {', '.join(FINGERS)}")
        return self.bus.adcs[FINGER_CHANNELS[finger]]

    def nack(self, finger: str, count: int) -> str:
        adc = self._adc(finger)
        with self.lock:
            if count:
                adc.nack_next += int(count)
            else:
                adc.failing = True
        return f"{finger} ADC does not acknowledge{f' {count} time(s)' if count else ' until i2c-clear'}"

    def glitch(self, finger: str, count: int) -> str:
        with self.lock:
            self._adc(finger).glitch_next += int(count)
        return f"the next {count} read(s) of the {finger} ADC return all-zero bytes"

    def clear(self) -> str:
        with self.lock:
            for adc in self.bus.adcs.values():
                adc.failing, adc.nack_next, adc.glitch_next = False, 0, 0
        return "every ADC answers again"

    def status(self) -> dict[str, Any]:
        with self.lock:
            return {"transfers": self.bus.transfers, "nacks": self.bus.nacks,
                    "failing": [f for f, ch in FINGER_CHANNELS.items() if self.bus.adcs[ch].failing]}
