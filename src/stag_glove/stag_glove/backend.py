"""Glove readout backends, the interface the driver polls: serial (the readout board,
serial_backend), sim (a synthetic glove, sim_backend) and replay (a dataset file, replay_backend).
Each is polled with the current time and returns the frames that arrived; none reads a clock
itself, so the node's timer (and use_sim_time) sets the pace.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

NS = 1_000_000_000
BACKENDS = ("serial", "sim", "replay")


@dataclass
class BackendFrame:
    stamp_ns: int
    sequence: int
    raw: np.ndarray  # uint16 [rows, cols]


@dataclass
class BackendStatus:
    connected: bool
    message: str
    values: dict[str, str] = field(default_factory=dict)


class GloveBackend(Protocol):
    def poll(self, now_ns: int) -> list[BackendFrame]: ...

    def status(self) -> BackendStatus: ...

    def take_errors(self) -> list[str]:
        """Errors (with the port and the OS reason) that appeared since the last call, each once."""
        ...

    def close(self) -> None: ...


class PacedBackend:
    """Emits frames from an iterator at `rate_hz` of the polled time (at most max_burst per poll,
    so a long pause in polling does not flood the graph)."""

    def __init__(self, frames: Iterator[np.ndarray], rate_hz: float, max_burst: int = 8) -> None:
        if rate_hz <= 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self._frame_iter = frames
        self._period_ns = int(round(NS / rate_hz))
        self._next_ns: int | None = None
        self._sequence = 0
        self._max_burst = max_burst
        self.frames_sent = 0
        self.finished = False

    def poll(self, now_ns: int) -> list[BackendFrame]:
        if self._next_ns is None:
            self._next_ns = now_ns
        out: list[BackendFrame] = []
        while self._next_ns <= now_ns and len(out) < self._max_burst and not self.finished:
            try:
                raw = next(self._frame_iter)
            except StopIteration:
                self.finished = True
                break
            out.append(BackendFrame(self._next_ns, self._sequence, np.asarray(raw, dtype=np.uint16)))
            self._sequence = (self._sequence + 1) & 0xFFFF
            self._next_ns += self._period_ns
            self.frames_sent += 1
        if self._next_ns <= now_ns and len(out) == self._max_burst:
            self._next_ns = now_ns + self._period_ns  # skip what we could not send in time
        return out

    def take_errors(self) -> list[str]:
        return []  # no link to fail

    def close(self) -> None:
        pass
