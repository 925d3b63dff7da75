"""The hand as a one-joint gripper (control_msgs/action/GripperCommand): position + force limit.

`position_rad` is the target of the `fingers` motor in rad (0 = open, the motor's maximum = fully
closed): the value an arm stack's gripper controller sends for the hand's actuated joint `fingers`.
Thumb flexion follows in a fixed ratio, `thumb_ratio` x position (clamped to its range), so that
thumb and fingers close together as the jaws of a gripper: the default 0.8333 is the pinch geometry
of the hand/world model, where the index touches a presented object at fingers 3.0 rad and the thumb
at thumb_flexion 2.5 rad, so both pads reach it at once. Thumb rotation is left where it is.

Each motor runs at its speed (`speed_rpm` for the fingers, `thumb_ratio` x that for the thumb)
toward its target and stops `stop_lead_s` of travel before it (the velocity loop coasts about one
time constant after a stop command, and positions are seen once per sample). The force limit
`max_effort_n` applies to the estimated normal forces of `pads`: while a motor closes, the first
sample whose highest pad force reaches the limit stops every closing motor ("stalled"). An opening
motor is never stopped by force, so a gripper holding an object above the limit still opens.
The goal ends when no motor moves: `reached` when every motor got to its target, `force_reached`
(stalled) when the force limit stopped one first; both succeed. The base class adds the timeout.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

from prisma_motor_driver.control_table import rpm_to_rad_s

from .controllers import (
    FORCE_REACHED,
    REACHED,
    ControlInput,
    ControlLimits,
    ControlOutput,
    Controller,
    JointSample,
    MotorCommand,
)

GRIPPER_MOTORS = ("fingers", "thumb_flexion")
DEFAULT_THUMB_RATIO = 0.8333  # thumb_flexion per fingers rad: 2.5 / 3.0, the pinch ball's contacts


class GripperController(Controller):
    kind = "gripper"

    def __init__(
        self,
        limits: ControlLimits,
        position_rad: float,
        max_effort_n: float,
        pads: Sequence[str],
        speed_rpm: float = 60.0,
        thumb_ratio: float = DEFAULT_THUMB_RATIO,
        timeout_s: float = 10.0,
        stop_lead_s: float = 0.015,
    ) -> None:
        super().__init__(limits, timeout_s)
        for label, value in (("max_effort", max_effort_n), ("speed_rpm", speed_rpm), ("thumb_ratio", thumb_ratio)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{label} {value} must be > 0")
        if not pads:
            raise ValueError("the gripper needs at least one pad to measure its force on")
        fingers = limits.motors["fingers"]
        if not (math.isfinite(position_rad) and fingers.min_position_rad <= position_rad <= fingers.max_position_rad):
            raise ValueError(f"position {position_rad} rad outside the fingers motor's range "
                             f"[{fingers.min_position_rad}, {fingers.max_position_rad}]")
        thumb = limits.motors["thumb_flexion"]
        self.targets = {"fingers": position_rad,
                        "thumb_flexion": min(max(thumb_ratio * position_rad, thumb.min_position_rad),
                                             thumb.max_position_rad)}
        self.speeds = {"fingers": speed_rpm, "thumb_flexion": speed_rpm * thumb_ratio}
        self.leads = {m: rpm_to_rad_s(rpm) * stop_lead_s for m, rpm in self.speeds.items()}
        self.max_effort_n = max_effort_n
        self.fingers = tuple(pads)
        self.moving: dict[str, float] = {}  # motor -> direction of travel (+1 closes)
        self.reached = {m: False for m in GRIPPER_MOTORS}
        self.stalled = False
        self.reached_goal = False
        self.position = 0.0  # latest fingers position and highest pad force, for feedback and result
        self.effort = 0.0

    def _on_start(self, joints: JointSample) -> ControlOutput:
        self.position = joints.positions["fingers"]
        for motor in GRIPPER_MOTORS:
            error = self.targets[motor] - joints.positions[motor]
            if abs(error) <= self.leads[motor]:
                self.reached[motor] = True
            else:
                self.moving[motor] = math.copysign(1.0, error)
        if not self.moving:
            return self._end(joints.stamp_ns)
        return self._set(joints.stamp_ns, self._phase(), self._command())

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        t = inp.stamp_ns
        positions = inp.joints.positions
        self.position = positions["fingers"]
        self.effort = max(inp.forces.get(pad, 0.0) for pad in self.fingers)
        closing = [m for m, direction in self.moving.items() if direction > 0]
        if closing and self.effort >= self.max_effort_n:
            self.stalled = True
            self._log(t, f"force_reached:{self.effort:.3f}")
            for motor in closing:
                del self.moving[motor]
        for motor, direction in list(self.moving.items()):
            if (self.targets[motor] - positions[motor]) * direction <= self.leads[motor]:
                self.reached[motor] = True
                self._log(t, f"reached:{motor}")
                del self.moving[motor]
        if not self.moving:
            return self._end(t)
        return self._set(t, self._phase(), self._command())

    def _end(self, stamp_ns: int) -> ControlOutput:
        self.reached_goal = all(self.reached.values())
        return self._finish(stamp_ns, REACHED if self.reached_goal else FORCE_REACHED, success=True)

    def _phase(self) -> str:
        directions = set(self.moving.values())
        return "close" if directions == {1.0} else "open" if directions == {-1.0} else "move"

    def _command(self) -> MotorCommand:
        return MotorCommand.of(**{m: direction * self.speeds[m] for m, direction in self.moving.items()})
