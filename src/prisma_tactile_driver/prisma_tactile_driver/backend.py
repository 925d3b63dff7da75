"""What every fingertip-hub backend (serial, I2C, sim) hands the hub: readings of raw counts."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class HubReading:
    """Counts of the fingers read in one hub cycle; a finger absent from `counts` was not read."""

    sequence: int
    counts: dict[str, np.ndarray] = field(default_factory=dict)  # finger -> uint16[9]


class HubBackend(Protocol):
    def read(self, stamp_ns: int) -> list[HubReading]:
        """Everything that arrived (serial) or was scanned (I2C, sim) at `stamp_ns`. Never raises
        on link trouble: failures are counted and reported through `counters()`."""
        ...

    def counters(self) -> dict[str, int]:
        """Monotonic link counters for /diagnostics (frames, errors, reconnects...)."""
        ...

    def close(self) -> None:
        ...
