"""Homing: find each motor's zero at its open end stop after the servos powered up.

An X-series servo keeps no turn count over power-off: at power-up its Present Position is within one
turn, so a spool that travels more than a turn (the fingers: 9 rad) can come up a whole turn off. The
driver therefore moves no servo whose zero it has not found since the servo powered up. Homing turns
each motor toward its open end (its minimum position) slowly, in current-based position mode with a
Goal Current well below the Current Limit, so that at the end stop the servo pulls the tendon with at
most that current; the end stop is where the motor stands still while pulling near that current. The
zero follows from there: the end stop is the motor's configured minimum position.

Which zero: the driver's own (`zero_ticks`, saved in the hand's directory), not the servo's Homing
Offset register. Homing Offset lives in EEPROM: writing it needs the torque off and wears the EEPROM
at every power-up, and it would shift Present Position for every other tool on the bus. The driver's
zero costs nothing to change and is written once, with the hand's other calibration.

Nothing here talks to the bus: `HomingRun.step` takes the motors' states and returns what to do.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

from .backend import MotorState

# A motor counts as standing still below this speed...
STILL_RPM = 0.5
# ...and as pulling against its stop at this share of the homing current or more (the unloaded spool
# turning slowly draws far less)...
STALL_CURRENT_SHARE = 0.7
# ...for this long: one or two driver ticks of a passing jam do not count.
STALL_HOLD_S = 0.1


class HomingOutcome(Enum):
    RUNNING = "running"
    HOMED = "homed"
    FAILED = "failed"


@dataclass(frozen=True)
class HomingSettings:
    rpm: float  # how fast the motors turn toward their end stops
    current_ma: float  # the most they pull there (Goal Current)
    timeout_s: float  # the longest a motor may take to reach its end stop
    max_travel_rad: dict[str, float]  # a motor that turns further than this has no end stop: fail

    def __post_init__(self) -> None:
        if not self.rpm > 0:
            raise ValueError(f"homing speed {self.rpm} rpm must be > 0")
        if not self.current_ma > 0:
            raise ValueError(f"homing current {self.current_ma} mA must be > 0")
        if not self.timeout_s > 0:
            raise ValueError(f"homing timeout {self.timeout_s} s must be > 0")


@dataclass
class MotorHoming:
    name: str
    start_rad: float | None = None  # position (from the zero the driver had) when homing started
    travel_rad: float = 0.0
    stall_since_ns: int | None = None
    stall_current_ma: float = 0.0
    outcome: HomingOutcome = HomingOutcome.RUNNING
    reason: str = ""


@dataclass
class HomingStep:
    """What the driver does after one tick: motors found at their end stops (set their zero there),
    and, once every motor is done, the run's end."""

    found: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    finished: bool = False


class HomingRun:
    """One homing of some motors, fed the motors' states each driver tick."""

    def __init__(self, motors: list[str], settings: HomingSettings, start_ns: int,
                 start_rad: Mapping[str, float] | None = None) -> None:
        """`start_rad`: where the motors stood when the homing was sent (each motor's travel counts
        from there); a motor without one counts from its first state here, which comes a tick or
        more after it started turning."""
        if not motors:
            raise ValueError("homing needs at least one motor")
        self.settings = settings
        self.start_ns = start_ns
        self.motors = {name: MotorHoming(name, (start_rad or {}).get(name)) for name in motors}

    @property
    def finished(self) -> bool:
        return all(m.outcome is not HomingOutcome.RUNNING for m in self.motors.values())

    @property
    def success(self) -> bool:
        return all(m.outcome is HomingOutcome.HOMED for m in self.motors.values())

    def reason(self) -> str:
        """The result's reason: `homed`, or `homing_failed: ` with every failed motor's reason."""
        failed = [m.reason for m in self.motors.values() if m.outcome is HomingOutcome.FAILED]
        return "homed" if not failed else "homing_failed: " + "; ".join(failed)

    def fail_all(self, reason: str) -> None:
        """The run ends early (canceled, the bus lost): every motor still homing fails with `reason`."""
        for m in self.motors.values():
            if m.outcome is HomingOutcome.RUNNING:
                m.outcome, m.reason = HomingOutcome.FAILED, f"{m.name}: {reason}"

    def fail(self, name: str, reason: str) -> None:
        """Fail one motor after the fact (homed, but its way back to 0 rad blocked)."""
        self.motors[name].outcome, self.motors[name].reason = HomingOutcome.FAILED, f"{name}: {reason}"

    def step(self, states: dict[str, MotorState], now_ns: int) -> HomingStep:
        step = HomingStep()
        s = self.settings
        for m in self.motors.values():
            if m.outcome is not HomingOutcome.RUNNING:
                continue
            state = states[m.name]
            if m.start_rad is None:
                m.start_rad = state.position_rad
            m.travel_rad = abs(state.position_rad - m.start_rad)
            if state.hardware_error:
                m.outcome, m.reason = HomingOutcome.FAILED, f"{m.name}: hardware error {state.hardware_error}"
                step.failed.append(m.name)
                continue
            stalled = (abs(state.velocity_rpm) < STILL_RPM
                       and abs(state.current_ma) >= STALL_CURRENT_SHARE * s.current_ma)
            if stalled:
                if m.stall_since_ns is None:
                    m.stall_since_ns = now_ns
                m.stall_current_ma = abs(state.current_ma)
                if now_ns - m.stall_since_ns >= STALL_HOLD_S * 1e9:
                    m.outcome = HomingOutcome.HOMED
                    step.found.append(m.name)
                    continue
            else:
                m.stall_since_ns = None
            limit = s.max_travel_rad.get(m.name)
            if limit is not None and m.travel_rad > limit:
                m.outcome, m.reason = HomingOutcome.FAILED, (
                    f"{m.name}: turned {m.travel_rad:.2f} rad without meeting its end stop (more than its "
                    f"{limit:.2f} rad range): is the tendon off its spool, or the motor's direction wrong?")
                step.failed.append(m.name)
            elif now_ns - self.start_ns > s.timeout_s * 1e9:
                m.outcome, m.reason = HomingOutcome.FAILED, (
                    f"{m.name}: no end stop within {s.timeout_s:g} s (turned {m.travel_rad:.2f} rad, pulling "
                    f"{abs(state.current_ma):.0f} mA of {s.current_ma:.0f} mA): raise homing_current_ma if the "
                    f"open hand needs more to turn, or homing_timeout")
                step.failed.append(m.name)
        step.finished = self.finished
        return step
