"""The hand's three Dynamixel servos (IDs 1-3, Protocol 2.0) as the emulator wires them: the servo
emulator on its pty, each motor's mechanical end stops, the world's loads as Present Current, and
the servo faults (hardware error, off the bus, power cycle, another baud rate, turned by hand).

The world follows the spools' MECHANICAL angles: what a servo reports loses whole turns at a
power-up, the spools do not. A servo driven into an end stop (END_STOPS_RAD: its configured minimum,
and 0.2 rad past its maximum) stalls there at the current its mode allows (logged via `log`)."""
from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from prisma_common.hand import MOTOR_NAMES
from prisma_motor_driver import control_table as ct
from prisma_motor_driver.backend import DEFAULT_MAX_POSITIONS, DEFAULT_MIN_POSITIONS
from prisma_motor_driver.dynamixel_emulator import DynamixelEmulator, ServoPresent
from prisma_motor_driver.sim_backend import SimMotorParams

from .fault_table import FaultError

# the servos' IDs as config/motor_driver.yaml has them
MOTOR_IDS = dict(zip(MOTOR_NAMES, (1, 2, 3)))
# Each motor's mechanical end stops (rad of the motor shaft from its zero): the open end is its
# configured minimum, the far one this far past its configured maximum.
END_STOP_MARGIN_RAD = 0.2
END_STOPS_RAD = {name: (lo, hi + END_STOP_MARGIN_RAD)
                 for name, lo, hi in zip(MOTOR_NAMES, DEFAULT_MIN_POSITIONS, DEFAULT_MAX_POSITIONS)}


class EmulatedServos:
    """The servo emulator (`bus`) with the hand's wiring: `directions` and `zero_ticks` as
    motor_driver's, per MOTOR_NAMES. The tick reads `positions` and sets `loads`; the control
    socket's thread sets the faults, and timed ones end at `expire_faults` (the tick's)."""

    def __init__(self, directions: tuple[int, ...], zero_ticks: tuple[int, ...], clock_ns: Callable[[], int],
                 log: Callable[[str], None] | None = None, wall_clock: bool = True) -> None:
        self.directions, self.zero_ticks = directions, zero_ticks
        self.clock_ns = clock_ns
        self.bus = DynamixelEmulator(list(MOTOR_IDS.values()), clock=lambda: clock_ns() * 1e-9, log=log,
                                     wall_clock=wall_clock)
        for name, (lo, hi) in END_STOPS_RAD.items():
            self.bus.set_end_stops(MOTOR_IDS[name], *sorted((self._mechanical_ticks(name, lo),
                                                             self._mechanical_ticks(name, hi))))
        self._faults_lock = threading.Lock()  # the tick expires them, the control thread sets them
        self._silent_until_ns: dict[str, int | None] = {}  # None = until servo-clear

    def positions(self, present: dict[int, ServoPresent] | None = None) -> dict[str, float]:
        """The joints' motor angles (rad), from the spools' mechanical angles (`present`: the
        servos' state already read, else read now)."""
        present = present or self.bus.present()
        return {name: self.directions[i] * ct.ticks_to_rad(present[MOTOR_IDS[name]].mechanical_ticks
                                                           - self.zero_ticks[i])
                for i, name in enumerate(MOTOR_NAMES)}

    def load(self, torques_nm: dict[str, float]) -> None:
        """The world's load torque on each motor's shaft, as the servo's Present Current."""
        for name, servo_id in MOTOR_IDS.items():
            self.bus.set_load(servo_id, _current_units(torques_nm[name]))

    def pose(self, positions: dict[str, float]) -> None:
        """Put every servo at `positions` (rad), at rest: the experimenter posing the hand."""
        for name in MOTOR_NAMES:
            self.bus.place(MOTOR_IDS[name], self._mechanical_ticks(name, positions[name]))

    def expire_faults(self, now_ns: int) -> None:
        with self._faults_lock:
            over = [name for name, until in self._silent_until_ns.items() if until is not None and now_ns >= until]
        for name in over:
            self._back(name)

    def _mechanical_ticks(self, motor: str, rad: float) -> float:
        i = MOTOR_NAMES.index(motor)
        return self.zero_ticks[i] + ct.rad_to_ticks(self.directions[i] * rad)

    def _servo_id(self, motor: str) -> int:
        if motor not in MOTOR_IDS:
            raise FaultError(f"motor {motor!r}: choose one of {', '.join(MOTOR_NAMES)}")
        return MOTOR_IDS[motor]

    # ---- faults ----------------------------------------------------------------------------
    def error(self, motor: str, bit: int | str) -> str:
        servo_id = self._servo_id(motor)
        names = {name: b for b, name in ct.HARDWARE_ERROR_BITS.items()}
        if isinstance(bit, str) and not bit.isdigit():
            if bit not in names:
                raise FaultError(f"bit {bit!r}: choose a number 0-7 or one of {', '.join(names)}")
            bit = names[bit]
        bit = int(bit)
        if not 0 <= bit <= 7:
            raise FaultError(f"bit {bit}: Hardware Error Status has bits 0-7")
        self.bus.inject_hardware_error(servo_id, bit)
        return f"{motor} (ID {servo_id}): {ct.describe_hardware_error(1 << bit)}"

    def silent(self, motor: str, seconds: float) -> str:
        servo_id = self._servo_id(motor)
        with self._faults_lock:
            self.bus.set_silent(servo_id, True)
            self._silent_until_ns[motor] = self.clock_ns() + int(seconds * 1e9) if seconds else None
        return f"{motor} (ID {servo_id}) off the bus{f' for {seconds:g} s' if seconds else ' until servo-clear'}"

    def _back(self, motor: str) -> None:
        with self._faults_lock:
            self.bus.set_silent(MOTOR_IDS[motor], False)
            self._silent_until_ns.pop(motor, None)

    def clear(self, motor: str) -> str:
        motors = [motor] if motor else list(MOTOR_NAMES)
        for name in motors:
            servo_id = self._servo_id(name)
            self.bus.clear_hardware_error(servo_id)
            self._back(name)
        return f"{', '.join(motors)}: hardware error cleared, answering"

    def power_cycle(self, motor: str) -> str:
        motors = [motor] if motor else list(MOTOR_NAMES)
        ids = [self._servo_id(name) for name in motors]
        for servo_id in ids:
            self.bus.power_cycle(servo_id)
        return (f"{', '.join(motors)}: power-cycled (torque off, RAM reset, position within one turn; "
                "the hand kept its pose)")

    def baud(self, motor: str, rate: int) -> str:
        servo_id = self._servo_id(motor)
        try:
            self.bus.set_baud(servo_id, int(rate))
        except (TypeError, ValueError) as exc:
            raise FaultError(str(exc)) from None
        return f"{motor} (ID {servo_id}) set to {int(rate)} baud"

    def place(self, motor: str, rad: float) -> str:
        servo_id = self._servo_id(motor)
        lo, hi = END_STOPS_RAD[motor]
        if not isinstance(rad, (int, float)) or isinstance(rad, bool) or not lo <= rad <= hi:
            raise FaultError(f"rad {rad!r}: {motor} moves between its end stops, {lo:g}..{hi:g} rad")
        self.bus.place(servo_id, self._mechanical_ticks(motor, rad))
        return f"{motor} (ID {servo_id}) turned by hand to {rad:g} rad (power-cycle to lose its turn count)"

    def status(self) -> dict[str, Any]:
        """Each servo as the status request reports it (plain data)."""
        present = self.bus.present()
        positions = self.positions(present)
        servos = {}
        for i, (name, servo_id) in enumerate(MOTOR_IDS.items()):
            servo, emulated = present[servo_id], self.bus.servos[servo_id]
            servos[name] = {"id": servo_id, "position_rad": round(positions[name], 4),
                            "velocity_rpm": round(self.directions[i] * servo.velocity_rpm, 3),
                            "torque_on": servo.torque_on, "hardware_error": servo.hardware_error,
                            "silent": emulated.silent, "baud_rate": emulated.baud_rate,
                            "present_position_ticks": int(round(servo.position_ticks)),
                            "mechanical_ticks": round(servo.mechanical_ticks, 1), "led": servo.led,
                            "bus_watchdog": servo.bus_watchdog,
                            "watchdog_firings": [
                                {"at_s": round(f.at_s, 4), "position_ticks": round(f.position_ticks, 1)}
                                for f in self.bus.watchdog_firings if f.servo_id == servo_id],
                            "current_ma": round(ct.current_units_to_ma(servo.current_units), 1),
                            "peak_current_ma": round(ct.current_units_to_ma(servo.peak_current_units), 1),
                            "current_limit_ma": round(ct.current_units_to_ma(servo.current_limit_units), 1)}
        return servos


def _current_units(load_nm: float, params: SimMotorParams = SimMotorParams()) -> int:
    """Present Current (units of 2.69 mA) for a load torque on the shaft."""
    return int(round(load_nm / params.torque_constant_nm_per_a * 1000.0 / ct.MA_PER_CURRENT_UNIT))
