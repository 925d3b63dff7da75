"""A human hand's joint angles -> the PRISMA hand's three motor targets: synergy retargeting, then a
low-pass filter and a deadband. ROS-free.

Input: joint angles in rad by name, as data gloves and hand trackers publish a hand in a
sensor_msgs/JointState. The names are configurable (`JointGroups`); the default set,
`DEFAULT_JOINTS`, is `<finger>_mcp`, `<finger>_pip`, `<finger>_dip` (flexion) for index, middle,
ring and little, and `thumb_cmc_flexion`, `thumb_cmc_abduction`, `thumb_mcp`, `thumb_ip`.

Synergies: the hand closes 19 joints with 3 motors (tendons flex every finger together), so a
retargeter cannot copy joints one to one; it maps the operator's synergies onto the motors:
- fingers = the mean normalised flexion of the four fingers' joints x `fingers_closed`;
- thumb_flexion = the mean normalised flexion of the thumb's CMC flexion, MCP and IP x
  `thumb_flexion_closed`;
- thumb_rotation = the thumb's normalised opposition (-1 adducted, 0 open hand, +1 opposed) onto
  `thumb_rotation_adducted` .. 0 .. `thumb_rotation_opposed`.
Each joint is normalised by the operator's calibration (calibration.py: clipped, monotone, 0 at the
open hand, 1 at the fist), so each target is monotone (never decreasing as a joint flexes or the
thumb opposes further), 0 for the open hand and the closed limit for the fist, exactly. Targets are
in the motor driver's frame (0 = hand open, thumb centred); the manipulation node clamps them to the
motors' configured limits.

`TargetFilter`: per motor a Butterworth low-pass (scipy.signal.butter, `order` at `cutoff_hz` for the
glove's nominal rate `rate_hz`) run sample by sample with its state, started at the first sample's
value (no transient from 0) and started again after a silence longer than `reset_gap_s`. Its delay
is the group delay at 0 Hz, `delay_s`: 36.3 ms for the default 2nd order at 6 Hz at 60 Hz (human
hand motion lies below ~5 Hz, physiological tremor at 8-12 Hz; the coefficients hold for the nominal
rate: a glove at half the rate sees twice the delay). Then a deadband: a motor's target moves only
when the filtered value has left it by at least `deadband_rad`, so glove noise does not keep the
motors hunting, and a filtered value within the deadband of 0 or of its range's ends takes that
value itself (the open hand opens fully, the fist closes fully).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import signal

from prisma_common.hand import MOTOR_NAMES

from .calibration import OperatorCalibration

NS = 1_000_000_000
FLEXING_FINGERS = ("index", "middle", "ring", "little")


@dataclass(frozen=True)
class JointGroups:
    """Which glove joints drive which synergy."""

    finger_flexion: tuple[str, ...]
    thumb_flexion: tuple[str, ...]
    thumb_opposition: tuple[str, ...]

    def __post_init__(self) -> None:
        for name, group in (("finger_flexion", self.finger_flexion), ("thumb_flexion", self.thumb_flexion),
                            ("thumb_opposition", self.thumb_opposition)):
            if not group:
                raise ValueError(f"{name}: at least one joint")
        names = self.all()
        if len(set(names)) != len(names):
            raise ValueError(f"a joint drives one synergy only: {sorted(n for n in set(names) if names.count(n) > 1)}")

    def all(self) -> tuple[str, ...]:
        return self.finger_flexion + self.thumb_flexion + self.thumb_opposition

    def flexion(self) -> tuple[str, ...]:
        return self.finger_flexion + self.thumb_flexion


DEFAULT_JOINTS = JointGroups(
    finger_flexion=tuple(f"{finger}_{joint}" for finger in FLEXING_FINGERS for joint in ("mcp", "pip", "dip")),
    thumb_flexion=("thumb_cmc_flexion", "thumb_mcp", "thumb_ip"),
    thumb_opposition=("thumb_cmc_abduction",),
)


@dataclass(frozen=True)
class MotorRanges:
    """Where each motor goes at the ends of its synergy (rad, motor driver frame)."""

    fingers_closed: float = 9.0  # the fist: the fingers motor's closed end (config/motor_driver.yaml)
    thumb_flexion_closed: float = 7.0
    thumb_rotation_adducted: float = -1.5
    thumb_rotation_opposed: float = 1.5

    def span(self, motor: str) -> tuple[float, float]:
        """(lowest, highest) target of `motor`."""
        if motor == "fingers":
            return 0.0, self.fingers_closed
        if motor == "thumb_flexion":
            return 0.0, self.thumb_flexion_closed
        if motor == "thumb_rotation":
            ends = (self.thumb_rotation_adducted, self.thumb_rotation_opposed)
            return min(ends), max(ends)
        raise ValueError(f"unknown motor {motor!r}; expected one of {MOTOR_NAMES}")


def nominal_calibration(joints: JointGroups = DEFAULT_JOINTS) -> OperatorCalibration:
    """A typical adult hand, until the operator captures their own: finger joints 0 open and
    MCP 80, PIP 95, DIP 65 degrees in a fist; thumb CMC 35, MCP 50, IP 70 degrees; the CMC abduction
    20 degrees with the hand open, 0 against the index, 70 opposed across the palm. Joints of
    another name (a glove's own set) flex 0 -> 90 degrees and abduct -> +-45 degrees."""
    fist_deg = {"mcp": 80.0, "pip": 95.0, "dip": 65.0, "thumb_cmc_flexion": 35.0, "thumb_mcp": 50.0,
                "thumb_ip": 70.0}

    def fist(joint: str) -> float:
        key = joint if joint in fist_deg else joint.rsplit("_", 1)[-1]
        return math.radians(fist_deg.get(key, 90.0))

    nominal = joints == DEFAULT_JOINTS
    centre, adducted, opposed = (math.radians(a) for a in ((20.0, 0.0, 70.0) if nominal else (0.0, -45.0, 45.0)))
    open_hand = {j: 0.0 for j in joints.flexion()} | {j: centre for j in joints.thumb_opposition}
    return OperatorCalibration(
        open_hand=open_hand,
        fist={j: fist(j) for j in joints.flexion()} | {j: centre for j in joints.thumb_opposition},
        thumb_adducted=open_hand | {j: adducted for j in joints.thumb_opposition},
        thumb_opposed=open_hand | {j: opposed for j in joints.thumb_opposition},
        operator="nominal hand",
    )


class MissingJoints(ValueError):
    """A hand pose without a joint retargeting needs (or with a non-finite angle)."""


def retarget(angles: Mapping[str, float], calibration: OperatorCalibration, joints: JointGroups = DEFAULT_JOINTS,
             ranges: MotorRanges = MotorRanges()) -> dict[str, float]:
    """Motor name -> target (rad) of the hand pose `angles` (joint name -> rad), in MOTOR_NAMES order.
    MissingJoints naming the joints a synergy needs and the pose lacks."""
    missing = [j for j in joints.all() if not math.isfinite(angles.get(j, math.nan))]
    if missing:
        raise MissingJoints(f"hand pose lacks {', '.join(missing)} (or its angle is not finite)")
    fingers = sum(calibration.flexion(j, angles[j]) for j in joints.finger_flexion) / len(joints.finger_flexion)
    thumb = sum(calibration.flexion(j, angles[j]) for j in joints.thumb_flexion) / len(joints.thumb_flexion)
    opposition = sum(calibration.opposition(j, angles[j]) for j in joints.thumb_opposition) / len(
        joints.thumb_opposition)
    rotation_end = ranges.thumb_rotation_opposed if opposition >= 0.0 else -ranges.thumb_rotation_adducted
    return {"fingers": fingers * ranges.fingers_closed, "thumb_flexion": thumb * ranges.thumb_flexion_closed,
            "thumb_rotation": opposition * rotation_end}


class TargetFilter:
    """The motor targets of successive samples, low-pass filtered and held within a deadband (the
    module docstring says how and with what delay)."""

    def __init__(self, ranges: MotorRanges = MotorRanges(), rate_hz: float = 60.0, cutoff_hz: float = 6.0,
                 order: int = 2, deadband_rad: float = 0.02, reset_gap_s: float = 0.1) -> None:
        if not 0.0 < cutoff_hz < rate_hz / 2.0:
            raise ValueError(f"cutoff {cutoff_hz} Hz must lie between 0 and half the glove rate {rate_hz} Hz")
        if order < 1 or deadband_rad < 0.0 or reset_gap_s <= 0.0:
            raise ValueError(f"order {order} >= 1, deadband {deadband_rad} >= 0 and reset gap {reset_gap_s} > 0")
        self.b, self.a = signal.butter(order, cutoff_hz, fs=rate_hz)
        self.delay_s = float(signal.group_delay((self.b, self.a), w=[0.0], fs=rate_hz)[1][0]) / rate_hz
        self.deadband_rad = deadband_rad
        self.reset_gap_ns = int(round(reset_gap_s * NS))
        self.motors = MOTOR_NAMES
        spans = [ranges.span(m) for m in self.motors]
        self._anchors = [sorted({lo, 0.0, hi}) for lo, hi in spans]
        self._low = np.array([lo for lo, _ in spans])
        self._high = np.array([hi for _, hi in spans])
        self._unit_state = signal.lfilter_zi(self.b, self.a)[:, None]  # steady state for an input of 1
        self._state: np.ndarray | None = None
        self._held = np.zeros(len(self.motors))
        self._last_ns: int | None = None

    def reset(self) -> None:
        """Forget the past: the next sample starts the filter at its own value."""
        self._state = None
        self._last_ns = None

    def step(self, stamp_ns: int, targets: Mapping[str, float]) -> dict[str, float]:
        """The targets to send for this sample (stamp_ns: the glove sample's stamp)."""
        x = np.array([targets[m] for m in self.motors], dtype=float)
        gap = None if self._last_ns is None else stamp_ns - self._last_ns
        if self._state is None or gap is None or not 0 <= gap <= self.reset_gap_ns:
            self._state = self._unit_state * x  # as if this pose had always been held
            self._held = np.clip(x, self._low, self._high)
        self._last_ns = stamp_ns
        y, self._state = signal.lfilter(self.b, self.a, x[None, :], axis=0, zi=self._state)
        filtered = np.clip(y[0], self._low, self._high)
        for i, value in enumerate(filtered):
            anchor = min(self._anchors[i], key=lambda a: abs(a - value))  # noqa: B023 - used at once
            if abs(anchor - value) < self.deadband_rad:
                value = anchor
            if abs(value - self._held[i]) >= self.deadband_rad or (value == anchor and value != self._held[i]):
                self._held[i] = value
        return {m: float(v) for m, v in zip(self.motors, self._held)}
