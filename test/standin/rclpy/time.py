"""rclpy.time.Time: a point on a clock, in integer nanoseconds."""
from __future__ import annotations

from .clock_type import ClockType
from .duration import Duration, S_TO_NS


class Time:
    def __init__(self, *, seconds: float = 0, nanoseconds: int = 0,
                 clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        if not isinstance(clock_type, ClockType):
            raise TypeError("Clock type must be a ClockType enum")
        if seconds < 0:
            raise ValueError("Seconds value must not be negative")
        if nanoseconds < 0:
            raise ValueError("Nanoseconds value must not be negative")
        total = int(seconds * S_TO_NS) + int(nanoseconds)
        if total >= 2**63:
            raise OverflowError("Total nanoseconds value is too large to store in C time point.")
        self._nanoseconds = total
        self._clock_type = clock_type

    @property
    def nanoseconds(self) -> int:
        return self._nanoseconds

    @property
    def clock_type(self) -> ClockType:
        return self._clock_type

    def seconds_nanoseconds(self) -> tuple[int, int]:
        return divmod(self.nanoseconds, S_TO_NS)

    def to_msg(self):
        from builtin_interfaces.msg import Time as TimeMsg

        seconds, nanoseconds = self.seconds_nanoseconds()
        return TimeMsg(sec=seconds, nanosec=nanoseconds)

    @classmethod
    def from_msg(cls, msg, clock_type: ClockType = ClockType.ROS_TIME) -> "Time":
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec, clock_type=clock_type)

    def __repr__(self) -> str:
        return f"Time(nanoseconds={self.nanoseconds}, clock_type={self.clock_type.name})"

    def __add__(self, other):
        if isinstance(other, Duration):
            return Time(nanoseconds=self.nanoseconds + other.nanoseconds, clock_type=self.clock_type)
        return NotImplemented

    def __radd__(self, other):
        return self.__add__(other)

    def __sub__(self, other):
        if isinstance(other, Time):
            if other.clock_type != self.clock_type:
                raise TypeError("Can't subtract times with different clock types")
            return Duration(nanoseconds=self.nanoseconds - other.nanoseconds)
        if isinstance(other, Duration):
            return Time(nanoseconds=self.nanoseconds - other.nanoseconds, clock_type=self.clock_type)
        return NotImplemented

    def _check(self, other):
        if not isinstance(other, Time):
            raise TypeError("Can't compare time with object of type: ", type(other))
        if other.clock_type != self.clock_type:
            raise TypeError("Can't compare times with different clock types")
        return other

    def __eq__(self, other):
        return self.nanoseconds == self._check(other).nanoseconds

    def __hash__(self):
        return hash((self.nanoseconds, self.clock_type))

    def __lt__(self, other): return self.nanoseconds < self._check(other).nanoseconds
    def __le__(self, other): return self.nanoseconds <= self._check(other).nanoseconds
    def __gt__(self, other): return self.nanoseconds > self._check(other).nanoseconds
    def __ge__(self, other): return self.nanoseconds >= self._check(other).nanoseconds
