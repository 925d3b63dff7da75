"""The fingers where they are under load: each motor angle less the stretch of its elastic tendon.

The description's finger joints follow the motors through rigid mimic couplings, but the tendons
stretch: once a pad presses on an object the motor turns on while the finger stays at the object.
A pad pressed with normal force F stretches its tendon by F / k (k = the tendon's stiffness
referred to the fingertip, HandWorldParams.tendon_stiffness_n_per_mm), which is F / (k t) rad of its
tendon motor (t = the pad's travel per motor rad, HandWorldParams.pad_travel_mm_per_rad). Every
joint the description couples to that motor on the finger's chain (spread and flexion) is drawn at
multiplier x (motor angle - stretch) + offset: the finger where the tendon has let it go.

The stretch never opens a finger past the motor's zero (the open hand): a tendon only pulls.
Inputs are the motor angles (/joint_states) and each pad's normal force (the force estimator's Fz);
the output is every moving joint of the description (motors as given, the coupled joints loaded),
the full joint state robot_state_publisher draws from.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from prisma_common.hand import FINGERS
from prisma_common.kinematics import RobotModel
from prisma_hand_sim.hand_world import TENDON_MOTOR, HandWorldParams


def pad_link(finger: str) -> str:
    return f"prisma_{finger}_pad"


@dataclass(frozen=True)
class Coupling:
    """A joint following a motor: position = multiplier x motor + offset."""

    joint: str
    motor: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class TendonStretch:
    stiffness_n_per_mm: float  # tendon, referred to the fingertip
    travel_mm_per_rad: Mapping[str, float]  # finger -> pad travel per rad of its tendon motor
    motors: Mapping[str, str]  # finger -> its tendon motor
    loaded: Mapping[str, tuple[Coupling, ...]]  # finger -> the joints its tendon motor moves on its chain
    rigid: tuple[Coupling, ...]  # the other coupled joints (thumb opposition): as the motors say

    @classmethod
    def from_model(cls, model: RobotModel, params: HandWorldParams | None = None) -> TendonStretch:
        """The couplings of `model` (the description robot_state_publisher draws), the stiffness and
        travel of `params` (the simulator's hand model, the shipped hand's numbers)."""
        params = params or HandWorldParams()
        loaded = {}
        for finger in FINGERS:
            motor = TENDON_MOTOR[finger]
            loaded[finger] = tuple(Coupling(j.name, motor, j.mimic.multiplier, j.mimic.offset)
                                   for j in model.chain(pad_link(finger))
                                   if j.mimic is not None and j.mimic.joint == motor)
        taken = {c.joint for couplings in loaded.values() for c in couplings}
        rigid = tuple(Coupling(j.name, j.mimic.joint, j.mimic.multiplier, j.mimic.offset)
                      for j in model.joints.values() if j.mimic is not None and j.name not in taken)
        return cls(params.tendon_stiffness_n_per_mm, {f: params.pad_travel_mm_per_rad(f) for f in FINGERS},
                   dict(TENDON_MOTOR), loaded, rigid)

    def stretch_rad(self, finger: str, force_n: float) -> float:
        """Stretch of `finger`'s tendon as an angle of its motor; 0 for a force that is not a
        positive number (no estimate, NaN, a pad pulled rather than pressed)."""
        if not math.isfinite(force_n) or force_n <= 0.0:
            return 0.0
        return force_n / self.stiffness_n_per_mm / self.travel_mm_per_rad[finger]

    def effective_angles(self, motors: Mapping[str, float], forces: Mapping[str, float]) -> dict[str, float]:
        """finger -> the angle of its tendon motor its joints are at: the motor's less the stretch,
        never past 0 (the open hand). Fingers whose motor is not in `motors` are left out."""
        out = {}
        for finger, motor in self.motors.items():
            if motor in motors:
                angle = motors[motor]
                out[finger] = max(angle - self.stretch_rad(finger, forces.get(finger, 0.0)), min(angle, 0.0))
        return out

    def joint_positions(self, motors: Mapping[str, float], forces: Mapping[str, float]) -> dict[str, float]:
        """Every joint position robot_state_publisher needs: the motors as given, each finger's
        coupled joints at its effective angle, the other coupled joints as their motors say."""
        positions = dict(motors)
        for finger, angle in self.effective_angles(motors, forces).items():
            for c in self.loaded[finger]:
                positions[c.joint] = c.multiplier * angle + c.offset
        for c in self.rigid:
            if c.motor in motors:
                positions[c.joint] = c.multiplier * motors[c.motor] + c.offset
        return positions


def forces_at(latest: Mapping[str, tuple[int, float]], stamp_ns: int, timeout_ns: int) -> dict[str, float]:
    """finger -> normal force for the joint sample at stamp_ns from the newest estimate of each pad
    (stamp, Fz): an estimate older than timeout_ns counts as none (its estimator has stopped or
    lost the pad; the finger is drawn as the motor says rather than held where it last was)."""
    return {finger: force for finger, (force_ns, force) in latest.items() if stamp_ns - force_ns <= timeout_ns}
