"""rclpy.duration.Duration."""
from __future__ import annotations

S_TO_NS = 1_000_000_000


class Duration:
    def __init__(self, *, seconds: float = 0, nanoseconds: int = 0) -> None:
        total = int(seconds * S_TO_NS) + int(nanoseconds)
        if not (-(2**63) <= total < 2**63):
            raise OverflowError("Total nanoseconds value is too large to store in C duration.")
        self._nanoseconds = total

    @property
    def nanoseconds(self) -> int:
        return self._nanoseconds

    def to_msg(self):
        from builtin_interfaces.msg import Duration as DurationMsg

        seconds, nanoseconds = divmod(self.nanoseconds, S_TO_NS)
        return DurationMsg(sec=seconds, nanosec=nanoseconds)

    @classmethod
    def from_msg(cls, msg) -> "Duration":
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec)

    def __repr__(self) -> str:
        return f"Duration(nanoseconds={self.nanoseconds})"

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Duration):
            return self.nanoseconds == other.nanoseconds
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self.nanoseconds)

    def _check(self, other: object) -> "Duration":
        if not isinstance(other, Duration):
            raise TypeError("Can't compare duration with object of type: ", type(other))
        return other

    def __lt__(self, other): return self.nanoseconds < self._check(other).nanoseconds
    def __le__(self, other): return self.nanoseconds <= self._check(other).nanoseconds
    def __gt__(self, other): return self.nanoseconds > self._check(other).nanoseconds
    def __ge__(self, other): return self.nanoseconds >= self._check(other).nanoseconds
