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
    # when the hub sampled them, from the hub's own clock (serial); None: the read's stamp_ns
    stamp_ns: int | None = None


@dataclass
class LinkStatus:
    """Why a backend delivers (or not), for /diagnostics and the driver's log."""

    error: str = ""  # what is wrong right now, with the port and the OS reason; "" while it works
    values: dict[str, str] = field(default_factory=dict)  # extra /diagnostics values (port, last_error)


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

    # Optional (the hub asks with getattr; a backend without it has no link to fail):
    # def link_status(self) -> LinkStatus: ...
