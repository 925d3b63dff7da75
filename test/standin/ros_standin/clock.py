"""The test clock: the one time source of every stand-in clock (ROS, system and steady).

Nothing advances it but the test: `TEST_CLOCK.advance(seconds)` / `set_ns(ns)`, or the `ros` fixture's
`advance()` which also fires due timers in time order. It starts at START_NS (a realistic epoch so
header stamps look like wall time) and is reset to it for every test by the fixture.
"""
from __future__ import annotations

START_NS = 1_700_000_000 * 1_000_000_000


class TestClock:
    __test__ = False  # not a pytest test class

    def __init__(self, start_ns: int = START_NS) -> None:
        self.now_ns = int(start_ns)

    def advance(self, seconds: float) -> int:
        """Move time forward by `seconds` (no callbacks run); returns the new time in ns."""
        if seconds < 0:
            raise ValueError(f"the test clock cannot go backwards ({seconds} s)")
        self.now_ns += int(round(seconds * 1e9))
        return self.now_ns

    def set_ns(self, now_ns: int) -> None:
        if now_ns < self.now_ns:
            raise ValueError(f"the test clock cannot go backwards ({now_ns} < {self.now_ns})")
        self.now_ns = int(now_ns)

    def reset(self, start_ns: int = START_NS) -> None:
        self.now_ns = int(start_ns)


TEST_CLOCK = TestClock()


def now_ns() -> int:
    return TEST_CLOCK.now_ns


def advance(seconds: float) -> int:
    return TEST_CLOCK.advance(seconds)
