"""What every fingertip-hub backend (serial, I2C, sim) hands the hub: readings of raw counts."""
from __future__ import annotations

import os
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


def describe_os_error(exc: BaseException) -> str:
    """`[Errno 2] No such file or directory` for anything carrying an errno (pyserial wraps the
    OS error of a failed open in a SerialException with the same errno; termios.error carries it
    as its first argument), else the text itself."""
    number = getattr(exc, "errno", None)
    if number is None and len(exc.args) == 2 and isinstance(exc.args[0], int):
        number = exc.args[0]
    if isinstance(number, int) and number > 0:
        return f"[Errno {number}] {os.strerror(number)}"
    return str(exc) or type(exc).__name__
