"""Controller framework: event-driven state machines stepped once per sensor sample.

A controller never reads a clock or touches a motor. It is started with the joint positions, then
stepped with a `ControlInput` per sample (explicit `stamp_ns`, Algorithm 1 evaluations per finger,
normal forces per finger and the latest joint sample), and answers with a `ControlOutput`: the
velocity command to apply (only when it changes), the phase, and, once finished, the stop reason.

Force feedback is an input: the caller decides where `forces` come from (the force estimator's Fz on
the robot and in the estimator closed loop, the world's ground truth in unit tests).

Stop reasons: edge_lost, force_reached, reached (a gripper goal's position), joint_limit, timeout,
canceled, sensor_stale, motor_fault, no_contact (a manipulation's pad has nothing to steer by).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from prisma_common.hand import MOTOR_NAMES
from prisma_motor_driver.backend import MotorConfig

from .contact_monitor import ContactEvaluation

EDGE_LOST = "edge_lost"
FORCE_REACHED = "force_reached"
REACHED = "reached"
JOINT_LIMIT = "joint_limit"
TIMEOUT = "timeout"
CANCELED = "canceled"
SENSOR_STALE = "sensor_stale"
MOTOR_FAULT = "motor_fault"
NO_CONTACT = "no_contact"
REASONS = (EDGE_LOST, FORCE_REACHED, REACHED, JOINT_LIMIT, TIMEOUT, CANCELED, SENSOR_STALE, MOTOR_FAULT, NO_CONTACT)


@dataclass(frozen=True)
class JointSample:
    stamp_ns: int
    positions: Mapping[str, float]  # rad
    velocities: Mapping[str, float] = field(default_factory=dict)  # rpm
    currents: Mapping[str, float] = field(default_factory=dict)  # mA


@dataclass(frozen=True)
class ControlInput:
    stamp_ns: int
    contacts: Mapping[str, ContactEvaluation]
    forces: Mapping[str, float]  # normal force per finger, N (pressing into the pad is positive)
    joints: JointSample
    inputs: Mapping[str, Any] = field(default_factory=dict)  # a goal kind's extra inputs (goal_kind.py)


@dataclass(frozen=True)
class MotorCommand:
    """Velocity-mode command for every motor (0 = stopped)."""

    velocities_rpm: Mapping[str, float]

    @classmethod
    def stop(cls) -> MotorCommand:
        return cls({name: 0.0 for name in MOTOR_NAMES})

    @classmethod
    def of(cls, **rpm: float) -> MotorCommand:
        return cls({name: float(rpm.get(name, 0.0)) for name in MOTOR_NAMES})

    @property
    def is_stop(self) -> bool:
        return all(v == 0.0 for v in self.velocities_rpm.values())


@dataclass(frozen=True)
class ControlEvent:
    stamp_ns: int
    phase: str
    what: str  # e.g. "edge_lost:right", "force_reached:fingers", "restored:left", "stop"


@dataclass(frozen=True)
class ControlOutput:
    stamp_ns: int
    phase: str
    command: MotorCommand | None  # None: keep the last command
    done: bool = False
    reason: str | None = None
    success: bool = False


@dataclass(frozen=True)
class ControlLimits:
    """Position windows the controllers keep the motors in (usually the motor_driver's limits)."""

    motors: Mapping[str, MotorConfig]
    margin_rad: float = 0.02

    def at_limit(self, name: str, position: float, velocity_rpm: float) -> bool:
        """True when moving at velocity_rpm would push `name` past its limit."""
        c = self.motors[name]
        if velocity_rpm > 0:
            return position >= c.max_position_rad - self.margin_rad
        if velocity_rpm < 0:
            return position <= c.min_position_rad + self.margin_rad
        return False


class Controller:
    """Base state machine: start/step/abort bookkeeping, timeout, joint limits, event log."""

    kind = "controller"
    fingers: tuple[str, ...] = ()  # fingers whose samples it needs (the watchdog checks these)

    def __init__(self, limits: ControlLimits, timeout_s: float = 0.0) -> None:
        if timeout_s < 0:
            raise ValueError(f"timeout {timeout_s} must be >= 0")
        self.limits = limits
        self.timeout_ns = int(timeout_s * 1e9)
        self.phase = "idle"
        self.command = MotorCommand.stop()
        self.start_ns: int | None = None
        self.stop_ns: int | None = None  # stamp of the sample that ended the motion
        self.reason: str | None = None
        self.success = False
        self.done = False
        self.events: list[ControlEvent] = []
        self.start_positions: dict[str, float] = {}

    # ---- public API ------------------------------------------------------------------------
    def start(self, joints: JointSample) -> ControlOutput:
        self.start_ns = joints.stamp_ns
        self.start_positions = dict(joints.positions)
        self._log(joints.stamp_ns, "start")
        return self._on_start(joints)

    def step(self, inp: ControlInput) -> ControlOutput:
        if self.done:
            return ControlOutput(inp.stamp_ns, self.phase, None, True, self.reason, self.success)
        if self.start_ns is None:
            raise RuntimeError("step() before start()")
        if self.timeout_ns and inp.stamp_ns - self.start_ns >= self.timeout_ns:
            return self._timeout(inp)
        return self._on_step(inp)

    def abort(self, stamp_ns: int, reason: str) -> ControlOutput:
        """End now (canceled, sensor_stale, motor_fault): stop every motor."""
        if self.done:
            return ControlOutput(stamp_ns, self.phase, None, True, self.reason, self.success)
        return self._finish(stamp_ns, reason, success=False)

    # ---- for subclasses --------------------------------------------------------------------
    def _on_start(self, joints: JointSample) -> ControlOutput:
        raise NotImplementedError

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        raise NotImplementedError

    def _timeout(self, inp: ControlInput) -> ControlOutput:
        return self._finish(inp.stamp_ns, TIMEOUT, success=False)

    def _log(self, stamp_ns: int, what: str) -> None:
        self.events.append(ControlEvent(stamp_ns, self.phase, what))

    def _set(self, stamp_ns: int, phase: str, command: MotorCommand) -> ControlOutput:
        """Enter `phase` with `command`; the output carries the command only when it changed."""
        changed = command != self.command
        if phase != self.phase:
            self.phase = phase
            self._log(stamp_ns, f"phase:{phase}")
        self.command = command
        return ControlOutput(stamp_ns, phase, command if changed else None)

    def _keep(self, stamp_ns: int) -> ControlOutput:
        return ControlOutput(stamp_ns, self.phase, None)

    def _finish(self, stamp_ns: int, reason: str, success: bool, record_stop: bool = True) -> ControlOutput:
        if record_stop and self.stop_ns is None:
            self.stop_ns = stamp_ns
        self.reason, self.success, self.done = reason, success, True
        self._log(stamp_ns, f"done:{reason}")
        changed = not self.command.is_stop
        self.command = MotorCommand.stop()
        self.phase = "done"
        return ControlOutput(stamp_ns, "done", self.command if changed else None, True, reason, success)

    def _moving_into_limit(self, joints: JointSample) -> str | None:
        """Name of a commanded motor that has reached its limit in its direction of travel."""
        for name, rpm in self.command.velocities_rpm.items():
            if rpm and name in joints.positions and self.limits.at_limit(name, joints.positions[name], rpm):
                return name
        return None
