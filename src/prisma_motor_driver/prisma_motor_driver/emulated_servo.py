"""One emulated Dynamixel X-series servo: its control table and what the e-Manual (XM430-W350) says
the servo does with it. `DynamixelEmulator` puts servos on a bus behind a pty and hands them packets.

- Motion, integrated lazily (the emulator calls `integrate` on every packet and when asked): velocity
  mode integrates Goal Velocity; position, extended position and current-based position modes move
  toward Goal Position at Profile Velocity (0 = Velocity Limit). Moving (122) is 1 while it moves.
- Positions: the MECHANICAL position (`mechanical_ticks`, the spool's real angle, continuous) and
  the REPORTED one (Present Position) differ by the multi-turn count lost at power-up: Present
  Position = mechanical - turn_offset + Homing Offset (20), where a power-up puts the turn count so
  that Present Position comes up within one turn (0..4095) plus Homing Offset. Goal Position is in
  reported coordinates.
- Power-up (`power_up`): RAM to its power-up values (Torque Enable 0, LED 0, Bus Watchdog 0, goals 0,
  Profile Velocity 0, Hardware Error Status 0), EEPROM kept (ID, Baud Rate, Operating Mode, limits,
  Homing Offset, Current Limit).
- Writes (`write`): EEPROM writes while torque is on get the Access error; Present values are
  read-only. Current Limit (38, default CURRENT_LIMIT_MAX_UNITS, above it: Data Range error): Present
  Current never exceeds it in any mode; Goal Current beyond +-Current Limit gets the Data Limit
  error, and Goal Velocity beyond +-Velocity Limit too (the e-Manual's ranges for both). In
  current-based position mode the pull is min(|Goal Current|, Current Limit).
- Bus Watchdog (98): with Torque Enable 1 and a value 1..127 (x 20 ms), a gap between two
  instruction packets the servo takes part in longer than the period stops the servo at that exact
  instant (`watchdog_deadline`, `fire_watchdog`): velocity mode stops, position modes hold where they
  were. Bus Watchdog then reads -1 and every goal register (GOAL_REGISTERS) refuses writes with the
  Data Range error; writing 0 clears it (writing 1..127 while it reads -1 is refused: clear first),
  and the servo moves again only for a goal written after that. Values outside -1..127 get the Data
  Range error.
- Mechanical end stops (`end_stops`, mechanical ticks): motion never passes them; pushing into one
  gives Present Velocity 0 and the stall current, the pull the mode allows. The servo keeps its peak
  |Present Current| and when it was reached; `integrate` returns a line when it stalls.
- Baud Rate (8) and LED (65): plain storage (the emulator routes by the rate).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from . import control_table as ct
from .dynamixel_packets import ERR_ACCESS, ERR_DATA_LIMIT, ERR_DATA_RANGE

FIRMWARE_VERSION = 46
POSITION_MODES = (ct.MODE_POSITION, ct.MODE_EXTENDED_POSITION, ct.MODE_CURRENT_BASED_POSITION)


@dataclass(frozen=True)
class WatchdogFiring:
    """One Bus Watchdog stop: the instant (clock seconds) and where the servo stopped."""

    servo_id: int
    at_s: float
    position_ticks: float  # reported (Present Position)
    mechanical_ticks: float


@dataclass
class EmulatedServo:
    servo_id: int
    table: bytearray = field(default_factory=lambda: bytearray(ct.CONTROL_TABLE_SIZE))
    mechanical_ticks: float = 0.0  # the spool's real angle, continuous; never reset
    turn_offset: int = 0  # the multi-turn count lost at the last power-up (a multiple of 4096)
    end_stops: tuple[float | None, float | None] = (None, None)  # mechanical ticks, lo and hi
    load_current_units: int = 0  # added to Present Current while torque is on
    drop_status: int = 0
    silent: bool = False  # processes nothing and answers nothing: a servo off the bus
    instructions: int = 0
    last_instruction_s: float = 0.0  # the Bus Watchdog measures from here
    halted: bool = False  # stopped by the Bus Watchdog; a goal written after clearing releases it
    hold_ticks: float = 0.0  # mechanical position held while halted (position modes)
    stalled: bool = False
    peak_current_units: int = 0  # |Present Current|
    peak_current_at_s: float | None = None

    def __post_init__(self) -> None:
        self.write_int(ct.ADDR_MODEL_NUMBER, 2, ct.MODEL_XM430_W350)
        self.write_int(ct.ADDR_FIRMWARE_VERSION, 1, FIRMWARE_VERSION)
        self.write_int(ct.ADDR_ID, 1, self.servo_id)
        self.write_int(ct.ADDR_BAUD_RATE, 1, 3)  # 1 Mbps
        self.write_int(ct.ADDR_OPERATING_MODE, 1, ct.MODE_VELOCITY)
        self.write_int(ct.ADDR_CURRENT_LIMIT, 2, ct.CURRENT_LIMIT_MAX_UNITS)
        self.write_int(ct.ADDR_VELOCITY_LIMIT, 4, ct.VELOCITY_LIMIT_MAX)
        self.write_int(ct.ADDR_MAX_POSITION_LIMIT, 4, 4095)
        self.write_int(ct.ADDR_MIN_POSITION_LIMIT, 4, 0)
        self.power_up(0.0)

    def read_int(self, address: int, n: int, signed: bool = False) -> int:
        return int.from_bytes(self.table[address : address + n], "little", signed=signed)

    def write_int(self, address: int, n: int, value: int) -> None:
        self.table[address : address + n] = ct.to_unsigned(value, n).to_bytes(n, "little")

    @property
    def torque_on(self) -> bool:
        return bool(self.table[ct.ADDR_TORQUE_ENABLE])

    @property
    def hardware_error(self) -> int:
        return self.table[ct.ADDR_HARDWARE_ERROR_STATUS]

    @property
    def bus_watchdog(self) -> int:
        return self.read_int(ct.ADDR_BUS_WATCHDOG, 1, signed=True)

    @property
    def current_limit_units(self) -> int:
        return self.read_int(ct.ADDR_CURRENT_LIMIT, 2)

    @property
    def baud_rate(self) -> int:
        return ct.BAUD_RATES.get(self.table[ct.ADDR_BAUD_RATE], 0)

    @property
    def _reported_offset(self) -> int:
        """reported - mechanical."""
        return self.read_int(ct.ADDR_HOMING_OFFSET, 4, signed=True) - self.turn_offset

    @property
    def position_ticks(self) -> float:
        """The REPORTED position, continuous (Present Position is its rounding)."""
        return self.mechanical_ticks + self._reported_offset

    def set_position_ticks(self, ticks: float) -> None:
        """Put the REPORTED position at `ticks` (the mechanical one moves with it, the turn count
        stays): a test's shortcut. Not clamped to the end stops."""
        self.mechanical_ticks = float(ticks) - self._reported_offset
        self.integrate(0.0, self.last_instruction_s)

    def power_up(self, now_s: float) -> None:
        """RAM to its power-up values, EEPROM kept; Present Position within one turn + Homing Offset."""
        eeprom = bytes(self.table[: ct.EEPROM_END])
        self.table[:] = bytes(ct.CONTROL_TABLE_SIZE)
        self.table[: ct.EEPROM_END] = eeprom
        self.write_int(ct.ADDR_PRESENT_TEMPERATURE, 1, 31)
        self.turn_offset = math.floor(round(self.mechanical_ticks) / ct.TICKS_PER_REV) * ct.TICKS_PER_REV
        self.halted = self.stalled = False
        self.last_instruction_s = now_s
        self.integrate(0.0, now_s)

    def watchdog_deadline(self) -> float | None:
        """When the Bus Watchdog fires if no instruction comes, or None (off, fired, torque off)."""
        units = self.bus_watchdog
        if units <= 0 or not self.torque_on:
            return None
        return self.last_instruction_s + units * ct.WATCHDOG_UNIT_S

    def fire_watchdog(self, at_s: float) -> WatchdogFiring:
        self.write_int(ct.ADDR_BUS_WATCHDOG, 1, ct.WATCHDOG_FIRED)
        self.halted, self.hold_ticks = True, self.mechanical_ticks
        self.integrate(0.0, at_s)
        return WatchdogFiring(self.servo_id, at_s, self.position_ticks, self.mechanical_ticks)

    def eeprom_locked(self, address: int, length: int) -> bool:
        """A write there is refused with the Access error because it reaches EEPROM with torque on."""
        return address + length <= ct.CONTROL_TABLE_SIZE and address < ct.EEPROM_END and self.torque_on

    def write(self, address: int, data: bytes) -> int:
        """A write instruction: validated against the table as it would be after it, applied whole or
        not at all. Returns the status packet's error (0: written)."""
        n = len(data)
        if address + n > ct.CONTROL_TABLE_SIZE or self.eeprom_locked(address, n):
            return ERR_ACCESS
        if address < ct.ADDR_ID or _overlaps(address, n, ct.ADDR_MOVING, 1) \
                or _overlaps(address, n, ct.ADDR_PRESENT_CURRENT, ct.STATE_LENGTH):
            return ERR_ACCESS  # read-only: model number, firmware version, Moving, the Present values
        after = bytearray(self.table)
        after[address : address + n] = data
        writes_goal = any(_overlaps(address, n, reg, size) for reg, size in ct.GOAL_REGISTERS)
        if writes_goal and self.bus_watchdog == ct.WATCHDOG_FIRED:
            return ERR_DATA_RANGE  # goals are read-only until Bus Watchdog is written 0
        if _overlaps(address, n, ct.ADDR_BUS_WATCHDOG, 1):
            value = _int(after, ct.ADDR_BUS_WATCHDOG, 1, signed=True)
            if not 0 <= value <= ct.WATCHDOG_MAX_UNITS or (value and self.bus_watchdog == ct.WATCHDOG_FIRED):
                return ERR_DATA_RANGE
        if _overlaps(address, n, ct.ADDR_CURRENT_LIMIT, 2) \
                and _int(after, ct.ADDR_CURRENT_LIMIT, 2) > ct.CURRENT_LIMIT_MAX_UNITS:
            return ERR_DATA_RANGE
        if _overlaps(address, n, ct.ADDR_GOAL_CURRENT, 2) and abs(
                _int(after, ct.ADDR_GOAL_CURRENT, 2, signed=True)) > _int(after, ct.ADDR_CURRENT_LIMIT, 2):
            return ERR_DATA_LIMIT
        if _overlaps(address, n, ct.ADDR_GOAL_VELOCITY, 4) and abs(
                _int(after, ct.ADDR_GOAL_VELOCITY, 4, signed=True)) > _int(after, ct.ADDR_VELOCITY_LIMIT, 4):
            return ERR_DATA_LIMIT
        self.table[:] = after
        if writes_goal:
            self.halted = False  # a new goal after the watchdog was cleared: it moves again
        return 0

    def _pull_units(self, mode: int) -> int:
        """The most current the mode lets the motor draw."""
        limit = self.current_limit_units
        if mode == ct.MODE_CURRENT_BASED_POSITION:
            return min(abs(self.read_int(ct.ADDR_GOAL_CURRENT, 2, signed=True)), limit)
        return limit

    def integrate(self, dt_s: float, now_s: float) -> str | None:
        """Advance the motion by dt_s (>= 0) under the current goals (ideal tracking) and publish the
        Present values at now_s. Returns a log line when the servo has just stalled at an end stop."""
        velocity_units, push = 0, 0  # push: the direction the motor drives in (+1, -1, 0)
        mode = self.table[ct.ADDR_OPERATING_MODE]
        limit = self.read_int(ct.ADDR_VELOCITY_LIMIT, 4)
        if self.torque_on:
            if mode == ct.MODE_VELOCITY:
                goal = 0 if self.halted else self.read_int(ct.ADDR_GOAL_VELOCITY, 4, signed=True)
                velocity_units = max(-limit, min(limit, goal))
                push = (velocity_units > 0) - (velocity_units < 0)
                self.mechanical_ticks += _ticks_per_s(velocity_units) * dt_s
            elif mode in POSITION_MODES:
                profile = self.read_int(ct.ADDR_PROFILE_VELOCITY, 4) or limit
                target = self.hold_ticks if self.halted else (
                    self.read_int(ct.ADDR_GOAL_POSITION, 4, signed=True) - self._reported_offset)
                step = _ticks_per_s(profile) * dt_s
                error = target - self.mechanical_ticks
                push = (error > 0) - (error < 0)
                if abs(error) <= step:
                    self.mechanical_ticks = float(target)
                else:
                    self.mechanical_ticks += step * push
                    velocity_units = profile * push
        lo, hi = self.end_stops
        at_stop = None
        if lo is not None and self.mechanical_ticks <= lo:
            self.mechanical_ticks, at_stop = float(lo), ("lo", -1)
        if hi is not None and self.mechanical_ticks >= hi:
            self.mechanical_ticks, at_stop = float(hi), ("hi", 1)
        pull = self._pull_units(mode)
        stalled = self.torque_on and at_stop is not None and push == at_stop[1]
        if stalled:
            velocity_units, current = 0, pull * push
        elif self.torque_on:
            # moving costs current too: a small speed term keeps the reading plausible
            current = self.load_current_units + int(abs(velocity_units) * 0.5)
            current = max(-pull, min(pull, current))
        else:
            current = 0
        self.write_int(ct.ADDR_PRESENT_POSITION, 4, int(round(self.position_ticks)))
        self.write_int(ct.ADDR_PRESENT_VELOCITY, 4, velocity_units)
        self.write_int(ct.ADDR_PRESENT_CURRENT, 2, current)
        self.write_int(ct.ADDR_MOVING, 1, int(velocity_units != 0))
        if abs(current) > self.peak_current_units:
            self.peak_current_units, self.peak_current_at_s = abs(current), now_s
        line = None
        if stalled and not self.stalled and at_stop is not None:
            line = (f"servo {self.servo_id}: stalled at its {at_stop[0]} end stop (mechanical "
                    f"{self.mechanical_ticks:.0f} ticks) at t={now_s:.3f} s, pulling "
                    f"{ct.current_units_to_ma(pull):.0f} mA ({ct.MODE_NAMES.get(mode, mode)} mode)")
        self.stalled = stalled
        return line


def _ticks_per_s(velocity_units: int) -> float:
    return velocity_units * ct.RPM_PER_VELOCITY_UNIT / 60.0 * ct.TICKS_PER_REV


def _int(table: bytearray, address: int, n: int, signed: bool = False) -> int:
    return int.from_bytes(table[address : address + n], "little", signed=signed)


def _overlaps(address: int, length: int, register: int, size: int) -> bool:
    return address < register + size and register < address + length

