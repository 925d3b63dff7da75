"""Dynamixel X-series control table (Protocol 2.0) and unit conversions.

Addresses and units from the X-series e-manual (docs/protocols.md). The motor bus, the emulator and
the tests all take their numbers from here so the three can never disagree.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

# EEPROM area (writable only while torque is off).
ADDR_MODEL_NUMBER = 0  # 2 B
ADDR_FIRMWARE_VERSION = 6  # 1 B
ADDR_ID = 7  # 1 B
ADDR_BAUD_RATE = 8  # 1 B
ADDR_OPERATING_MODE = 11  # 1 B
ADDR_HOMING_OFFSET = 20  # 4 B, signed
ADDR_PWM_LIMIT = 36  # 2 B
ADDR_CURRENT_LIMIT = 38  # 2 B: caps Goal Current and the current every mode may draw
ADDR_VELOCITY_LIMIT = 44  # 4 B
ADDR_MAX_POSITION_LIMIT = 48  # 4 B
ADDR_MIN_POSITION_LIMIT = 52  # 4 B
EEPROM_END = 64  # first RAM address

# RAM area.
ADDR_TORQUE_ENABLE = 64  # 1 B
ADDR_LED = 65  # 1 B, off at power-up: the driver lights it on a servo it has homed (a power-up marker)
ADDR_HARDWARE_ERROR_STATUS = 70  # 1 B
ADDR_BUS_WATCHDOG = 98  # 1 B, signed: 0 off (writing 0 clears its error), 1..127 x 20 ms, -1 fired
ADDR_GOAL_PWM = 100  # 2 B
ADDR_GOAL_CURRENT = 102  # 2 B
ADDR_GOAL_VELOCITY = 104  # 4 B
ADDR_PROFILE_VELOCITY = 112  # 4 B
ADDR_GOAL_POSITION = 116  # 4 B
ADDR_MOVING = 122  # 1 B
ADDR_PRESENT_CURRENT = 126  # 2 B, signed
ADDR_PRESENT_VELOCITY = 128  # 4 B, signed
ADDR_PRESENT_POSITION = 132  # 4 B, signed
ADDR_PRESENT_TEMPERATURE = 146  # 1 B

# One GroupSyncRead covers current, velocity and position: 126..135.
STATE_START = ADDR_PRESENT_CURRENT
STATE_LENGTH = ADDR_PRESENT_POSITION + 4 - ADDR_PRESENT_CURRENT  # 10 bytes

CONTROL_TABLE_SIZE = 662  # X-series tables end at 661 (indirect data)

# Operating modes.
MODE_CURRENT = 0
MODE_VELOCITY = 1
MODE_POSITION = 3
MODE_EXTENDED_POSITION = 4  # multi-turn: tendon spools turn more than once
MODE_CURRENT_BASED_POSITION = 5  # multi-turn, and Goal Current caps the pull: homing runs in it
MODE_PWM = 16
MODE_NAMES = {MODE_CURRENT: "current", MODE_VELOCITY: "velocity", MODE_POSITION: "position",
              MODE_EXTENDED_POSITION: "extended_position", MODE_CURRENT_BASED_POSITION: "current_based_position",
              MODE_PWM: "pwm"}

# Bus Watchdog (98): 1..127 in 20 ms units; -1 (0xFF) once it fired. While it reads -1 every goal
# register (Goal PWM, Goal Current, Goal Velocity, Goal Position) is read-only: a write gets the Data
# Range error, until Bus Watchdog is written 0. Available from firmware v38.
WATCHDOG_UNIT_S = 0.020
WATCHDOG_MAX_UNITS = 127
WATCHDOG_FIRED = -1
WATCHDOG_MIN_FIRMWARE = 38
GOAL_REGISTERS = ((ADDR_GOAL_PWM, 2), (ADDR_GOAL_CURRENT, 2), (ADDR_GOAL_VELOCITY, 4), (ADDR_GOAL_POSITION, 4))
CURRENT_LIMIT_MAX_UNITS = 1193  # XM430-W350: Current Limit range 0..1193 (3.2 A)
# Baud Rate (8) register values and the rates they select
BAUD_RATES = {0: 9600, 1: 57600, 2: 115200, 3: 1_000_000, 4: 2_000_000, 5: 3_000_000, 6: 4_000_000,
              7: 4_500_000}

# Units.
RPM_PER_VELOCITY_UNIT = 0.229
TICKS_PER_REV = 4096
MA_PER_CURRENT_UNIT = 2.69  # XM430 series
VELOCITY_LIMIT_MAX = 1023  # units (234 rpm): the top of the Velocity Limit range
# the fastest speed a parameter may name, in whole rpm (1023 x 0.229 = 234.27)
VELOCITY_LIMIT_MAX_RPM = float(math.floor(VELOCITY_LIMIT_MAX * RPM_PER_VELOCITY_UNIT))
MODEL_XM430_W350 = 1020

# Hardware Error Status bits (address 70).
HARDWARE_ERROR_BITS = {
    0: "input_voltage",
    2: "overheating",
    3: "motor_encoder",
    4: "electrical_shock",
    5: "overload",
}
# Bit 7 of the error byte of every status packet: "check Hardware Error Status".
STATUS_ALERT_BIT = 0x80


def rpm_to_units(rpm: float) -> int:
    """Goal Velocity units (signed), rounded to the nearest unit."""
    return int(round(rpm / RPM_PER_VELOCITY_UNIT))


def units_to_rpm(units: int) -> float:
    return units * RPM_PER_VELOCITY_UNIT


def rad_to_ticks(rad: float) -> int:
    return int(round(rad * TICKS_PER_REV / (2.0 * math.pi)))


def ticks_to_rad(ticks: float) -> float:  # the emulator's continuous positions too
    return ticks * 2.0 * math.pi / TICKS_PER_REV


def rpm_to_rad_s(rpm: float) -> float:
    return rpm * 2.0 * math.pi / 60.0


def rad_s_to_rpm(rad_s: float) -> float:
    return rad_s * 60.0 / (2.0 * math.pi)


def current_units_to_ma(units: int) -> float:
    return units * MA_PER_CURRENT_UNIT


def ma_to_current_units(ma: float) -> int:
    """Current units (Goal Current, Current Limit), rounded down: a limit never rounds up."""
    return int(math.floor(ma / MA_PER_CURRENT_UNIT))


def watchdog_units(period_s: float) -> int:
    """Bus Watchdog value for a period (rounded up to the next 20 ms, at least one unit)."""
    units = math.ceil(round(period_s / WATCHDOG_UNIT_S, 6))
    if not 1 <= units <= WATCHDOG_MAX_UNITS:
        raise ValueError(f"bus watchdog period {period_s} s outside {WATCHDOG_UNIT_S:g}.."
                         f"{WATCHDOG_MAX_UNITS * WATCHDOG_UNIT_S:g} s")
    return units


def to_signed(value: int, n_bytes: int) -> int:
    """Two's complement of an unsigned register value."""
    bits = 8 * n_bytes
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >= 1 << (bits - 1) else value


def to_unsigned(value: int, n_bytes: int) -> int:
    return value & ((1 << (8 * n_bytes)) - 1)


def decode_hardware_error(status: int) -> list[str]:
    """Names of the set bits of Hardware Error Status, e.g. ['overload'] for 0x20."""
    names = [name for bit, name in HARDWARE_ERROR_BITS.items() if status & (1 << bit)]
    unknown = [f"bit{bit}" for bit in range(8) if status & (1 << bit) and bit not in HARDWARE_ERROR_BITS]
    return names + unknown


def describe_hardware_error(status: int) -> str:
    """'bit 5 overload' style text for every set bit (the goal abort reason quotes it)."""
    parts = []
    for bit in range(8):
        if status & (1 << bit):
            parts.append(f"bit {bit} {HARDWARE_ERROR_BITS.get(bit, 'unknown')}")
    return ", ".join(parts)


@dataclass(frozen=True)
class PresentState:
    """Decoded 126..135 block of one servo."""

    current_units: int
    velocity_units: int
    position_ticks: int

    @classmethod
    def from_bytes(cls, block: bytes | list[int]) -> PresentState:
        b = bytes(block)
        if len(b) != STATE_LENGTH:
            raise ValueError(f"present-state block must be {STATE_LENGTH} bytes, got {len(b)}")
        return cls(
            current_units=int.from_bytes(b[0:2], "little", signed=True),
            velocity_units=int.from_bytes(b[2:6], "little", signed=True),
            position_ticks=int.from_bytes(b[6:10], "little", signed=True),
        )
