"""Parameters of the motor_driver and manipulation nodes: defaults (= config/*.yaml) and validation.

`from_parameters` raises ParameterError naming the parameter and the bad value, so a node with an
invalid parameter fails at start with that message.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_common.parameters import ParameterError, Params, check_positive
from prisma_motor_driver.backend import (
    DEFAULT_MAX_POSITIONS,
    DEFAULT_MIN_POSITIONS,
    MotorConfig,
    MotorMap,
)

from .contact_monitor import DEFAULT_K, K_RANGE
from .gripper_controller import DEFAULT_THUMB_RATIO


@dataclass
class ManipulationConfig(Params):
    fingers: list = field(default_factory=lambda: list(FINGERS))
    frame_id_format: str = "prisma_{finger}_pad"
    k: float = DEFAULT_K  # Algorithm 1 threshold factor, changeable at run time
    min_mean_voltage: float = 0.55  # below it a pad is "not in contact" (feasible = false)
    monitored_finger: str = "thumb"  # the pad Manipulate goals steer by
    stale_timeout: float = 0.1  # s
    watchdog_period: float = 0.02  # s
    max_speed_rpm: float = 70.0  # goals asking more are rejected
    max_force_n: float = 3.0  # goals asking more are rejected
    hold_min_k: float = 0.6  # the hold needs K above this (docs/manipulation.md)
    # defaults for goal fields left at 0
    grasp_finger_force: float = 0.8
    grasp_thumb_force: float = 1.0
    grasp_speed_rpm: float = 60.0
    grasp_timeout: float = 10.0
    horizontal_speed_rpm: float = 20.0
    vertical_speed_rpm: float = 10.0
    hold_speed_rpm: float = 20.0
    manipulate_timeout: float = 30.0
    # GripperCommand (/prisma/gripper_cmd): position = fingers motor rad; docs/manipulation.md
    gripper_max_effort: float = 1.0  # N: the force limit of a goal whose max_effort is 0 (MoveIt's default)
    gripper_speed_rpm: float = 60.0  # fingers motor; thumb flexion at gripper_thumb_ratio x this
    gripper_thumb_ratio: float = DEFAULT_THUMB_RATIO  # thumb_flexion target per fingers rad
    gripper_timeout: float = 10.0
    # controller details
    contact_force_n: float = 0.1  # a pad "touches" above this (power grasp averaging)
    lateral_closure: float = 7.0  # rad of the fingers motor for the lateral grasp's fist
    force_target_n: float = 1.0  # use_force: thumb force the combined controller keeps
    force_band_n: float = 0.15  # ...restored when it drops more than this below the target
    force_speed_rpm: float = 20.0
    # the motor_driver's motors and limits (keep equal to config/motor_driver.yaml)
    motor_names: list = field(default_factory=lambda: list(MOTOR_NAMES))
    min_positions: list = field(default_factory=lambda: list(DEFAULT_MIN_POSITIONS))
    max_positions: list = field(default_factory=lambda: list(DEFAULT_MAX_POSITIONS))
    limit_margin: float = 0.02  # rad: a motor this close to its limit counts as at the limit
    move_action: str = "prisma/motors/move"  # relative: follows the node namespace

    def validate(self) -> None:
        for f in self.fingers:
            if f not in FINGERS:
                raise ParameterError("fingers", self.fingers, f"{f!r} is not one of {list(FINGERS)}")
        if self.monitored_finger not in self.fingers:
            raise ParameterError("monitored_finger", self.monitored_finger, f"must be one of fingers {self.fingers}")
        if not (isinstance(self.k, float) and K_RANGE[0] < self.k <= K_RANGE[1]):
            raise ParameterError("k", self.k, f"must be in ({K_RANGE[0]}, {K_RANGE[1]}]")
        if not 0 <= self.min_mean_voltage < 3.3:
            raise ParameterError("min_mean_voltage", self.min_mean_voltage, "must be in [0, 3.3) V")
        if "{finger}" not in self.frame_id_format:
            raise ParameterError("frame_id_format", self.frame_id_format, "must contain {finger}")
        for name in ("stale_timeout", "watchdog_period", "max_speed_rpm", "max_force_n", "grasp_finger_force",
                     "grasp_thumb_force", "grasp_speed_rpm", "grasp_timeout", "horizontal_speed_rpm",
                     "vertical_speed_rpm", "hold_speed_rpm", "manipulate_timeout", "gripper_max_effort",
                     "gripper_speed_rpm", "gripper_thumb_ratio", "gripper_timeout", "contact_force_n",
                     "lateral_closure", "force_target_n", "force_band_n", "force_speed_rpm", "limit_margin"):
            check_positive(name, getattr(self, name))
        if not 0 <= self.hold_min_k < K_RANGE[1]:
            raise ParameterError("hold_min_k", self.hold_min_k, f"must be in [0, {K_RANGE[1]})")
        for name in ("grasp_speed_rpm", "horizontal_speed_rpm", "vertical_speed_rpm", "hold_speed_rpm",
                     "force_speed_rpm", "gripper_speed_rpm"):
            if getattr(self, name) > self.max_speed_rpm:
                raise ParameterError(name, getattr(self, name), f"above max_speed_rpm {self.max_speed_rpm}")
        if self.gripper_thumb_ratio * self.gripper_speed_rpm > self.max_speed_rpm:
            raise ParameterError("gripper_thumb_ratio", self.gripper_thumb_ratio,
                                 f"the thumb would close at {self.gripper_thumb_ratio * self.gripper_speed_rpm:g} rpm, "
                                 f"above max_speed_rpm {self.max_speed_rpm}")
        for name in ("grasp_finger_force", "grasp_thumb_force", "force_target_n", "gripper_max_effort"):
            if getattr(self, name) > self.max_force_n:
                raise ParameterError(name, getattr(self, name), f"above max_force_n {self.max_force_n}")
        if self.force_band_n >= self.force_target_n:
            raise ParameterError("force_band_n", self.force_band_n,
                                 f"must be below force_target_n {self.force_target_n}")
        n = len(self.motor_names)
        if sorted(self.motor_names) != sorted(MOTOR_NAMES):
            raise ParameterError("motor_names", self.motor_names, f"must name {list(MOTOR_NAMES)}")
        for name in ("min_positions", "max_positions"):
            if len(getattr(self, name)) != n:
                raise ParameterError(name, getattr(self, name), f"needs one entry per motor ({n})")
        for name, lo, hi in zip(self.motor_names, self.min_positions, self.max_positions):
            if not lo < hi:
                raise ParameterError("min_positions/max_positions", [lo, hi], f"empty window for {name}")

    def limits_motors(self) -> dict[str, MotorConfig]:
        """MotorConfigs carrying only what the controllers use: the position windows."""
        return MotorMap.from_lists(list(self.motor_names), list(range(1, len(self.motor_names) + 1)),
                                   [float(v) for v in self.min_positions], [float(v) for v in self.max_positions],
                                   [self.max_speed_rpm] * len(self.motor_names)).motors
