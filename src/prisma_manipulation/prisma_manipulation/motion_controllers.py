"""In-hand manipulation controllers driven by Algorithm 1 (docs/manipulation.md).

All of them watch one fingertip (the thumb by default) through its ContactEvaluation:
- HorizontalController: thumb rotation clockwise at 20 rpm until the right side (6-3-0) is lost or
  the joint limit, then back anticlockwise to the start angle.
- VerticalController: "down" = fingers close + thumb extends at 10 rpm until the top row (6-7-8) is
  lost or a limit; "up" = fingers open + thumb flexes at 10 rpm until the bottom row (0-1-2) is lost or
  a limit.
- HoldController: keep the grasp; when a lateral side is lost, rotate the thumb at 20 rpm toward
  restoring it until at least two of that side's taxels are back at or above v_t.
- With a ForceKeeper (Manipulate goal use_force = true) each of them also holds the thumb's normal
  force: when it drops more than `band_n` below the target the thumb flexes until the target is back,
  while the voltages keep steering the orientation (the combined voltage + force controller).
- Each steers by a contact: a sample on which the watched pad's mean voltage is below
  `contact_voltage` (the monitor's min_mean_voltage: an untouched pad sits at its ~0.43 V rest
  voltages) ends the goal with `no_contact`, unsuccessful, whatever the phase. Algorithm 1 alone
  would call an untouched pad "safe" and a horizontal sweep would run on to the joint limit.

Direction convention: positive thumb_rotation velocity is "clockwise", which moves the contact on the
thumb pad toward its left side (+x), away from the right side; positive fingers / thumb_flexion close.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from prisma_motor_driver.control_table import rpm_to_rad_s

from .contact_monitor import ContactEvaluation
from .controllers import (
    EDGE_LOST,
    JOINT_LIMIT,
    NO_CONTACT,
    TIMEOUT,
    ControlInput,
    ControlLimits,
    ControlOutput,
    Controller,
    JointSample,
    MotorCommand,
)

OPPOSITE_SIDE = {"left": "right", "right": "left"}
# rotation that moves the thumb contact back toward a lost side: +x (left) needs clockwise (+)
RESTORE_DIRECTION = {"left": +1.0, "right": -1.0}


@dataclass
class ForceKeeper:
    """Hysteresis force regulator on the thumb's normal force (combined controller)."""

    target_n: float = 1.0
    band_n: float = 0.15
    speed_rpm: float = 20.0
    restoring: bool = field(default=False, init=False)
    restores: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        if not self.target_n > 0 or not 0 < self.band_n < self.target_n or not self.speed_rpm > 0:
            raise ValueError(f"ForceKeeper target {self.target_n} N, band {self.band_n} N, speed "
                             f"{self.speed_rpm} rpm: need target > band > 0 and speed > 0")

    def update(self, force_n: float) -> float:
        """Thumb flexion velocity (rpm) to add for this sample."""
        if not self.restoring and force_n < self.target_n - self.band_n:
            self.restoring = True
            self.restores += 1
        elif self.restoring and force_n >= self.target_n:
            self.restoring = False
        return self.speed_rpm if self.restoring else 0.0


class _MotionController(Controller):
    def __init__(self, limits: ControlLimits, speed_rpm: float, finger: str, timeout_s: float,
                 force_keeper: ForceKeeper | None, contact_voltage: float = 0.0) -> None:
        super().__init__(limits, timeout_s)
        if not speed_rpm > 0:
            raise ValueError(f"speed_rpm {speed_rpm} must be > 0")
        self.contact_voltage = contact_voltage
        self.speed_rpm = speed_rpm
        self.finger = finger
        self.fingers = (finger,) if finger == "thumb" else (finger, "thumb")
        self.force_keeper = force_keeper
        self.phase_stops: dict[str, tuple[int, str]] = {}  # phase -> (stamp_ns, reason)
        self.threshold = 0.0
        self.feasible = False

    def _motion(self, stamp_ns: int, phase: str, rpm: dict[str, float],
                inp: ControlInput | None = None) -> ControlOutput:
        """Set a phase's motion plus the force keeper's thumb flexion share."""
        rpm = dict(rpm)
        if self.force_keeper is not None and inp is not None:
            extra = self.force_keeper.update(inp.forces.get("thumb", 0.0))
            rpm["thumb_flexion"] = rpm.get("thumb_flexion", 0.0) + extra
        return self._set(stamp_ns, phase, MotorCommand.of(**rpm))

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        contact = inp.contacts[self.finger]
        self.threshold, self.feasible = contact.threshold, contact.feasible
        if contact.mean_voltage < self.contact_voltage:
            self._log(inp.stamp_ns, f"no_contact:{self.finger}")
            return self._finish(inp.stamp_ns, NO_CONTACT, success=False)
        return self._steer(inp, contact)

    def _steer(self, inp: ControlInput, contact: ContactEvaluation) -> ControlOutput:
        raise NotImplementedError


class HorizontalController(_MotionController):
    kind = "horizontal"

    def __init__(self, limits: ControlLimits, speed_rpm: float = 20.0, finger: str = "thumb",
                 edge: str = "right", timeout_s: float = 20.0, stop_lead_s: float = 0.015,
                 force_keeper: ForceKeeper | None = None, contact_voltage: float = 0.0) -> None:
        super().__init__(limits, speed_rpm, finger, timeout_s, force_keeper, contact_voltage)
        if edge not in OPPOSITE_SIDE:
            raise ValueError(f"edge {edge!r} is not 'left' or 'right'")
        self.edge = edge
        # rotating away from `edge`: clockwise loses the right side
        self.direction = 1.0 if edge == "right" else -1.0
        # the motor keeps turning for about one velocity-loop time constant after the stop command
        # and the position is only seen once per sample: stop the return this much early
        self.stop_lead_rad = rpm_to_rad_s(speed_rpm) * stop_lead_s
        self.return_ns: int | None = None

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._set(joints.stamp_ns, "rotate", MotorCommand.of(thumb_rotation=self.direction * self.speed_rpm))

    def _steer(self, inp: ControlInput, contact: ContactEvaluation) -> ControlOutput:
        t = inp.stamp_ns
        rotation = {"thumb_rotation": self.direction * self.speed_rpm}
        if self.phase == "rotate":
            reason = None
            if self.edge in contact.lost_edges:
                reason = EDGE_LOST
                self._log(t, f"edge_lost:{self.edge}")
            elif self._moving_into_limit(inp.joints):
                reason = JOINT_LIMIT
                self._log(t, "joint_limit:thumb_rotation")
            if reason:
                self.stop_ns, self.reason = t, reason
                self.phase_stops["rotate"] = (t, reason)
                return self._motion(t, "return", {"thumb_rotation": -rotation["thumb_rotation"]}, inp)
            return self._motion(t, "rotate", rotation, inp)
        # return phase: back to the start angle
        start = self.start_positions.get("thumb_rotation", 0.0)
        remaining = (inp.joints.positions["thumb_rotation"] - start) * self.direction
        if remaining <= self.stop_lead_rad:
            self.return_ns = t
            self._log(t, "returned")
            return self._finish(t, self.reason or EDGE_LOST, success=True, record_stop=False)
        return self._motion(t, "return", {"thumb_rotation": -rotation["thumb_rotation"]}, inp)


class VerticalController(_MotionController):
    kind = "vertical"

    def __init__(self, limits: ControlLimits, speed_rpm: float = 10.0, finger: str = "thumb",
                 timeout_s: float = 30.0, force_keeper: ForceKeeper | None = None,
                 contact_voltage: float = 0.0) -> None:
        super().__init__(limits, speed_rpm, finger, timeout_s, force_keeper, contact_voltage)

    def _down(self) -> dict[str, float]:
        return {"fingers": self.speed_rpm, "thumb_flexion": -self.speed_rpm}

    def _up(self) -> dict[str, float]:
        return {"fingers": -self.speed_rpm, "thumb_flexion": self.speed_rpm}

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._set(joints.stamp_ns, "down", MotorCommand.of(**self._down()))

    def _steer(self, inp: ControlInput, contact: ContactEvaluation) -> ControlOutput:
        t = inp.stamp_ns
        if self.phase == "down":
            reason = None
            if "top" in contact.lost_edges:
                reason = EDGE_LOST
                self._log(t, "edge_lost:top")
            elif self._moving_into_limit(inp.joints):
                reason = JOINT_LIMIT
                self._log(t, "joint_limit")
            if reason:
                self.phase_stops["down"] = (t, reason)
                return self._motion(t, "up", self._up(), inp)
            return self._motion(t, "down", self._down(), inp)
        if "bottom" in contact.lost_edges:
            self._log(t, "edge_lost:bottom")
            self.phase_stops["up"] = (t, EDGE_LOST)
            return self._finish(t, EDGE_LOST, success=True)
        if self._moving_into_limit(inp.joints):
            self.phase_stops["up"] = (t, JOINT_LIMIT)
            return self._finish(t, JOINT_LIMIT, success=True)
        return self._motion(t, "up", self._up(), inp)


class HoldController(_MotionController):
    """Disturbance rejection. Runs until timeout (success) or an abort."""

    kind = "hold"

    def __init__(self, limits: ControlLimits, speed_rpm: float = 20.0, finger: str = "thumb",
                 timeout_s: float = 30.0, restored_taxels: int = 2,
                 force_keeper: ForceKeeper | None = None, contact_voltage: float = 0.0) -> None:
        super().__init__(limits, speed_rpm, finger, timeout_s, force_keeper, contact_voltage)
        if not 1 <= restored_taxels <= 3:
            raise ValueError(f"restored_taxels {restored_taxels} must be 1..3")
        self.restored_taxels = restored_taxels
        self.side: str | None = None
        self.restorations: list[tuple[str, int, int]] = []  # (side, lost stamp, restored stamp)
        self._lost_ns = 0

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._set(joints.stamp_ns, "hold", MotorCommand.stop())

    def _steer(self, inp: ControlInput, contact: ContactEvaluation) -> ControlOutput:
        t = inp.stamp_ns
        if self.side is None:
            lost_sides = [s for s in ("left", "right") if s in contact.lost_edges]
            if len(lost_sides) == 1:  # both lost = no contact to steer by
                self.side, self._lost_ns = lost_sides[0], t
                self._log(t, f"edge_lost:{self.side}")
        elif contact.safe_count(self.side) >= self.restored_taxels:
            self._log(t, f"restored:{self.side}")
            self.restorations.append((self.side, self._lost_ns, t))
            self.stop_ns = t
            self.side = None
        if self.side is not None:
            rpm = {"thumb_rotation": RESTORE_DIRECTION[self.side] * self.speed_rpm}
            if self._moving_into_limit(inp.joints):
                return self._finish(t, JOINT_LIMIT, success=False)
            return self._motion(t, f"restore_{self.side}", rpm, inp)
        out = self._motion(t, "hold", {}, inp)
        if self._moving_into_limit(inp.joints):
            return self._finish(t, JOINT_LIMIT, success=False)
        return out

    def _timeout(self, inp: ControlInput) -> ControlOutput:
        # holding for the whole goal duration is the normal end of a hold goal
        return self._finish(inp.stamp_ns, TIMEOUT, success=True, record_stop=False)
