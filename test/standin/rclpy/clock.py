"""rclpy.clock: every stand-in clock reads the test clock (ros_standin.clock.TEST_CLOCK).

Real rclpy: ROS_TIME follows /clock when use_sim_time is true and the system clock otherwise.
In the stand-in all clock types read the one test clock, which only the test moves, so the
use_sim_time parameter exists but changes nothing.
"""
from __future__ import annotations

from ros_standin import clock as _test_clock

from .clock_type import ClockType
from .duration import Duration
from .time import Time

__all__ = ["Clock", "ClockType", "ROSClock", "JumpThreshold"]


class JumpThreshold:
    def __init__(self, *, min_forward=None, min_backward=None, on_clock_change=True) -> None:
        self.min_forward = min_forward
        self.min_backward = min_backward
        self.on_clock_change = on_clock_change


class Clock:
    def __init__(self, *, clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        if not isinstance(clock_type, ClockType):
            raise TypeError("Clock type must be a ClockType enum")
        self._clock_type = clock_type

    @property
    def clock_type(self) -> ClockType:
        return self._clock_type

    def now(self) -> Time:
        return Time(nanoseconds=_test_clock.now_ns(), clock_type=self._clock_type)

    def __repr__(self) -> str:
        return f"Clock(clock_type={self.clock_type.name})"

    def sleep_for(self, rel_time: Duration, context=None) -> bool:
        raise NotImplementedError(
            "Clock.sleep_for would block; in tests advance the test clock with the `ros` fixture")

    def sleep_until(self, until: Time, context=None) -> bool:
        raise NotImplementedError(
            "Clock.sleep_until would block; in tests advance the test clock with the `ros` fixture")


class ROSClock(Clock):
    def __init__(self) -> None:
        super().__init__(clock_type=ClockType.ROS_TIME)
        self._ros_time_is_active = False

    @property
    def ros_time_is_active(self) -> bool:
        return self._ros_time_is_active

    def _set_ros_time_is_active(self, enabled: bool) -> None:
        self._ros_time_is_active = bool(enabled)
