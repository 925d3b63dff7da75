"""What the motor_driver node does each tick, without ROS: read the bus, supervise the MoveMotors
goal, reconnect a lost bus with exponential backoff, and summarise health for /diagnostics."""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.diagnostics import ERROR, OK, WARN, DiagnosticStatusData
from prisma_common.goal_refusal import INVALID, NOT_READY, Refusal

from .backend import BusError, MotorBus, MotorState
from .control_table import decode_hardware_error
from .motor_goals import (
    GoalStartError,
    MoveFeedback,
    MoveGoal,
    MoveGoalRunner,
    MoveResult,
    goal_expired,
    validate_goal,
)
from .node_config import MotorDriverConfig


def make_bus(config: MotorDriverConfig, start_ns: int | None = 0) -> MotorBus:
    motors = config.motors()
    if config.backend == "dynamixel":
        from .dynamixel_backend import DynamixelBus  # dynamixel-sdk only where it is used

        return DynamixelBus(config.port, config.baud, motors, retries=config.retries)
    from .sim_backend import SimMotorBus

    initial = dict(zip(config.motor_names, (float(p) for p in config.sim_initial_positions)))
    return SimMotorBus(motors, initial_positions=initial, start_ns=start_ns)


@dataclass
class StartOutcome:
    preempted: MoveResult | None = None  # the goal that was running: it has ended
    failed: MoveResult | None = None  # set when the bus failed: the new goal ends with this at once


@dataclass
class TickResult:
    states: dict[str, MotorState] | None  # None while the bus is down
    feedback: MoveFeedback | None = None
    result: MoveResult | None = None  # the running goal ended this tick


class MotorDriverCore:
    def __init__(self, config: MotorDriverConfig, bus: MotorBus | None = None, start_ns: int = 0) -> None:
        self.config = config
        self.bus = bus or make_bus(config, start_ns)
        self.runner = MoveGoalRunner(self.bus, config.position_profile_rpm, config.position_tolerance)
        self.connected = False
        self.last_error = ""
        self._reported_error = ""  # the bus error last handed out by take_errors()
        self._new_errors: list[str] = []
        self.reconnects = 0
        self._backoff_s = config.reconnect_backoff_initial
        self._next_attempt_ns = start_ns
        self._last_states: dict[str, MotorState] = {}

    def reconfigure(self, config: MotorDriverConfig) -> None:
        """Live parameters changed (validated by MotorDriverConfig): the position-goal speed from the
        next goal, the position tolerance from the next tick."""
        self.runner.profile_rpm = config.position_profile_rpm
        self.runner.position_tolerance_rad = config.position_tolerance
        self.config = config

    def connect(self, now_ns: int) -> str | None:
        """Try to open the bus when the backoff allows; returns the error text or None."""
        if self.connected or now_ns < self._next_attempt_ns:
            return None if self.connected else self.last_error or "waiting to reconnect"
        try:
            self.bus.open()
        except BusError as exc:
            self.last_error = str(exc)
            self._note_error(self.last_error)
            self._next_attempt_ns = now_ns + int(self._backoff_s * 1e9)
            self._backoff_s = min(self._backoff_s * 2.0, self.config.reconnect_backoff_max)
            return self.last_error
        self.connected = True
        self._reported_error = ""  # the same error later is news again
        self._backoff_s = self.config.reconnect_backoff_initial
        return None

    def take_errors(self) -> list[str]:
        """Bus errors (open failures with the port and OS reason, a lost bus) that appeared since
        the last call, each once: the node logs them."""
        errors, self._new_errors = self._new_errors, []
        return errors

    def _note_error(self, error: str) -> None:
        if error != self._reported_error:
            self._new_errors.append(error)
            self._reported_error = error

    def validate(self, goal: MoveGoal, now_ns: int | None = None) -> Refusal | None:
        """Why the goal is refused (the node aborts it at once with this reason), else None:
        not_ready while the bus is not connected, invalid for a malformed goal or (given the time it
        arrives) one whose timeout ended on the way. A goal naming a faulted motor is valid: it
        fails at start with the fault reason."""
        if not self.connected:
            return Refusal(NOT_READY, f"motor bus not connected: {self.last_error or 'not opened yet'}")
        reason = validate_goal(goal, self.bus.motors) or (goal_expired(goal, now_ns) if now_ns is not None else None)
        return Refusal(INVALID, reason) if reason else None

    def start(self, goal: MoveGoal, now_ns: int) -> StartOutcome:
        """Start a goal (ValueError on an invalid one: nothing changes). Whatever the bus does, a
        goal it replaces is over (`preempted`) and a goal the bus failed to start is `failed`; a
        goal naming a faulted motor is `failed` with the fault reason and the running goal goes on."""
        fault = self.runner.fault_of(goal)
        if fault:
            return StartOutcome(failed=MoveResult(False, [], fault))
        try:
            preempted = self.runner.start(goal, now_ns)
        except GoalStartError as exc:
            return StartOutcome(exc.preempted, MoveResult(False, [], f"motor_fault: communication: {exc}"))
        return StartOutcome(preempted)

    def cancel(self) -> MoveResult | None:
        return self.runner.cancel()

    def tick(self, now_ns: int) -> TickResult:
        if not self.connected:
            if self.connect(now_ns) is not None:
                return TickResult(None)
        try:
            states = self.bus.read_state(now_ns)
        except BusError as exc:
            return self._lost(exc, now_ns)
        self._last_states = states
        feedback, result = self.runner.tick(states, now_ns)
        return TickResult(states, feedback, result)

    def _lost(self, exc: BusError, now_ns: int) -> TickResult:
        self.last_error = str(exc)
        self._note_error(self.last_error)
        result = self.runner.communication_failure(exc)
        self.connected = False
        self.reconnects += 1
        try:
            self.bus.close()
        except BusError:
            pass  # the bus is already unreachable; torque off failed with it
        self._next_attempt_ns = now_ns + int(self._backoff_s * 1e9)
        return TickResult(None, None, result)

    def close(self) -> None:
        if self.connected:
            self.connected = False
            self.bus.close()

    def diagnostics(self) -> list[DiagnosticStatusData]:
        stats = self.bus.stats
        hw = self.config.port if self.config.backend == "dynamixel" else "sim"
        if not self.connected:
            level, message = ERROR, f"disconnected: {self.last_error}"
        elif self.runner.faults:
            level, message = ERROR, "; ".join(self.runner.fault_log[-3:])
        elif stats.retries or stats.comm_failures:
            level, message = WARN, f"{stats.retries} retries, {stats.comm_failures} failed transactions"
        else:
            level, message = OK, "ok"
        values = {"backend": self.config.backend, "reads": stats.reads, "writes": stats.writes,
                  "retries": stats.retries, "dropped_status": stats.dropped_status,
                  "corrupt_status": stats.corrupt_status, "comm_failures": stats.comm_failures,
                  "hardware_errors": stats.hardware_errors, "mode_changes": stats.mode_changes,
                  "reconnects": self.reconnects, "goal_active": self.runner.active,
                  "last_error": self.last_error}
        if self.config.backend == "dynamixel":
            values["port"] = self.config.port
        out = [DiagnosticStatusData("motor_driver: bus", level, message, hw, {k: str(v) for k, v in values.items()})]
        for name, c in self.bus.motors.items():
            s = self._last_states.get(name)
            error = self.runner.faults.get(name, 0)
            m_level = ERROR if error else OK
            m_message = ("hardware error " + ", ".join(decode_hardware_error(error))) if error else "ok"
            vals: dict[str, object] = {"id": c.servo_id}
            if s is not None:
                vals.update(position_rad=f"{s.position_rad:.4f}", velocity_rpm=f"{s.velocity_rpm:.2f}",
                            current_ma=f"{s.current_ma:.1f}", torque_on=s.torque_on)
            out.append(DiagnosticStatusData(f"motor_driver: {name}", m_level, m_message, f"{hw}#{c.servo_id}",
                                            {k: str(v) for k, v in vals.items()}))
        return out
