"""Force-controlled grasp (docs/manipulation.md): fingers close at speed until their normal force
reaches the finger target, then the thumb flexes at speed until its normal force reaches the thumb
target.

Presets say which fingertips carry the finger force:
- pinch: the index pad opposes the thumb pad (tip pinch);
- power: all four finger pads wrap the object; the finger force is their mean over the pads in
  contact (a pad above `contact_force_n`), so one finger that misses the object cannot hold the grasp
  open forever;
- lateral: the object is held between the thumb pad and the side of the index, where there is no
  sensor; the fingers close to `lateral_closure_rad` (a fist that makes the lateral surface) and only
  the thumb phase is force-controlled.

Each phase stops on the first sample whose force reaches the target (reason force_reached at the
end of the thumb phase); a motor reaching its limit first ends the grasp with joint_limit.
"""
from __future__ import annotations

from dataclasses import dataclass

from .controllers import (
    FORCE_REACHED,
    JOINT_LIMIT,
    ControlInput,
    ControlLimits,
    ControlOutput,
    Controller,
    JointSample,
    MotorCommand,
)


@dataclass(frozen=True)
class GraspPreset:
    name: str
    force_fingers: tuple[str, ...]  # pads whose normal force ends the fingers phase
    force_controlled_fingers: bool = True


GRASP_PRESETS = {
    "pinch": GraspPreset("pinch", ("index",)),
    "power": GraspPreset("power", ("index", "middle", "ring", "little")),
    "lateral": GraspPreset("lateral", (), force_controlled_fingers=False),
}


class GraspController(Controller):
    kind = "grasp"

    def __init__(
        self,
        limits: ControlLimits,
        grasp: str = "pinch",
        finger_force_n: float = 0.8,
        thumb_force_n: float = 1.0,
        speed_rpm: float = 60.0,
        timeout_s: float = 10.0,
        contact_force_n: float = 0.1,
        lateral_closure_rad: float = 7.0,
    ) -> None:
        super().__init__(limits, timeout_s)
        if grasp not in GRASP_PRESETS:
            raise ValueError(f"grasp {grasp!r} is not one of {sorted(GRASP_PRESETS)}")
        for label, value in (("finger_force", finger_force_n), ("thumb_force", thumb_force_n),
                             ("speed_rpm", speed_rpm)):
            if not value > 0:
                raise ValueError(f"{label} {value} must be > 0")
        self.preset = GRASP_PRESETS[grasp]
        self.finger_force_n = finger_force_n
        self.thumb_force_n = thumb_force_n
        self.speed_rpm = speed_rpm
        self.contact_force_n = contact_force_n
        self.lateral_closure_rad = lateral_closure_rad
        self.fingers = ("thumb",) + self.preset.force_fingers
        self.finger_force = 0.0  # latest values, for feedback
        self.thumb_force = 0.0
        self.phase_end_ns: dict[str, int] = {}

    def fingers_force(self, forces) -> float:
        pads = [forces.get(f, 0.0) for f in self.preset.force_fingers]
        if not pads:
            return 0.0
        touching = [f for f in pads if f >= self.contact_force_n]
        return sum(touching) / len(touching) if touching else max(pads)

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._set(joints.stamp_ns, "close_fingers", MotorCommand.of(fingers=self.speed_rpm))

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        self.finger_force = self.fingers_force(inp.forces)
        self.thumb_force = inp.forces.get("thumb", 0.0)
        t = inp.stamp_ns
        if self.phase == "close_fingers":
            if self.preset.force_controlled_fingers:
                reached = self.finger_force >= self.finger_force_n
            else:
                reached = inp.joints.positions.get("fingers", 0.0) >= self.lateral_closure_rad
            if reached:
                self.phase_end_ns["close_fingers"] = t
                self._log(t, "force_reached:fingers" if self.preset.force_controlled_fingers else "closed:fingers")
                return self._set(t, "close_thumb", MotorCommand.of(thumb_flexion=self.speed_rpm))
        elif self.phase == "close_thumb":
            if self.thumb_force >= self.thumb_force_n:
                self.phase_end_ns["close_thumb"] = t
                self._log(t, "force_reached:thumb")
                return self._finish(t, FORCE_REACHED, success=True)
        if self._moving_into_limit(inp.joints):
            return self._finish(t, JOINT_LIMIT, success=False)
        return self._keep(t)
