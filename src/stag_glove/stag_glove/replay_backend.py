"""The raw frames of a recorded dataset file, replayed at the glove's frame rate."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .backend import BackendStatus, PacedBackend
from .dataset import load_dataset


class ReplayGloveBackend(PacedBackend):
    """Replays the raw frames of a dataset file (metadata.mat or HDF5) in order."""

    def __init__(self, path: str | Path, rate_hz: float = 7.3, loop: bool = True) -> None:
        self.path = Path(path)
        self.dataset = load_dataset(self.path)
        if not np.issubdtype(self.dataset.pressure.dtype, np.integer):
            raise ValueError(f"{self.path}: replay needs raw 10-bit counts, pressure has dtype "
                             f"{self.dataset.pressure.dtype}")
        self.loop = loop
        super().__init__(self._frames(), rate_hz)

    def _frames(self) -> Iterator[np.ndarray]:
        while True:
            yield from self.dataset.pressure
            if not self.loop:
                return

    def status(self) -> BackendStatus:
        state = "finished" if self.finished else "replaying"
        return BackendStatus(not self.finished, f"{state} {self.path.name}",
                             {"file": str(self.path), "frames": str(self.frames_sent),
                              "file_frames": str(len(self.dataset))})
