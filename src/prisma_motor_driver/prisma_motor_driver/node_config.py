"""Parameters of the motor_driver node: defaults (= config/motor_driver.yaml), their specs
(description, unit, bounds, live or read-only) and validation.

`from_parameters` raises ParameterError naming the parameter and the bad value, so a node with an
invalid parameter fails at start with that message. Live: the position-goal settings, which the
goal runner reads at each goal and tick; everything else (bus, motor map, limits, rates) is set up
at start.
"""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.hand import MOTOR_NAMES
from prisma_common.parameters import ParameterError, Params, backoff_initial, backoff_max, check_backoff, parameter

from .backend import (
    CURRENT_LIMIT_MAX_MA,
    DEFAULT_CURRENT_LIMITS_MA,
    DEFAULT_IDS,
    DEFAULT_MAX_POSITIONS,
    DEFAULT_MAX_VELOCITIES_RPM,
    DEFAULT_MIN_POSITIONS,
    MotorConfig,
    MotorMap,
)
from .control_table import VELOCITY_LIMIT_MAX_RPM, WATCHDOG_MAX_UNITS, WATCHDOG_UNIT_S

BACKENDS = ("sim", "dynamixel")
PER_MOTOR = "one entry per motor, in the order of motor_names"


@dataclass
class MotorDriverConfig(Params):
    backend: str = parameter("sim", "motor bus: dynamixel (X-series, Protocol 2.0) or sim (motor model)",
                             choices=BACKENDS)
    port: str = parameter("/dev/ttyUSB0", "serial port of the U2D2 / USB-RS485 adapter (backend dynamixel)")
    baud: int = parameter(1_000_000, "Dynamixel bus baud rate", unit="baud", bounds=(1, 4_500_000))
    retries: int = parameter(3, "extra attempts per Dynamixel transaction after a missing or corrupt status packet",
                             bounds=(0, 10))
    motor_names: list = parameter(list(MOTOR_NAMES), "the hand's motors, also the /joint_states names",
                                  rules=f"each of {', '.join(MOTOR_NAMES)} once")
    motor_ids: list = parameter(list(DEFAULT_IDS), "Dynamixel ID of each motor", rules=f"{PER_MOTOR}; distinct")
    min_positions: list = parameter(list(DEFAULT_MIN_POSITIONS), "lowest position of each motor from its zero",
                                    unit="rad", rules=PER_MOTOR)
    max_positions: list = parameter(list(DEFAULT_MAX_POSITIONS), "highest position of each motor from its zero",
                                    unit="rad", rules=f"{PER_MOTOR}; above min_positions")
    max_velocities_rpm: list = parameter(list(DEFAULT_MAX_VELOCITIES_RPM), "fastest velocity goal of each motor",
                                         unit="rpm", rules=PER_MOTOR)
    directions: list = parameter([1, 1, 1], "-1 where the servo's positive turn opens the joint, else 1",
                                 rules=PER_MOTOR)
    zero_ticks: list = parameter([0, 0, 0], "Present Position (ticks) that means 0 rad (hand open, thumb centred)",
                                 rules=PER_MOTOR)
    current_limits_ma: list = parameter(list(DEFAULT_CURRENT_LIMITS_MA),
                                        "Current Limit written to each servo at start: the hardest any command "
                                        "pulls its tendon", unit="mA", rules=f"{PER_MOTOR}; 0 < limit <= "
                                        f"{CURRENT_LIMIT_MAX_MA:.0f}")
    # 10 driver cycles at 100 Hz: a busy host's pauses (10-25 ms garbage collections) never trip it,
    # and a dead or frozen driver leaves the motors turning 0.1 s at most (0.7 rad at 70 rpm)
    bus_watchdog: float = parameter(0.1, "Bus Watchdog of every servo: it stops itself when no instruction "
                                    "reaches it for this long (a driver that died or froze, a cut bus); "
                                    "rounded up to 20 ms steps", unit="s",
                                    bounds=(WATCHDOG_UNIT_S, WATCHDOG_MAX_UNITS * WATCHDOG_UNIT_S))
    homing_rpm: float = parameter(15.0, "speed of the motors toward their open end stops while homing", unit="rpm",
                                  bounds=(0.0, 60.0), open_low=True)
    homing_current_ma: float = parameter(150.0, "the most a motor pulls while homing (Goal Current): enough to "
                                         "turn the open hand, far below a tendon's load", unit="mA",
                                         bounds=(0.0, CURRENT_LIMIT_MAX_MA), open_low=True)
    homing_timeout: float = parameter(20.0, "a motor that finds no end stop within this long fails homing",
                                      unit="s", bounds=(0.0, 300.0), open_low=True)
    home_at_start: bool = parameter(False, "home the motors as soon as the bus is open (launch: home:=true)")
    hand_config: str = parameter("", "this hand's directory (launch: hand_config:=): the zeros homing finds are "
                                 "saved there and loaded at start; '' = none (home after every start)")
    rate_hz: float = parameter(100.0, "/joint_states and goal supervision rate", unit="Hz", bounds=(0.0, 1000.0),
                               open_low=True)
    position_profile_rpm: float = parameter(30.0, "speed of position-mode MoveMotors goals (from the next goal)",
                                            unit="rpm", bounds=(0.0, VELOCITY_LIMIT_MAX_RPM), open_low=True,
                                            live=True)
    position_tolerance: float = parameter(0.02, "a position goal is reached within this of its targets",
                                          unit="rad", bounds=(0.0, 1.0), open_low=True, live=True)
    diagnostics_period: float = parameter(1.0, "time between /diagnostics messages", unit="s",
                                          bounds=(0.0, 60.0), open_low=True)
    reconnect_backoff_initial: float = backoff_initial(0.5, "bus")
    reconnect_backoff_max: float = backoff_max(8.0)
    sim_initial_positions: list = parameter([0.0, 0.0, 0.0], "start positions of the simulated motors (backend sim)",
                                            unit="rad", rules=PER_MOTOR)

    def check_rules(self) -> None:
        check_backoff(self.reconnect_backoff_initial, self.reconnect_backoff_max)
        for name in self.motor_names:
            if name not in MOTOR_NAMES:
                raise ParameterError("motor_names", self.motor_names, f"{name!r} is not one of {list(MOTOR_NAMES)}")
        n = len(self.motor_names)
        for name in ("motor_ids", "min_positions", "max_positions", "max_velocities_rpm", "directions",
                     "zero_ticks", "current_limits_ma", "sim_initial_positions"):
            if len(getattr(self, name)) != n:
                raise ParameterError(name, getattr(self, name), f"needs one entry per motor ({n})")
        if self.homing_current_ma > min(float(v) for v in self.current_limits_ma):
            raise ParameterError("homing_current_ma", self.homing_current_ma,
                                 f"above a motor's current limit (current_limits_ma {self.current_limits_ma})")
        try:
            self.motors()
        except ValueError as exc:
            raise ParameterError("motor map", {"motor_ids": self.motor_ids, "min_positions": self.min_positions,
                                     "max_positions": self.max_positions}, str(exc)) from exc

    def motors(self, zeros: dict[str, int] | None = None) -> dict[str, MotorConfig]:
        """The motor map; `zeros` (from the hand's directory) replace zero_ticks where given."""
        zero_ticks = [int((zeros or {}).get(name, z)) for name, z in zip(self.motor_names, self.zero_ticks)]
        return MotorMap.from_lists(list(self.motor_names), [int(i) for i in self.motor_ids],
                                   [float(v) for v in self.min_positions], [float(v) for v in self.max_positions],
                                   [float(v) for v in self.max_velocities_rpm], [int(d) for d in self.directions],
                                   zero_ticks, [float(v) for v in self.current_limits_ma]).motors
