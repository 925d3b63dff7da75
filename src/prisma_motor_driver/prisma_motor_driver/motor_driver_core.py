"""What the motor_driver node does each tick, without ROS: read the bus, supervise the MoveMotors
goal and the homing (`homing_job`), reconnect a lost bus with exponential backoff, and summarise
health for /diagnostics.

The servos' own safety is watched here too: a Bus Watchdog that fired (the driver or the bus held up
longer than its period: the servo stopped itself) ends the running goal, and is cleared and armed
again with the motors still; a servo that powered up again while the bus was open (its watchdog reads
0: its RAM and its turn count are lost) ends the goal and is no longer homed. A motor not homed since
its servo powered up takes no MoveMotors goal (`not_homed`) until the homing found its zero."""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.diagnostics import ERROR, OK, WARN, DiagnosticStatusData
from prisma_common.goal_refusal import BUSY, INVALID, NOT_HOMED, NOT_READY, Refusal

from .backend import BusError, MotorBus, MotorState
from .control_table import decode_hardware_error
from .homing_job import HomingFeedback, HomingJob, HomingResult
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


def make_bus(config: MotorDriverConfig, start_ns: int | None = 0, zeros: dict[str, int] | None = None) -> MotorBus:
    """The configured bus; `zeros` (motor -> ticks, from the hand's directory) override zero_ticks."""
    motors = config.motors(zeros)
    if config.backend == "dynamixel":
        from .dynamixel_backend import DynamixelBus  # dynamixel-sdk only where it is used

        return DynamixelBus(config.port, config.baud, motors, retries=config.retries,
                            watchdog_s=config.bus_watchdog)
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
    homing_feedback: HomingFeedback | None = None
    homing_result: HomingResult | None = None  # the homing ended this tick


class MotorDriverCore:
    def __init__(self, config: MotorDriverConfig, bus: MotorBus | None = None, start_ns: int = 0,
                 zeros: dict[str, int] | None = None) -> None:
        self.config = config
        self.bus = bus or make_bus(config, start_ns, zeros)
        # zeros this driver can vouch for: read from the hand's directory, or found by its homing; a
        # servo's LED alone (lit by some homing) does not say which zero that homing found
        self.known_zeros = dict(zeros or {})
        self.homing = HomingJob(self.bus, config, self.known_zeros, self._note_error)
        self.watchdog_firings = 0
        self.servo_resets = 0
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
        self.config = self.homing.config = config

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
        self._trust_only_known_zeros()
        return None

    def _trust_only_known_zeros(self) -> None:
        for name in self.bus.homed:
            if self.bus.needs_homing and name not in self.known_zeros:
                self.bus.homed[name] = False

    def unhomed(self, motors: list[str] | None = None) -> list[str]:
        """The motors (of `motors`, default all) whose zero is not known since their servo powered up."""
        names = list(self.bus.motors) if motors is None else motors
        return [m for m in names if m in self.bus.motors and not self.bus.homed.get(m, False)]

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
        arrives) one whose timeout ended on the way, busy while another controller holds the motors
        (motor_goals.py), not_ready while the homing runs or is about to (`homing_refusal`), not_homed
        for a motor whose zero is not known. A goal naming a faulted motor is valid: it fails at start
        with the fault reason."""
        if not self.connected:
            return Refusal(NOT_READY, f"motor bus not connected: {self.last_error or 'not opened yet'}")
        reason = validate_goal(goal, self.bus.motors) or (goal_expired(goal, now_ns) if now_ns is not None else None)
        if reason:
            return Refusal(INVALID, reason)
        busy = self.runner.busy_reason(goal, now_ns)
        if busy:
            return Refusal(BUSY, busy)
        homing = self.homing_refusal()
        if homing is not None:
            return homing
        unhomed = self.unhomed(goal.motors)
        if unhomed:
            return Refusal(NOT_HOMED, f"{self._named(unhomed)} not homed since the servo powered up (the zero may be "
                                      f"a turn off): home first (the HomeMotors action prisma/motors/home, or "
                                      f"home:=true at launch)")
        return None

    def homing_refusal(self) -> Refusal | None:
        """not_ready while a homing runs or one asked for (at start, or again after an interruption) is
        about to start: it takes every motor, and the goal can run once it has ended (send it again).
        Without this, a goal sent at start-up before the homing began would be refused `not_homed`,
        which asks the client to home: the driver is doing that already."""
        if self.homing.run is not None:
            motors = list(self.homing.run.motors)
        elif self.homing.wanted:
            motors = list(self.bus.motors)
        else:
            return None
        return Refusal(NOT_READY, f"homing ({', '.join(motors)}): send it again when the homing has ended")

    def _named(self, motors: list[str]) -> str:
        return ", ".join(f"{m} (id {self.bus.motors[m].servo_id})" for m in motors)

    # ---- homing ----------------------------------------------------------------------------
    def validate_homing(self, motors: list[str]) -> Refusal | None:
        if not self.connected:
            return Refusal(NOT_READY, f"motor bus not connected: {self.last_error or 'not opened yet'}")
        unknown = [m for m in motors if m not in self.bus.motors]
        if unknown:
            return Refusal(INVALID, f"unknown motor(s) {unknown}; configured: {sorted(self.bus.motors)}")
        if self.homing.run is not None:
            return Refusal(BUSY, f"already homing {', '.join(self.homing.run.motors)}")
        faulted = [m for m in (motors or list(self.bus.motors)) if self.runner.faults.get(m)]
        if faulted:
            return Refusal(NOT_READY, f"{self._named(faulted)} in hardware error: clear it (power cycle) first")
        return None

    def start_homing(self, motors: list[str], now_ns: int) -> tuple[MoveResult | None, HomingResult | None]:
        """Home `motors` (empty = all; validated by validate_homing). Returns the running MoveMotors
        goal's result (it ends: homing takes the motors) and, when the homing is over at once (the sim's
        motors need none, or the bus failed), its result."""
        preempted = self.runner.abort("preempted: homing") if self.runner.active else None
        return preempted, self.homing.start(list(motors) or list(self.bus.motors), now_ns,
                                            _positions(self._last_states))

    def cancel_homing(self) -> HomingResult | None:
        return self.homing.cancel()

    def _step_homing(self, states: dict[str, MotorState], now_ns: int) -> TickResult:
        try:
            feedback, result = self.homing.step(states, now_ns)
        except BusError as exc:
            return self._lost(exc, now_ns)
        return TickResult(states, homing_feedback=feedback, homing_result=result)

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
        # a goal whose timeout passed since the last tick (this tick late: the driver held up) has its
        # motors stopped before they are read; it ends below (timeout, or a fault the states show)
        self.runner.stop_if_expired(now_ns)
        try:
            states = self.bus.read_state(now_ns)
            stopped = self._servo_safety(states)
        except BusError as exc:
            return self._lost(exc, now_ns)
        self._last_states = states
        if stopped:
            result = self.runner.abort(stopped)
            # the servos were made safe again above: the ones still homing go back to velocity mode
            homing = self.homing.interrupt(stopped, bus_open=True)
            return TickResult(states, None, result, homing_result=homing)
        if self.homing.run is not None:
            return self._step_homing(states, now_ns)
        if self.homing.wanted and not self.runner.active:
            return TickResult(states, homing_result=self.homing.start_wanted(now_ns, _positions(states)))
        feedback, result = self.runner.tick(states, now_ns)
        return TickResult(states, feedback, result)

    def _servo_safety(self, states: dict[str, MotorState]) -> str | None:
        """Servos that stopped themselves (Bus Watchdog) or powered up again: made safe again (cleared,
        re-armed; a reset one prepared as at open and no longer homed). Returns the reason that ends the
        running goal, else None."""
        reasons = []
        fired = [n for n, s in states.items() if s.watchdog_fired]
        if fired:
            self.watchdog_firings += len(fired)
            self.bus.rearm_watchdog(fired)
            whose = "its bus watchdog" if len(fired) == 1 else "their bus watchdogs"
            reasons.append(f"motor_fault: {self._named(fired)} stopped by {whose}: no instruction for more than "
                           f"{self.config.bus_watchdog * 1e3:.0f} ms (the driver or the bus was held up); re-armed, "
                           f"still until the next goal")
        reset = [n for n, s in states.items() if s.servo_reset and not s.watchdog_fired]
        if reset:
            self.servo_resets += len(reset)
            for name in reset:
                self.known_zeros.pop(name, None)
                self.bus.torque_on(name)  # as at open: limits, watchdog; its LED, off, says not homed
                self.bus.homed[name] = False
            reasons.append(f"motor_fault: {self._named(reset)} powered up again (its RAM lost: torque off, bus "
                           f"watchdog 0) and lost its turn count: home it again")
        return "; ".join(reasons) or None

    def _lost(self, exc: BusError, now_ns: int) -> TickResult:
        self.last_error = str(exc)
        self._note_error(self.last_error)
        result = self.runner.communication_failure(exc)
        # the servos may power up again with the bus: a homing asked for at start is tried again once
        # it reopens
        homing = self.homing.interrupt(f"motor bus lost: {exc}", bus_open=False)
        self.connected = False
        self.reconnects += 1
        try:
            self.bus.close()
        except BusError:
            pass  # the bus is already unreachable; torque off failed with it
        self._next_attempt_ns = now_ns + int(self._backoff_s * 1e9)
        return TickResult(None, None, result, homing_result=homing)

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
        values = {"backend": self.config.backend, "baud": self.config.baud, "reads": stats.reads,
                  "writes": stats.writes, "watchdog_firings": self.watchdog_firings,
                  "servo_resets": self.servo_resets, "homing": self.homing.run is not None,
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
            # homed once its homing is over (the motors back at 0 rad), not when its end stop is found
            homed = self.bus.homed.get(name, False) and self.homing.run is None
            m_level = ERROR if error else OK if homed or not self.connected else WARN
            m_message = ("hardware error " + ", ".join(decode_hardware_error(error)) if error
                         else "ok" if homed or not self.connected else "not homed since the servo powered up")
            vals: dict[str, object] = {"id": c.servo_id, "homed": homed, "hardware_error": error,
                                       "zero_ticks": c.zero_ticks}
            info = self.bus.servo_info.get(name)
            if info is not None:
                vals.update(model=info.model, firmware=info.firmware, operating_mode=info.operating_mode,
                            watchdog_ms=f"{info.watchdog_ms:g}", current_limit_ma=f"{info.current_limit_ma:.0f}")
            if s is not None:
                vals.update(position_rad=f"{s.position_rad:.4f}", velocity_rpm=f"{s.velocity_rpm:.2f}",
                            current_ma=f"{s.current_ma:.1f}", torque_on=s.torque_on, watchdog_fired=s.watchdog_fired)
            out.append(DiagnosticStatusData(f"motor_driver: {name}", m_level, m_message, f"{hw}#{c.servo_id}",
                                            {k: str(v) for k, v in vals.items()}))
        return out


def _positions(states: dict[str, MotorState]) -> dict[str, float]:
    return {name: state.position_rad for name, state in states.items()}
