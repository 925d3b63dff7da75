"""Parameters of the motor_driver node: defaults (= config/motor_driver.yaml) and validation.

`from_parameters` raises ParameterError naming the parameter and the bad value, so a node with an
invalid parameter fails at start with that message.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from prisma_common.hand import MOTOR_NAMES
from prisma_common.parameters import ParameterError, Params, check_positive

from .backend import (
    DEFAULT_IDS,
    DEFAULT_MAX_POSITIONS,
    DEFAULT_MAX_VELOCITIES_RPM,
    DEFAULT_MIN_POSITIONS,
    MotorConfig,
    MotorMap,
)


@dataclass
class MotorDriverConfig(Params):
    backend: str = "sim"  # sim | dynamixel
    port: str = "/dev/ttyUSB0"
    baud: int = 1_000_000
    retries: int = 3  # per Dynamixel transaction, on timeout / corrupt status
    motor_names: list = field(default_factory=lambda: list(MOTOR_NAMES))
    motor_ids: list = field(default_factory=lambda: list(DEFAULT_IDS))
    min_positions: list = field(default_factory=lambda: list(DEFAULT_MIN_POSITIONS))  # rad
    max_positions: list = field(default_factory=lambda: list(DEFAULT_MAX_POSITIONS))  # rad
    max_velocities_rpm: list = field(default_factory=lambda: list(DEFAULT_MAX_VELOCITIES_RPM))
    directions: list = field(default_factory=lambda: [1, 1, 1])
    zero_ticks: list = field(default_factory=lambda: [0, 0, 0])
    rate_hz: float = 100.0  # /joint_states and goal supervision
    position_profile_rpm: float = 30.0  # position-mode goals move at this speed
    position_tolerance: float = 0.02  # rad: a position goal is reached within this
    diagnostics_period: float = 1.0
    reconnect_backoff_initial: float = 0.5  # s, doubled after each failed reopen
    reconnect_backoff_max: float = 8.0
    sim_initial_positions: list = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def validate(self) -> None:
        if self.backend not in ("sim", "dynamixel"):
            raise ParameterError("backend", self.backend, "must be 'sim' or 'dynamixel'")
        if not isinstance(self.baud, int) or self.baud <= 0:
            raise ParameterError("baud", self.baud, "must be a positive integer")
        if not isinstance(self.retries, int) or self.retries < 0:
            raise ParameterError("retries", self.retries, "must be an integer >= 0")
        for name in ("rate_hz", "position_profile_rpm", "position_tolerance", "diagnostics_period",
                     "reconnect_backoff_initial", "reconnect_backoff_max"):
            check_positive(name, getattr(self, name))
        for name in self.motor_names:
            if name not in MOTOR_NAMES:
                raise ParameterError("motor_names", self.motor_names, f"{name!r} is not one of {list(MOTOR_NAMES)}")
        n = len(self.motor_names)
        for name in ("motor_ids", "min_positions", "max_positions", "max_velocities_rpm", "directions",
                     "zero_ticks", "sim_initial_positions"):
            if len(getattr(self, name)) != n:
                raise ParameterError(name, getattr(self, name), f"needs one entry per motor ({n})")
        try:
            self.motors()
        except ValueError as exc:
            raise ParameterError("motor map", {"motor_ids": self.motor_ids, "min_positions": self.min_positions,
                                     "max_positions": self.max_positions}, str(exc)) from exc

    def motors(self) -> dict[str, MotorConfig]:
        return MotorMap.from_lists(list(self.motor_names), [int(i) for i in self.motor_ids],
                                   [float(v) for v in self.min_positions], [float(v) for v in self.max_positions],
                                   [float(v) for v in self.max_velocities_rpm], [int(d) for d in self.directions],
                                   [int(z) for z in self.zero_ticks]).motors
