"""MoveMotors goal execution over a MotorBus: validation, limits, timeout, cancel, faults.

The motor_driver node feeds this from its 100 Hz timer (`tick`) and its action callbacks; everything
here takes explicit stamps, so it runs the same on the Dynamixel bus, the sim bus and in tests.

Goal semantics (MoveMotors.action):
- mode "velocity": targets are rpm. Each motor runs until it reaches its stop position in its
  direction of travel (the configured limit, narrowed by `position_limits`), then stops; when every
  moving motor has stopped the goal ends with reason "joint_limit". `timeout` > 0 ends it with
  "timeout" (both count as success: the requested motion ran to its end).
- mode "position": targets are rad, reached at `profile_rpm`; success with reason "reached" when all
  are within `position_tolerance_rad`; `timeout` > 0 ends it unsuccessfully with "timeout".
- `position_limits`: empty, one stop position per motor (velocity mode: where that motor stops), or
  a [min, max] pair per motor (flattened).
- a velocity-mode motor already at its stop position in its direction of travel when the goal starts
  is not driven (a re-sent command does not push a stopped motor into its limit again);
- `stamp_ns` (when the client sent the goal, by its clock; 0 = not given): the timeout counts from
  there, but never from later than the goal's arrival (a client clock ahead of the driver's cannot
  lengthen it); a goal whose timeout has passed when it arrives is rejected. A velocity goal is a
  lease its client renews by sending the next one: one that a dropped link held back and delivered
  once the link came back would otherwise start the motors after its client had stopped them;
- cancel stops the motors ("canceled"); a new goal preempts the running one ("preempted"); a hardware
  error on ANY motor turns that motor's torque off and aborts the running goal with a reason naming
  the motor, its ID and the error bit; a bus failure aborts it with "motor_fault: communication ...".
- `controller` (who sends the goal: the client node's fully qualified name; "" = an anonymous client
  such as `ros2 action send_goal`, which counts as one more controller named ""): one controller at a
  time holds the motors. Its lease runs while its goal runs and, for a velocity goal with a timeout
  that ended early at its joint limit, until that timeout (its controller is still renewing it); a
  cancel, a failure or the timeout itself ends it at once. A goal of another controller meanwhile
  is refused `busy` (`busy_reason`), and the running goal goes on: two controllers that each preempt
  the other's goals every 0.1 s would otherwise drive the motors by turns. Anonymous clients cannot
  be told apart: one may preempt another's goal, as before controllers were named.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .backend import BusError, MotorBus, MotorConfig, MotorState, fault_reason

VELOCITY = "velocity"
POSITION = "position"


class GoalStartError(BusError):
    """The bus failed while a goal was starting: the new goal never ran (the motors it could reach
    were told to stop) and `preempted` is the result of the goal it replaced, which is over too."""

    def __init__(self, error: BusError, preempted: MoveResult | None) -> None:
        super().__init__(str(error))
        self.preempted = preempted


@dataclass
class MoveGoal:
    motors: list[str]
    mode: str
    targets: list[float]
    position_limits: list[float] = field(default_factory=list)
    timeout_s: float = 0.0
    stamp_ns: int = 0  # when the client sent it (0: not given)
    controller: str = ""  # who sent it: the client node's fully qualified name ("": anonymous)


@dataclass
class MoveFeedback:
    positions: list[float]
    velocities: list[float]
    currents: list[float]


@dataclass
class MoveResult:
    success: bool
    final_positions: list[float]
    reason: str


# ends a client brings about in its normal work: a refresh (the next goal preempts this one, every
# 0.1 s) and a stop (a cancel, at the end of every manipulation goal): the log keeps quiet about them
ROUTINE_ENDS = ("preempted", "canceled")


def end_severity(result: MoveResult) -> str | None:
    """How the motor driver logs a goal's end: "info" for a success, "warn" for a failure, None for a
    routine end (ROUTINE_ENDS)."""
    if result.reason in ROUTINE_ENDS:
        return None
    return "info" if result.success else "warn"


def validate_goal(goal: MoveGoal, motors: dict[str, MotorConfig], faults: dict[str, int] | None = None) -> str | None:
    """None when the goal is acceptable, else the rejection reason naming the bad value."""
    if not goal.motors:
        return "no motors named"
    unknown = [m for m in goal.motors if m not in motors]
    if unknown:
        return f"unknown motor(s) {unknown}; configured: {sorted(motors)}"
    if len(set(goal.motors)) != len(goal.motors):
        return f"motor named twice in {goal.motors}"
    if goal.mode not in (VELOCITY, POSITION):
        return f"mode {goal.mode!r} is not 'velocity' or 'position'"
    if len(goal.targets) != len(goal.motors):
        return f"{len(goal.targets)} targets for {len(goal.motors)} motors"
    if len(goal.position_limits) not in (0, len(goal.motors), 2 * len(goal.motors)):
        return (f"position_limits has {len(goal.position_limits)} entries; expected 0, "
                f"{len(goal.motors)} or {2 * len(goal.motors)}")
    if not math.isfinite(goal.timeout_s) or goal.timeout_s < 0:
        return f"timeout {goal.timeout_s} must be >= 0"
    for name, target in zip(goal.motors, goal.targets):
        c = motors[name]
        if not math.isfinite(target):
            return f"target {target} for {name} is not finite"
        if goal.mode == VELOCITY and abs(target) > c.max_velocity_rpm:
            return f"velocity {target} rpm for {name} above the limit {c.max_velocity_rpm} rpm"
        if goal.mode == POSITION and not c.min_position_rad <= target <= c.max_position_rad:
            return f"position {target} rad for {name} outside [{c.min_position_rad}, {c.max_position_rad}]"
    for value in goal.position_limits:
        if not math.isfinite(value):
            return f"position limit {value} is not finite"
    return goal_fault(goal, motors, faults or {})


def goal_expired(goal: MoveGoal, now_ns: int) -> str | None:
    """Why a stamped goal with a timeout arrives too late to run, else None."""
    if goal.stamp_ns <= 0 or goal.timeout_s <= 0:
        return None
    age_ns = now_ns - goal.stamp_ns
    if age_ns < goal.timeout_s * 1e9:
        return None
    return (f"its timeout {goal.timeout_s:g} s ended before it arrived (sent {age_ns / 1e6:.0f} ms ago by its "
            f"stamp): held up on the way (a link that dropped?), or the client's clock is behind this one")


def goal_fault(goal: MoveGoal, motors: dict[str, MotorConfig], faults: dict[str, int]) -> str | None:
    """The fault reason naming each of the goal's motors with an active hardware error, else None."""
    return "; ".join(fault_reason(m, motors[m].servo_id, faults[m]) for m in goal.motors if faults.get(m)) or None


def controller_label(controller: str) -> str:
    """A controller as the logs and refusals name it."""
    return controller or "an anonymous client (empty controller)"


def stop_window(goal: MoveGoal, index: int, config: MotorConfig) -> tuple[float, float]:
    """[lo, hi] a velocity-mode motor may travel in: configured limits narrowed by the goal."""
    lo, hi = config.min_position_rad, config.max_position_rad
    n = len(goal.motors)
    if len(goal.position_limits) == 2 * n:
        lo, hi = max(lo, goal.position_limits[2 * index]), min(hi, goal.position_limits[2 * index + 1])
    elif len(goal.position_limits) == n:
        stop = goal.position_limits[index]
        if goal.targets[index] > 0:
            hi = min(hi, stop)
        elif goal.targets[index] < 0:
            lo = max(lo, stop)
    return lo, hi


class MoveGoalRunner:
    def __init__(self, bus: MotorBus, profile_rpm: float = 30.0, position_tolerance_rad: float = 0.02) -> None:
        self.bus = bus
        self.profile_rpm = profile_rpm
        self.position_tolerance_rad = position_tolerance_rad
        self.goal: MoveGoal | None = None
        self.start_ns = 0
        self.deadline_ns = 0  # when the running goal's timeout ends it (timeout > 0)
        self.faults: dict[str, int] = {}  # motor -> Hardware Error Status seen
        self.fault_log: list[str] = []
        self._stopped: set[str] = set()
        self._last_states: dict[str, MotorState] = {}
        # the controller of the goal that ended last and until when its lease holds the motors (0: not)
        self._ended_controller = ""
        self._ended_lease_ns = 0

    @property
    def active(self) -> bool:
        return self.goal is not None

    def validate(self, goal: MoveGoal) -> str | None:
        return validate_goal(goal, self.bus.motors, self.faults)

    def lease_holder(self, now_ns: int | None = None) -> str | None:
        """The controller that holds the motors at `now_ns` ("" = anonymous), else None: the running
        goal's, or, after a velocity goal ended early at its joint limit, its controller's until the
        goal's timeout (without `now_ns`: the running goal's only)."""
        if self.goal is not None:
            # past its timeout it is over, whether or not the tick that ends it has come yet
            expired = now_ns is not None and self.goal.timeout_s > 0 and now_ns >= self.deadline_ns
            return None if expired else self.goal.controller
        if now_ns is not None and now_ns < self._ended_lease_ns:
            return self._ended_controller
        return None

    def busy_reason(self, goal: MoveGoal, now_ns: int | None = None) -> str | None:
        """Why `goal` must wait (another controller holds the motors), else None."""
        holder = self.lease_holder(now_ns)
        if holder is None or holder == goal.controller:
            return None
        lease_end_ns = self.deadline_ns if self.goal is not None else self._ended_lease_ns
        if self.goal is not None and self.goal.timeout_s <= 0:
            until = "until it ends (no timeout)"
        elif now_ns is None:
            until = "until its timeout"
        else:
            until = f"for {max(0.0, (lease_end_ns - now_ns) / 1e6):.0f} ms more unless renewed"
        return (f"MoveMotors held by {controller_label(holder)}: its goal holds the motors {until}; "
                f"wait for its end, cancel it, or stop that controller (this goal's controller: "
                f"{controller_label(goal.controller)})")

    def fault_of(self, goal: MoveGoal) -> str | None:
        """The fault reason of the goal's motors that have an active hardware error, else None."""
        return goal_fault(goal, self.bus.motors, self.faults)

    def start(self, goal: MoveGoal, stamp_ns: int) -> MoveResult | None:
        """Start a validated goal; returns the preempted goal's result, if one was running.

        ValueError for an invalid goal (the running one goes on). GoalStartError when the bus fails
        on the way: the running goal is ended all the same (its result rides on the error) and the
        new one is not started, so no goal is left half-replaced."""
        reason = self.validate(goal)
        if reason:
            raise ValueError(reason)
        previous = self.goal
        preempted = self._finish(False, "preempted", stop=False) if previous else None
        stopped: set[str] = set()
        try:
            if goal.mode == VELOCITY:
                velocities = {}
                for i, name in enumerate(goal.motors):
                    target = goal.targets[i]
                    state = self._last_states.get(name)
                    if target and state is not None and self._at_stop(goal, i, state.position_rad):
                        target = 0.0
                        stopped.add(name)
                    velocities[name] = target
                self.bus.set_velocities(velocities)
            else:
                self.bus.set_positions(dict(zip(goal.motors, goal.targets)), self.profile_rpm)
        except BusError as exc:
            self.fault_log.append(f"starting a goal: {exc}")
            moved = set(goal.motors) | set(previous.motors if previous else [])
            healthy = [m for m in self.bus.motors if m in moved and m not in self.faults]
            try:
                if healthy:
                    self.bus.stop(healthy)
            except BusError as stop_exc:
                self.fault_log.append(f"stop failed: {stop_exc}")
            raise GoalStartError(exc, preempted) from exc
        self.goal, self.start_ns, self._stopped = goal, stamp_ns, stopped
        self._ended_lease_ns = 0
        start = min(stamp_ns, goal.stamp_ns) if goal.stamp_ns > 0 else stamp_ns
        self.deadline_ns = start + round(goal.timeout_s * 1e9)
        return preempted

    def _at_stop(self, goal: MoveGoal, index: int, position: float) -> bool:
        """True when a velocity-mode motor has reached its stop in its direction of travel."""
        lo, hi = stop_window(goal, index, self.bus.motors[goal.motors[index]])
        target = goal.targets[index]
        return (target > 0 and position >= hi) or (target < 0 and position <= lo)

    def cancel(self) -> MoveResult | None:
        if self.goal is None:
            return None
        return self._finish(False, "canceled")

    def abort(self, reason: str) -> MoveResult | None:
        """End the running goal unsuccessfully with `reason`, its motors stopped (None: no goal)."""
        self.fault_log.append(reason)
        if self.goal is None:
            return None
        return self._finish(False, reason)

    def communication_failure(self, error: BusError) -> MoveResult | None:
        self.fault_log.append(str(error))
        if self.goal is None:
            return None
        return self._finish(False, f"motor_fault: communication: {error}", stop=False)

    def stop_if_expired(self, now_ns: int) -> None:
        """Stop the running goal's motors when its timeout has passed at `now_ns`. The driver calls it
        before it reads the motors: a tick that comes late (the driver held up: SIGSTOP, a starved
        process) stops them first, so nothing moves after the goal's lease ended, not even until that
        tick's end (the sim's motors would be integrated on at the goal's velocity up to now). The goal
        itself ends in `tick` (timeout), or for a fault the states show."""
        goal = self.goal
        if goal is None or goal.timeout_s <= 0 or now_ns < self.deadline_ns:
            return
        self._stop_healthy(goal)

    def tick(self, states: dict[str, MotorState], stamp_ns: int) -> tuple[MoveFeedback | None, MoveResult | None]:
        """Check faults, limits, completion and timeout against fresh states."""
        self._last_states = states
        fault = self._check_faults(states)
        if self.goal is None:
            return None, None
        goal = self.goal
        feedback = MoveFeedback(
            [states[m].position_rad for m in goal.motors],
            [states[m].velocity_rpm for m in goal.motors],
            [states[m].current_ma for m in goal.motors],
        )
        if fault:
            return feedback, self._finish(False, fault, stop=True)
        if goal.mode == VELOCITY:
            for i, name in enumerate(goal.motors):
                if name in self._stopped or goal.targets[i] == 0:
                    continue
                if self._at_stop(goal, i, states[name].position_rad):
                    self.bus.stop([name])
                    self._stopped.add(name)
            moving = [m for i, m in enumerate(goal.motors) if goal.targets[i] != 0]
            if moving and all(m in self._stopped for m in moving):
                return feedback, self._finish(True, "joint_limit", stop=False)
        else:
            errors = [abs(states[m].position_rad - t) for m, t in zip(goal.motors, goal.targets)]
            if max(errors) <= self.position_tolerance_rad:
                return feedback, self._finish(True, "reached", stop=False)
        if goal.timeout_s > 0 and stamp_ns >= self.deadline_ns:
            return feedback, self._finish(goal.mode == VELOCITY, "timeout")
        return feedback, None

    def _check_faults(self, states: dict[str, MotorState]) -> str | None:
        reasons = []
        for name, state in states.items():
            if state.hardware_error and self.faults.get(name) != state.hardware_error:
                self.faults[name] = state.hardware_error
                reason = fault_reason(name, self.bus.motors[name].servo_id, state.hardware_error)
                self.fault_log.append(reason)
                try:
                    self.bus.torque_off(name)
                except BusError as exc:  # keep going: the abort below matters more
                    self.fault_log.append(f"torque off {name} failed: {exc}")
                reasons.append(reason)
            elif not state.hardware_error and name in self.faults:
                # cleared (power cycle or reboot): take the motor back as the bus opened it
                try:
                    self.bus.torque_on(name)
                except BusError as exc:
                    self.fault_log.append(f"torque on {name} after its error cleared failed: {exc}")
                    continue  # still faulted: tried again on the next state
                del self.faults[name]
        return "; ".join(reasons) or None

    def _stop_healthy(self, goal: MoveGoal) -> None:
        """Stop the goal's motors that have no fault latched (a faulted one has its torque off); a
        failing stop is logged, not raised: the goal's end matters more."""
        try:
            healthy = [m for m in goal.motors if m not in self.faults]
            if healthy:
                self.bus.stop(healthy)
        except BusError as exc:
            self.fault_log.append(f"stop failed: {exc}")

    def _finish(self, success: bool, reason: str, stop: bool = True) -> MoveResult:
        goal = self.goal
        assert goal is not None
        if stop:
            self._stop_healthy(goal)
        final = [self._last_states[m].position_rad if m in self._last_states else float("nan") for m in goal.motors]
        self.goal = None
        # a velocity goal that reached its joint limit before its timeout is still its controller's
        # lease (it renews it); every other end gives the motors free at once
        early = success and reason != "timeout" and goal.timeout_s > 0
        self._ended_controller, self._ended_lease_ns = goal.controller, (self.deadline_ns if early else 0)
        return MoveResult(success, final, reason)
