"""The motor bus: what every backend (Dynamixel, sim) offers the motor driver and the controllers.

Motors are named (`MOTOR_NAMES`, also the /joint_states names); positions are motor-shaft angles in
rad from the configured zero, velocities in rpm, currents in mA.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from prisma_common.hand import MOTOR_NAMES

from .control_table import CURRENT_LIMIT_MAX_UNITS, current_units_to_ma, describe_hardware_error

CURRENT_LIMIT_MAX_MA = current_units_to_ma(CURRENT_LIMIT_MAX_UNITS)

# The hand's motor map (same values as config/motor_driver.yaml), in MOTOR_NAMES order.
DEFAULT_IDS = (1, 2, 3)
DEFAULT_MIN_POSITIONS = (0.0, 0.0, -3.0)  # rad
DEFAULT_MAX_POSITIONS = (9.0, 7.0, 3.0)  # rad
DEFAULT_MAX_VELOCITIES_RPM = (70.0, 70.0, 70.0)
# Current Limit of each servo: the hardest any command may pull a tendon (about half an XM430-W350's
# stall current: a grasp's tendon loads stay well below it)
DEFAULT_CURRENT_LIMITS_MA = (1200.0, 1200.0, 1200.0)


@dataclass(frozen=True)
class MotorConfig:
    name: str
    servo_id: int
    min_position_rad: float
    max_position_rad: float
    max_velocity_rpm: float
    direction: int = 1  # -1 when the servo is mounted so that its positive turn opens the joint
    zero_ticks: int = 0  # Present Position that means 0 rad
    current_limit_ma: float = DEFAULT_CURRENT_LIMITS_MA[0]  # the servo's Current Limit

    def __post_init__(self) -> None:
        if self.name not in MOTOR_NAMES:
            raise ValueError(f"motor name {self.name!r} is not one of {MOTOR_NAMES}")
        if not 0 <= self.servo_id <= 252:
            raise ValueError(f"motor {self.name}: servo id {self.servo_id} outside 0..252")
        if not self.min_position_rad < self.max_position_rad:
            raise ValueError(
                f"motor {self.name}: position limits [{self.min_position_rad}, {self.max_position_rad}] are empty"
            )
        if not self.max_velocity_rpm > 0:
            raise ValueError(f"motor {self.name}: max_velocity_rpm {self.max_velocity_rpm} must be > 0")
        if self.direction not in (1, -1):
            raise ValueError(f"motor {self.name}: direction {self.direction} must be 1 or -1")
        if not 0 < self.current_limit_ma <= CURRENT_LIMIT_MAX_MA:
            raise ValueError(f"motor {self.name}: current limit {self.current_limit_ma} mA outside "
                             f"(0, {CURRENT_LIMIT_MAX_MA:.0f}] mA")

    def clamp(self, position_rad: float) -> float:
        return min(self.max_position_rad, max(self.min_position_rad, position_rad))


@dataclass
class MotorState:
    name: str
    position_rad: float
    velocity_rpm: float
    current_ma: float
    torque_on: bool = True
    hardware_error: int = 0  # Hardware Error Status bits (0 = healthy)
    watchdog_fired: bool = False  # the servo's Bus Watchdog stopped it (no instruction in its period)
    servo_reset: bool = False  # the servo powered up again while the bus was open: RAM and turn count lost


@dataclass
class BusStats:
    """Counters published on /diagnostics."""

    reads: int = 0
    writes: int = 0
    retries: int = 0
    dropped_status: int = 0  # no status packet in time (retried)
    corrupt_status: int = 0  # status packet with a bad CRC or header (retried)
    comm_failures: int = 0  # retries exhausted
    hardware_errors: int = 0
    mode_changes: int = 0


class BusError(RuntimeError):
    """Communication failed after the bounded retries; the message names the operation and motor."""


def fault_reason(name: str, servo_id: int, status: int) -> str:
    """The abort reason of a goal: names the motor, its ID and every set error bit."""
    return f"motor_fault: {name} (id {servo_id}) hardware error {describe_hardware_error(status)}"


@dataclass
class ServoInfo:
    """What the bus found out about one servo when it opened it (diagnostics, prisma-doctor)."""

    model: int = 0
    firmware: int = 0
    operating_mode: str = ""
    watchdog_ms: float = 0.0  # the armed Bus Watchdog period, 0 = off
    current_limit_ma: float = 0.0


class MotorBus(Protocol):
    motors: dict[str, MotorConfig]
    stats: BusStats
    # motors whose zero is known since their servo powered up (the sim's motors always know theirs)
    homed: dict[str, bool]
    needs_homing: bool  # False where the zero can never be lost (the sim)
    servo_info: dict[str, ServoInfo]

    def open(self) -> None: ...

    def close(self) -> None:
        """Torque off on every motor, then release the port."""

    def read_state(self, stamp_ns: int) -> dict[str, MotorState]: ...

    def set_velocities(self, rpm: Mapping[str, float]) -> None:
        """Velocity mode for the named motors (others keep their goals)."""

    def set_positions(self, rad: Mapping[str, float], profile_rpm: float) -> None:
        """Position mode: go to the named positions at profile_rpm."""

    def stop(self, names: list[str] | None = None) -> None:
        """Zero velocity (velocity mode) or hold the present position (position mode)."""

    def torque_off(self, name: str) -> None: ...

    def torque_on(self, name: str) -> None:
        """Velocity mode, goal 0, torque on: the motor as open() leaves it (after its error cleared)."""

    def rearm_watchdog(self, names: list[str]) -> None:
        """Clear a fired Bus Watchdog and arm it again, the motors stopped (velocity 0)."""

    def start_homing(self, names: list[str], rpm: float, current_ma: float) -> None:
        """Turn the motors toward their open end (minimum position) at `rpm`, pulling at most
        `current_ma`, until told otherwise."""

    def finish_homing(self, name: str) -> int:
        """The motor stands at its open end stop: its zero is set there (its minimum position is the
        stop), it is marked homed and stopped (velocity mode, goal 0). Returns the zero (ticks)."""

    def abort_homing(self, names: list[str]) -> None:
        """Stop homing motors where they are (velocity mode, goal 0), not homed."""


def check_velocity(config: MotorConfig, rpm: float) -> float:
    if not math.isfinite(rpm):
        raise ValueError(f"motor {config.name}: velocity {rpm} rpm is not finite")
    if abs(rpm) > config.max_velocity_rpm + 1e-9:
        raise ValueError(f"motor {config.name}: velocity {rpm} rpm above the limit {config.max_velocity_rpm} rpm")
    return rpm


@dataclass
class MotorMap:
    """Configured motors by name; built from the motor_driver parameters."""

    motors: dict[str, MotorConfig] = field(default_factory=dict)

    @classmethod
    def from_lists(
        cls,
        names: list[str],
        ids: list[int],
        min_positions: list[float],
        max_positions: list[float],
        max_velocities: list[float],
        directions: list[int] | None = None,
        zero_ticks: list[int] | None = None,
        current_limits_ma: list[float] | None = None,
    ) -> MotorMap:
        n = len(names)
        for label, values in (("motor_ids", ids), ("min_positions", min_positions),
                              ("max_positions", max_positions), ("max_velocities_rpm", max_velocities)):
            if len(values) != n:
                raise ValueError(f"{label} has {len(values)} entries for {n} motors {names}")
        if len(set(ids)) != n:
            raise ValueError(f"motor_ids {ids} are not unique")
        directions = directions or [1] * n
        zero_ticks = zero_ticks or [0] * n
        current_limits_ma = current_limits_ma or [DEFAULT_CURRENT_LIMITS_MA[0]] * n
        return cls({
            name: MotorConfig(name, int(ids[i]), float(min_positions[i]), float(max_positions[i]),
                              float(max_velocities[i]), int(directions[i]), int(zero_ticks[i]),
                              float(current_limits_ma[i]))
            for i, name in enumerate(names)
        })


def default_motors() -> dict[str, MotorConfig]:
    return MotorMap.from_lists(list(MOTOR_NAMES), list(DEFAULT_IDS), list(DEFAULT_MIN_POSITIONS),
                               list(DEFAULT_MAX_POSITIONS), list(DEFAULT_MAX_VELOCITIES_RPM)).motors
