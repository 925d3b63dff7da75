"""The motor driver's homing on the bus: start it, step it each tick, bring the homed motors back to
0 rad, end it (also when interrupted) and try a homing asked for at start again.

`homing.HomingRun` decides from the motors' states; this drives the bus accordingly and keeps the
zeros found. A homing at start that something interrupted (a fired watchdog, the bus lost or failing
under its start) goes again, HOMING_AT_START_TRIES times in all: the hand must come up homed without
an operator, and a fault that persists must not keep the motors turning toward their end stops.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from .backend import BusError, MotorBus, MotorState
from .homing import HomingRun, HomingSettings
from .node_config import MotorDriverConfig

HOMING_AT_START_TRIES = 3


@dataclass
class HomingFeedback:
    motors: list[str]
    positions: list[float]  # rad from where each started
    currents: list[float]  # mA
    homed: list[bool]


@dataclass
class HomingResult:
    success: bool
    reason: str
    motors: list[str] = field(default_factory=list)
    zero_ticks: list[int] = field(default_factory=list)
    travel_rad: list[float] = field(default_factory=list)
    stall_current_ma: list[float] = field(default_factory=list)

    def zeros(self) -> dict[str, int]:
        """The zeros found, by motor (what the node saves in the hand's directory)."""
        return dict(zip(self.motors, self.zero_ticks))


class HomingJob:
    """At most one homing at a time. `known_zeros` is the driver's dict of zeros it can vouch for:
    each zero found is added to it. Bus errors while stepping are raised for the driver to handle
    (it then calls `interrupt`); elsewhere they go to `note_error`."""

    def __init__(self, bus: MotorBus, config: MotorDriverConfig, known_zeros: dict[str, int],
                 note_error: Callable[[str], None]) -> None:
        self.bus = bus
        self.config = config
        self.known_zeros = known_zeros
        self._note_error = note_error
        self.run: HomingRun | None = None
        self.wanted = config.home_at_start  # home as soon as the bus is open
        self._at_start = False  # the running homing is the one asked for at start
        self._at_start_tries = HOMING_AT_START_TRIES
        self._zeros: dict[str, int] = {}
        # after the end stops: where each homed motor goes before the homing ends (0 rad: the hand open,
        # the thumb centred), and by when it must be there
        self._return: dict[str, float] = {}
        self._return_deadline_ns = 0

    def start(self, names: list[str], now_ns: int, positions: Mapping[str, float] | None = None) -> HomingResult | None:
        """Home `names` from `positions` (rad, the last read: each motor's travel counts from there);
        the result when the homing is over at once (the sim's motors need none, or the bus failed),
        else None."""
        motors = self.bus.motors
        if not self.bus.needs_homing:
            return HomingResult(True, "homed: the sim motors start at their zero, nothing to find", names,
                                [motors[m].zero_ticks for m in names], [0.0] * len(names), [0.0] * len(names))
        c = self.config
        # a lost turn and a little more beyond the range: further, and the open end has no stop
        max_travel = {m: motors[m].max_position_rad - motors[m].min_position_rad + 2 * math.pi + 0.5 for m in names}
        settings = HomingSettings(c.homing_rpm, c.homing_current_ma, c.homing_timeout, max_travel)
        try:
            self.bus.start_homing(names, c.homing_rpm, c.homing_current_ma)
        except (BusError, ValueError) as exc:
            try:
                self.bus.abort_homing(names)
            except BusError:
                pass
            return HomingResult(False, f"homing_failed: {exc}", names)
        self.run = HomingRun(names, settings, now_ns, positions)
        self._at_start = False
        self._zeros, self._return = {}, {}
        return None

    def start_wanted(self, now_ns: int, positions: Mapping[str, float] | None = None) -> HomingResult | None:
        """The homing asked for at start (or again after an interruption), of every motor."""
        self.wanted = False
        self._at_start_tries -= 1
        done = self.start(list(self.bus.motors), now_ns, positions)
        if done is not None and not done.success and self._at_start_tries > 0:
            self.wanted = True  # the bus failed under it: tried again, as after an interruption
        self._at_start = done is None
        return done

    def cancel(self) -> HomingResult | None:
        if self.run is None:
            return None
        self.run.fail_all("canceled")
        self._abort_unhomed()
        return self._end()

    def step(self, states: dict[str, MotorState], now_ns: int) -> tuple[HomingFeedback, HomingResult | None]:
        """One tick of the running homing: its feedback and, when it ended, its result. BusError
        propagates."""
        run = self.run
        assert run is not None
        feedback = HomingFeedback(list(run.motors), [run.motors[m].travel_rad for m in run.motors],
                                  [states[m].current_ma for m in run.motors], [m in self._zeros for m in run.motors])
        if self._return:
            return feedback, self._step_return(states, now_ns)
        step = run.step(states, now_ns)
        for name in step.found:
            self._zeros[name] = self.bus.finish_homing(name)
            self.known_zeros[name] = self._zeros[name]
        if step.failed:
            self.bus.abort_homing(step.failed)
        if step.finished and self._zeros:
            # a motor whose open end is not its 0 (the thumb's rotation: -3 rad) goes to 0 first
            self._return = {m: self.bus.motors[m].clamp(0.0) for m in self._zeros}
            distance = max(abs(self._return[m] - states[m].position_rad) for m in self._return)
            speed_rad_s = self.config.position_profile_rpm * 2 * math.pi / 60
            self._return_deadline_ns = now_ns + int((distance / speed_rad_s + 2.0) * 1e9)
            self.bus.set_positions(self._return, self.config.position_profile_rpm)
            return feedback, None
        return feedback, self._end() if step.finished else None

    def interrupt(self, reason: str, bus_open: bool) -> HomingResult | None:
        """The running homing (if any) ends with `reason` for every motor still homing, those motors back
        in velocity mode where the bus is open. A homing asked for at start goes again (at most
        HOMING_AT_START_TRIES in all): an interruption (a fired watchdog, the bus lost) says nothing
        about the end stops, unlike a motor that found none."""
        if self.run is None:
            return None
        self._retry_at_start()
        self.run.fail_all(reason)
        if bus_open:
            self._abort_unhomed()
        return self._end()

    def _abort_unhomed(self) -> None:
        assert self.run is not None
        try:
            self.bus.abort_homing([m for m in self.run.motors if m not in self._zeros])
        except BusError as exc:
            self._note_error(str(exc))

    def _step_return(self, states: dict[str, MotorState], now_ns: int) -> HomingResult | None:
        errors = {m: abs(states[m].position_rad - target) for m, target in self._return.items()}
        if max(errors.values()) <= self.config.position_tolerance:
            return self._end()
        if now_ns >= self._return_deadline_ns:
            assert self.run is not None
            for name, error in errors.items():
                if error > self.config.position_tolerance:
                    self.run.fail(name, f"homed, but stopped {error:.2f} rad short of 0 rad on the way back")
            return self._end()
        return None

    def _retry_at_start(self) -> None:
        if self._at_start and self._at_start_tries > 0:
            self.wanted = True

    def _end(self) -> HomingResult:
        run = self.run
        assert run is not None
        self.run = None
        self._return = {}
        if run.success:
            self._at_start = False  # done: a later fault asks for a homing of its own
        found = [m for m in run.motors if m in self._zeros]
        return HomingResult(run.success, run.reason(), found, [self._zeros[m] for m in found],
                            [run.motors[m].travel_rad for m in found], [run.motors[m].stall_current_ma for m in found])
