"""A synthetic hand-pose glove, ROS-free: an operator's scripted hand as a glove reports it.

The operator (`OperatorScript`), one cycle: the open hand for `rest_s`; closing in `close_s` (fingers
and thumb together, to `closure` of a fist: the operator's hand holds nothing, the robot's holds the
ball and its touch limit stops it there); holding for `hold_s`; opening in `open_s`; the open hand
for `rest_s`; then the thumb's opposition sweep in `sweep_s` (from the open hand's thumb to pressed
against the index, then opposed across the palm, then back), the fingers open. Moves follow a raised
cosine (no jerk at their ends), as a hand moves. `synergies(t)` is the operator's command at t:
flexion of the fingers and of the thumb (0 open .. 1 fist) and opposition (-1 adducted .. 0 open ..
+1 opposed).

`SyntheticGlove` turns it into joint angles through a calibration (retargeting.nominal_calibration
by default: the inverse of the normalisation, so that retargeting it gives back the command exactly)
with the glove's noise on each joint. The teleop launch file runs it as the synthetic_glove node;
prisma-sim's teleop scenario and the launch tests use the same operator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .calibration import OperatorCalibration
from .retargeting import DEFAULT_JOINTS, JointGroups, nominal_calibration


@dataclass(frozen=True)
class Synergies:
    """The operator's command: flexion of the fingers and of the thumb (0..1), opposition (-1..1)."""

    fingers: float
    thumb: float
    opposition: float


def _ease(u: float) -> float:
    """0 -> 1 along a raised cosine, u in [0, 1]."""
    return 0.5 - 0.5 * math.cos(math.pi * min(1.0, max(0.0, u)))


@dataclass(frozen=True)
class OperatorScript:
    rest_s: float = 1.0
    close_s: float = 1.5
    hold_s: float = 2.0
    open_s: float = 1.5
    sweep_s: float = 4.0
    closure: float = 1.0

    def __post_init__(self) -> None:
        if self.close_s <= 0 or self.open_s <= 0 or min(self.rest_s, self.hold_s, self.sweep_s) < 0:
            raise ValueError(f"close_s and open_s must be > 0, the other durations >= 0: {self}")

    @property
    def duration_s(self) -> float:
        """One cycle."""
        return 2 * self.rest_s + self.close_s + self.hold_s + self.open_s + self.sweep_s

    def phases(self) -> list[tuple[str, float]]:
        """(phase, its start in s) in order."""
        names = ("rest", "close", "hold", "open", "rest", "sweep")
        lengths = (self.rest_s, self.close_s, self.hold_s, self.open_s, self.rest_s, self.sweep_s)
        starts = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
        return [(n, float(s)) for n, s in zip(names, starts)]

    def synergies(self, t_s: float) -> Synergies:
        """The command at t_s (s from the cycle's start; later cycles repeat it)."""
        t = t_s % self.duration_s if self.duration_s > 0 else 0.0
        rest, close, hold, open_, _, _ = (start for _, start in self.phases())
        if t < close:
            flexion = 0.0
        elif t < hold:
            flexion = self.closure * _ease((t - close) / self.close_s)
        elif t < open_:
            flexion = self.closure
        else:
            flexion = self.closure * (1.0 - _ease((t - open_) / self.open_s))
        sweep = open_ + self.open_s + self.rest_s
        opposition = 0.0
        if self.sweep_s > 0 and t >= sweep:
            opposition = -math.sin(2.0 * math.pi * (t - sweep) / self.sweep_s)  # adducted, then opposed
        return Synergies(flexion, flexion, opposition)


def hand_pose(command: Synergies, calibration: OperatorCalibration, joints: JointGroups = DEFAULT_JOINTS
              ) -> dict[str, float]:
    """Joint angles (rad) of an operator whose every joint follows the command: the inverse of the
    calibration's normalisation."""
    angles = {}
    for group, flexion in ((joints.finger_flexion, command.fingers), (joints.thumb_flexion, command.thumb)):
        for j in group:
            angles[j] = calibration.open_hand[j] + flexion * (calibration.fist[j] - calibration.open_hand[j])
    for j in joints.thumb_opposition:
        end = calibration.thumb_opposed[j] if command.opposition >= 0 else calibration.thumb_adducted[j]
        angles[j] = calibration.open_hand[j] + abs(command.opposition) * (end - calibration.open_hand[j])
    return angles


class SyntheticGlove:
    """The scripted operator's joint angles at a time, with the glove's noise."""

    def __init__(self, script: OperatorScript = OperatorScript(), calibration: OperatorCalibration | None = None,
                 joints: JointGroups = DEFAULT_JOINTS, noise_rad: float = 0.005, seed: int = 0,
                 loop: bool = True) -> None:
        self.script, self.joints, self.loop = script, joints, loop
        self.calibration = calibration or nominal_calibration(joints)
        self.noise_rad = noise_rad
        self.rng = np.random.default_rng(seed)

    def sample(self, t_s: float) -> dict[str, float] | None:
        """The glove's joint angles at t_s from the start, or None once the script is over (loop off)."""
        if not self.loop and t_s >= self.script.duration_s:
            return None
        angles = hand_pose(self.script.synergies(t_s), self.calibration, self.joints)
        if self.noise_rad > 0:
            noise = self.rng.normal(0.0, self.noise_rad, len(angles))
            angles = {j: a + float(n) for (j, a), n in zip(angles.items(), noise)}
        return angles
