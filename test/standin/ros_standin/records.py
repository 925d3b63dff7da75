"""Log records written by stand-in loggers, for tests to read (fixture: `ros.logs()`)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LogRecord:
    stamp_ns: int
    severity: str  # DEBUG, INFO, WARN, ERROR, FATAL
    name: str  # logger name, e.g. the node name
    message: str


RECORDS: list[LogRecord] = []


def clear() -> None:
    RECORDS.clear()
