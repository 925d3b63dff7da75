"""Teleoperation: the motors follow a glove's targets, limited by the fingertips' touch (issue 27).

Stepped once per tactile scan with the latest target (`TeleopTarget`: motor angles in rad in the
motor driver's frame, any subset of the motors; sample-and-hold in manipulation_core). A motor
without a target yet stands still; until any target came the phase is `waiting`.

- **Following.** Each motor's velocity is `gain x (target - position)` (gain in 1/s: rad/s per rad
  of error), capped at `max_speed_rpm` and at the motor's configured maximum velocity. Targets are
  clamped into the motor's position window less the limit margin (the motor driver would end the
  motion at the limit itself): a glove asking beyond the hand's range gets the end of the range.
  A motor within `POSITION_TOLERANCE_RAD` of its target stops, and moves again once twice as far
  off, so a glove's jitter around a held pose does not start and stop it.
- **Touch limit.** A motor does not close (positive velocity) while any configured pad it drives
  (the fingers motor: index, middle, ring, little; thumb_flexion: the thumb) reads at least
  `max_pad_force` N; it may close again once they all read `FORCE_RELEASE_N` below it (without that
  band, force noise at the limit would start and stop the motor on every scan). Within
  `APPROACH_N` of the limit a closing motor slows with the force left, down to `APPROACH_FLOOR` of
  its speed cap: the force that overshoots the limit is what rises between the scan that reaches it
  and the motor standing (the scan period, the estimator, the stop reaching the motor driver's next
  tick, the velocity loop's coast), in proportion to the speed; at the full 40 rpm onto the sim ball
  it was 0.10-0.12 N on the launched graph. Opening is always allowed, so an operator can let go of
  an object pressed above the limit. thumb_rotation drives no pad and is not limited. The phase is
  `holding` while a motor is held back, else `following`.
- **Commands.** A motor starting, stopping or turning is commanded at once; a changed speed in the
  same direction at most every `COMMAND_PERIOD_S`. Each command is a MoveMotors goal: a proportional
  law changes its speed on every scan, and 100 goals a second would swamp the motor driver's
  goal bookkeeping (docs/manipulation.md, "Safety"); 20 a second sample the law finely enough
  (gain x period = 0.5 at the default gain: no overshoot from the sampling).

It never ends on its own (a teleoperation has no goal of its own to reach): the core ends it on a
cancel (success), the targets falling silent (input_stale), stale sensors or a motor fault.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from prisma_common.hand import MOTOR_NAMES
from prisma_hand_sim.hand_world import TENDON_MOTOR
from prisma_motor_driver.control_table import rad_s_to_rpm

from .controllers import CANCELED, ControlInput, ControlLimits, ControlOutput, Controller, JointSample, MotorCommand

TARGET_STREAM = "teleop_target"  # the core's name of the targets input (teleop_goal.py)
WAITING, FOLLOWING, HOLDING = "waiting", "following", "holding"
POSITION_TOLERANCE_RAD = 0.02
FORCE_RELEASE_N = 0.05
COMMAND_PERIOD_S = 0.05
APPROACH_N = 0.5
APPROACH_FLOOR = 0.25
PRESSING_MOTORS = tuple(m for m in MOTOR_NAMES if m in TENDON_MOTOR.values())  # fingers, thumb_flexion


@dataclass(frozen=True)
class TeleopTarget:
    """One target message: the stamp of the glove sample it came from, and angles per motor (rad)."""

    stamp_ns: int
    positions: Mapping[str, float] = field(default_factory=dict)


def pads_of(motor: str, pads: Sequence[str]) -> tuple[str, ...]:
    """The pads among `pads` that `motor` presses onto an object (none for thumb_rotation)."""
    return tuple(p for p in pads if TENDON_MOTOR.get(p) == motor)


class TeleopController(Controller):
    kind = "teleop"

    def __init__(self, limits: ControlLimits, pads: Sequence[str], max_pad_force_n: float, max_speed_rpm: float,
                 gain_per_s: float) -> None:
        super().__init__(limits)
        for label, value in (("max_pad_force", max_pad_force_n), ("max_speed_rpm", max_speed_rpm),
                             ("gain", gain_per_s)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{label} {value} must be > 0")
        self.fingers = tuple(pads)
        self.max_pad_force_n = max_pad_force_n
        self.gain_per_s = gain_per_s
        self.speed_caps = {m: min(max_speed_rpm, limits.motors[m].max_velocity_rpm) for m in MOTOR_NAMES}
        self.targets: dict[str, float] = {}  # rad, clamped; a motor without one stands still
        self.force_limited: tuple[str, ...] = ()
        self._held: set[str] = set()  # motors held back by the touch limit
        self._settled: set[str] = set()  # motors stopped at their target (the tolerance)
        self._commanded_ns = 0  # stamp of the last command sent

    def abort(self, stamp_ns: int, reason: str) -> ControlOutput:
        """A cancel is a teleoperation's normal end (it has no goal of its own to reach): a success."""
        if reason == CANCELED and not self.done:
            return self._finish(stamp_ns, CANCELED, success=True)
        return super().abort(stamp_ns, reason)

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._set(joints.stamp_ns, WAITING, MotorCommand.stop())

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        target = inp.inputs.get(TARGET_STREAM)
        if target is not None:
            self.targets.update({m: self._clamp(m, a) for m, a in target.positions.items()
                                 if m in MOTOR_NAMES and math.isfinite(a)})
        if not self.targets:
            return self._set(inp.stamp_ns, WAITING, MotorCommand.stop())
        velocities = {m: self._velocity(m, inp.joints.positions[m]) for m in MOTOR_NAMES}
        self.force_limited = tuple(m for m in MOTOR_NAMES if self._touch_limit(m, velocities, inp.forces))
        phase = HOLDING if self.force_limited else FOLLOWING
        return self._command(inp.stamp_ns, phase, MotorCommand.of(**velocities))

    def _clamp(self, motor: str, angle: float) -> float:
        c, margin = self.limits.motors[motor], self.limits.margin_rad
        return min(max(angle, c.min_position_rad + margin), c.max_position_rad - margin)

    def _velocity(self, motor: str, position: float) -> float:
        """rpm toward the target: proportional, capped; 0 within the tolerance (twice it to restart)."""
        if motor not in self.targets:
            return 0.0
        error = self.targets[motor] - position
        tolerance = POSITION_TOLERANCE_RAD * (2.0 if motor in self._settled else 1.0)
        if abs(error) <= tolerance:
            self._settled.add(motor)
            return 0.0
        self._settled.discard(motor)
        cap = self.speed_caps[motor]
        return min(max(rad_s_to_rpm(self.gain_per_s * error), -cap), cap)

    def _touch_limit(self, motor: str, velocities: dict[str, float], forces: Mapping[str, float]) -> bool:
        """Hold `motor` from closing while a pad it drives is at the limit (with the release band):
        True when it was asked to close and is held back."""
        force = max((forces.get(p, 0.0) for p in pads_of(motor, self.fingers)), default=0.0)
        if force >= self.max_pad_force_n:
            self._held.add(motor)
        elif force < self.max_pad_force_n - FORCE_RELEASE_N:
            self._held.discard(motor)
        if motor in self._held and velocities[motor] > 0.0:
            velocities[motor] = 0.0
            return True
        left = (self.max_pad_force_n - force) / APPROACH_N
        if velocities[motor] > 0.0 and left < 1.0:
            velocities[motor] = min(velocities[motor], self.speed_caps[motor] * max(left, APPROACH_FLOOR))
        return False

    def _command(self, stamp_ns: int, phase: str, command: MotorCommand) -> ControlOutput:
        """`command` now when a motor starts, stops or turns, or the last one is COMMAND_PERIOD_S old;
        else the phase with the last command kept."""
        old, new = self.command.velocities_rpm, command.velocities_rpm
        turns = any(_sign(old[m]) != _sign(new[m]) for m in MOTOR_NAMES)
        if turns or stamp_ns - self._commanded_ns >= COMMAND_PERIOD_S * 1e9:
            if command != self.command:
                self._commanded_ns = stamp_ns
            return self._set(stamp_ns, phase, command)
        return self._set(stamp_ns, phase, self.command)


def _sign(x: float) -> int:
    return (x > 0) - (x < 0)
