"""rclpy.logging: loggers that print like rcutils and keep records for tests (ros_standin.records)."""
from __future__ import annotations

import sys
from enum import IntEnum

from ros_standin import clock as _test_clock
from ros_standin import records as _records


class LoggingSeverity(IntEnum):
    UNSET = 0
    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40
    FATAL = 50


_LEVELS: dict[str, LoggingSeverity] = {}
_DEFAULT_LEVEL = LoggingSeverity.INFO


def _reset() -> None:
    _LEVELS.clear()


class RcutilsLogger:
    def __init__(self, name: str = "") -> None:
        self.name = name
        self._once: set = set()
        self._last: dict = {}
        self._skipped: set = set()

    def get_child(self, name: str) -> "RcutilsLogger":
        if not name:
            raise ValueError("Child logger name must not be empty.")
        return RcutilsLogger(f"{self.name}.{name}" if self.name else name)

    def set_level(self, level) -> None:
        _LEVELS[self.name] = LoggingSeverity(level)

    def get_effective_level(self) -> LoggingSeverity:
        name = self.name
        while True:
            if name in _LEVELS and _LEVELS[name] != LoggingSeverity.UNSET:
                return _LEVELS[name]
            if "." not in name:
                return _DEFAULT_LEVEL
            name = name.rsplit(".", 1)[0]

    def is_enabled_for(self, severity) -> bool:
        return LoggingSeverity(severity) >= self.get_effective_level()

    def log(self, message, severity, *, once: bool = False, throttle_duration_sec=None,
            throttle_time_source_type=None, skip_first: bool = False, **kwargs) -> bool:
        severity = LoggingSeverity(severity)
        if not self.is_enabled_for(severity):
            return False
        caller = sys._getframe(2)
        site = (caller.f_code.co_filename, caller.f_lineno)
        if once:
            if site in self._once:
                return False
            self._once.add(site)
        if skip_first and site not in self._skipped:
            self._skipped.add(site)
            return False
        now = _test_clock.now_ns()
        if throttle_duration_sec is not None:
            last = self._last.get(site)
            if last is not None and now - last < throttle_duration_sec * 1e9:
                return False
            self._last[site] = now
        text = str(message)
        _records.RECORDS.append(_records.LogRecord(now, severity.name, self.name, text))
        seconds, nanoseconds = divmod(now, 1_000_000_000)
        print(f"[{severity.name}] [{seconds}.{nanoseconds:09d}] [{self.name}]: {text}", file=sys.stderr)
        return True

    def debug(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.DEBUG, **kwargs)

    def info(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.INFO, **kwargs)

    def warning(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.WARN, **kwargs)

    warn = warning

    def error(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.ERROR, **kwargs)

    def fatal(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.FATAL, **kwargs)


def get_logger(name: str) -> RcutilsLogger:
    if not name:
        raise ValueError("Logger name must not be empty.")
    return RcutilsLogger(name)


def set_logger_level(name: str, level) -> None:
    _LEVELS[name] = LoggingSeverity(level)


def get_logger_effective_level(name: str) -> LoggingSeverity:
    return RcutilsLogger(name).get_effective_level()
