"""Dynamixel X-series motors over Protocol 2.0 with dynamixel-sdk.

One GroupSyncRead per cycle of the block from Hardware Error Status (70) through Present Position
(135), which holds Bus Watchdog (98) and Present Current/Velocity/Position (126..135): one
transaction, not one per register (each costs the adapter's USB round trip, and on an emulated bus
a wake-up of the emulator: three of them made a tick take 20-80 ms there); goals go out with
GroupSyncWrite. Mode changes follow the firmware rule (torque off, write Operating Mode: EEPROM,
torque on), for every servo at once in sync writes, and are read back. Communication errors (no status
packet, corrupt status, a sync read answered with a block of another length: the late status of an
earlier instruction) are retried a bounded number of times and counted; exhausting the retries raises
BusError. A port that fails underneath (the adapter unplugged: EIO from the read, the write or the
SDK's input flush) raises BusError at once, naming the port and the OS reason.

Opening the bus makes each servo safe on its own before anything moves: its Current Limit (EEPROM)
is written, so no command pulls a tendon harder; its Bus Watchdog is armed (`watchdog_s`), so a driver
that dies or freezes, or a cable that is cut, stops the servo within that period: the driver's own
traffic (a sync read every tick) feeds it. A fired watchdog (Bus Watchdog reads -1; the goal
registers refuse writes) is cleared by writing 0 and armed again (`rearm_watchdog`). The servo's LED
(RAM, off at every power-up) marks it homed since it powered up (homing.py).
"""
from __future__ import annotations

import dataclasses
import math
import termios
from collections.abc import Callable, Mapping

import dynamixel_sdk as sdk
import serial

from prisma_common.os_errors import describe_os_error

from . import control_table as ct
from .backend import BusError, BusStats, MotorConfig, MotorState, ServoInfo, check_velocity
from .dynamixel_port import WaitingPortHandler

# Results worth another attempt: the packet may simply have been lost or garbled on the wire.
_RETRYABLE = {sdk.COMM_RX_TIMEOUT, sdk.COMM_RX_CORRUPT, sdk.COMM_RX_FAIL, sdk.COMM_TX_FAIL}
# The block each tick reads: Hardware Error Status (70) through Present Position (135), Bus Watchdog
# (98) and the present state (126..135) inside it
CYCLE_START = ct.ADDR_HARDWARE_ERROR_STATUS
CYCLE_LENGTH = ct.STATE_START + ct.STATE_LENGTH - CYCLE_START


class DynamixelBus:
    def __init__(
        self,
        port: str,
        baudrate: int,
        motors: Mapping[str, MotorConfig],
        retries: int = 3,
        port_handler_factory: Callable[[str], sdk.PortHandler] = WaitingPortHandler,
        watchdog_s: float = 0.1,
    ) -> None:
        if retries < 0:
            raise ValueError(f"retries {retries} must be >= 0")
        self.watchdog_units = ct.watchdog_units(watchdog_s)  # ValueError beyond 20 ms..2.54 s
        self.port_name = port
        self.baudrate = baudrate
        self.motors = dict(motors)
        self.retries = retries
        self.stats = BusStats()
        self._port = port_handler_factory(port)
        self._packet = sdk.PacketHandler(2.0)
        self._modes: dict[str, int] = {}
        self._state_reader = sdk.GroupSyncRead(self._port, self._packet, CYCLE_START, CYCLE_LENGTH)
        for config in self.motors.values():
            self._state_reader.addParam(config.servo_id)
        self.model_numbers: dict[str, int] = {}
        self.needs_homing = True
        self.homed = {name: False for name in self.motors}
        self.servo_info: dict[str, ServoInfo] = {}
        self._open = False

    # ---- lifecycle -------------------------------------------------------------------------
    def open(self) -> None:
        """Open the port, ping every motor, put them in velocity mode with torque on (stopped)."""
        try:
            opened = self._port.openPort()
        except (serial.SerialException, OSError, ValueError) as exc:
            raise BusError(f"cannot open Dynamixel port {self.port_name}: {describe_os_error(exc)}") from exc
        if not opened:
            raise BusError(f"cannot open Dynamixel port {self.port_name}")
        if not self._port.setBaudRate(self.baudrate):
            self._port.closePort()
            raise BusError(f"Dynamixel port {self.port_name}: baud rate {self.baudrate} not supported")
        self._open = True
        for name, config in self.motors.items():
            model, _, _ = self._retry(lambda c=config: self._packet.ping(self._port, c.servo_id),
                                      f"ping {name} (id {config.servo_id})", result_index=1, error_index=2)
            self.model_numbers[name] = model
            self._prepare(name, config, model, arm=False)
        # armed together once every servo is ready: armed one by one, the first servos' periods ran
        # out while the driver was still preparing the others (eight round trips each)
        self._sync_write(ct.ADDR_BUS_WATCHDOG, 1, {name: self.watchdog_units for name in self.motors})

    def _prepare(self, name: str, config: MotorConfig, model: int, arm: bool = True) -> None:
        """Make one servo safe before it moves (also after it powered up again and forgot its RAM):
        its Current Limit, velocity mode stopped, torque on, its Bus Watchdog armed (`arm`); homed
        where its LED (off at power-up, lit by homing) says so."""
        firmware = self._read1(config, ct.ADDR_FIRMWARE_VERSION, "firmware version")
        if firmware < ct.WATCHDOG_MIN_FIRMWARE:
            raise BusError(f"{name} (id {config.servo_id}): firmware v{firmware} has no Bus Watchdog (v"
                           f"{ct.WATCHDOG_MIN_FIRMWARE} or later needed): update it with DYNAMIXEL Wizard 2.0")
        limit_units = ct.ma_to_current_units(config.current_limit_ma)
        self._write1(config, ct.ADDR_TORQUE_ENABLE, 0)
        self._write2(config, ct.ADDR_CURRENT_LIMIT, limit_units)  # EEPROM: torque off
        self._write1(config, ct.ADDR_OPERATING_MODE, ct.MODE_VELOCITY)
        self._write1(config, ct.ADDR_BUS_WATCHDOG, 0)  # clears an error a fired watchdog left
        self._write4(config, ct.ADDR_GOAL_VELOCITY, 0)
        self._write1(config, ct.ADDR_TORQUE_ENABLE, 1)
        if arm:
            self._write1(config, ct.ADDR_BUS_WATCHDOG, self.watchdog_units)
        self._modes[name] = ct.MODE_VELOCITY
        # the LED is off at power-up and lit by the homing that found this servo's zero
        self.homed[name] = self._read1(config, ct.ADDR_LED, "LED") == 1
        self.servo_info[name] = ServoInfo(model, firmware, ct.MODE_NAMES[ct.MODE_VELOCITY],
                                          self.watchdog_units * ct.WATCHDOG_UNIT_S * 1e3,
                                          ct.current_units_to_ma(limit_units))

    def close(self) -> None:
        """Torque off everywhere (best effort: a dead motor must not keep the others on), then close."""
        if not self._open:
            return
        errors = []
        for name in self.motors:
            try:
                self.torque_off(name)
            except BusError as exc:
                errors.append(str(exc))
        try:
            self._port.closePort()
        except (serial.SerialException, OSError, termios.error):
            pass  # the adapter is gone; its handle cannot be closed any better
        self._open = False
        if errors:
            raise BusError("; ".join(errors))

    # ---- reading ---------------------------------------------------------------------------
    def read_state(self, stamp_ns: int = 0) -> dict[str, MotorState]:
        states = {}
        for name, block in self._read_blocks().items():
            c = self.motors[name]
            present = ct.PresentState.from_bytes(bytes(block[ct.STATE_START - CYCLE_START:]))
            error = block[ct.ADDR_HARDWARE_ERROR_STATUS - CYCLE_START]
            watchdog = ct.to_signed(block[ct.ADDR_BUS_WATCHDOG - CYCLE_START], 1)
            if error:
                self.stats.hardware_errors += 1
            states[name] = MotorState(
                name=name,
                position_rad=c.direction * ct.ticks_to_rad(present.position_ticks - c.zero_ticks),
                velocity_rpm=c.direction * ct.units_to_rpm(present.velocity_units),
                current_ma=c.direction * ct.current_units_to_ma(present.current_units),
                torque_on=True,
                hardware_error=int(error),
                watchdog_fired=watchdog == ct.WATCHDOG_FIRED,
                # the watchdog this bus armed reads 0: the servo powered up again since (RAM lost)
                servo_reset=watchdog == 0,
            )
        return states

    def _read_blocks(self) -> dict[str, list[int]]:
        """One sync read of every servo's block from Hardware Error Status through Present Position."""
        attempts = self.retries + 1
        for attempt in range(attempts):
            self._retry(self._state_reader.txRxPacket, "sync read present state")
            wrong = self._wrong_length_blocks()
            if wrong is None:
                break
            # a status packet of another length: the late answer of an earlier instruction to that
            # servo (one that timed out on a busy computer), taken by the SDK for this one's
            self.stats.corrupt_status += 1
            if attempt + 1 < attempts:
                self.stats.retries += 1
        else:
            self.stats.comm_failures += 1
            raise BusError(f"sync read: {wrong} after {attempts} attempts")
        self.stats.reads += 1
        blocks = {}
        for name, c in self.motors.items():
            if not self._state_reader.isAvailable(c.servo_id, CYCLE_START, CYCLE_LENGTH):
                raise BusError(f"sync read: no present state from {name} (id {c.servo_id})")
            blocks[name] = self._state_reader.data_dict[c.servo_id]
        return blocks

    def _wrong_length_blocks(self) -> str | None:
        """What the last sync reads got of another length than asked, None if nothing."""
        for name, c in self.motors.items():
            block = self._state_reader.data_dict.get(c.servo_id)
            if block is not None and len(block) != CYCLE_LENGTH:
                return f"{name} (id {c.servo_id}) answered {len(block)} bytes of present state, not {CYCLE_LENGTH}"
        return None

    # ---- commands --------------------------------------------------------------------------
    def set_velocities(self, rpm: Mapping[str, float]) -> None:
        for name, value in rpm.items():
            check_velocity(self._config(name), value)
        self._ensure_mode(list(rpm), ct.MODE_VELOCITY)
        self._sync_write4(ct.ADDR_GOAL_VELOCITY, {
            name: ct.rpm_to_units(self._config(name).direction * value) for name, value in rpm.items()
        })

    def set_positions(self, rad: Mapping[str, float], profile_rpm: float) -> None:
        for name, value in rad.items():
            c = self._config(name)
            if not c.min_position_rad <= value <= c.max_position_rad:
                raise ValueError(
                    f"motor {name}: position {value} rad outside [{c.min_position_rad}, {c.max_position_rad}]"
                )
            check_velocity(c, profile_rpm)
        self._ensure_mode(list(rad), ct.MODE_EXTENDED_POSITION)
        self._sync_write4(ct.ADDR_PROFILE_VELOCITY, {n: ct.rpm_to_units(abs(profile_rpm)) for n in rad})
        self._sync_write4(ct.ADDR_GOAL_POSITION, {
            n: self._config(n).zero_ticks + ct.rad_to_ticks(self._config(n).direction * v) for n, v in rad.items()
        })

    def stop(self, names: list[str] | None = None) -> None:
        names = list(self.motors) if names is None else names
        velocity = [n for n in names if self._modes.get(n) == ct.MODE_VELOCITY]
        holding = [n for n in names if n not in velocity]
        if velocity:
            self._sync_write4(ct.ADDR_GOAL_VELOCITY, {n: 0 for n in velocity})
        if holding:
            self._sync_write4(ct.ADDR_GOAL_POSITION, self._present_ticks_of(holding))

    def torque_off(self, name: str) -> None:
        self._write1(self._config(name), ct.ADDR_TORQUE_ENABLE, 0)

    def torque_on(self, name: str) -> None:
        # a power-cycled servo forgets its RAM, so every step of open() again, not just the torque
        self._prepare(name, self._config(name), self.model_numbers.get(name, 0))

    def rearm_watchdog(self, names: list[str]) -> None:
        # sync writes for every fired servo at once, not a round trip per servo and register: on a slow
        # bus (or emulator) the re-arm of one servo took long enough for the others' watchdogs to fire
        # in turn
        self._sync_write(ct.ADDR_BUS_WATCHDOG, 1, {n: 0 for n in names})  # the goal registers take writes again
        self.stop(names)
        self._sync_write(ct.ADDR_BUS_WATCHDOG, 1, {n: self.watchdog_units for n in names})

    def start_homing(self, names: list[str], rpm: float, current_ma: float) -> None:
        for name in names:
            c = self._config(name)
            check_velocity(c, rpm)
            if current_ma > c.current_limit_ma:
                raise ValueError(f"motor {name}: homing current {current_ma} mA above its current limit "
                                 f"{c.current_limit_ma} mA")
        # every servo in one burst of sync writes (see _change_mode), each from where it stands
        ticks = self._present_ticks_of(names)
        for name in names:
            self.homed[name] = False
        self._sync_write(ct.ADDR_LED, 1, {n: 0 for n in names})
        goals = {}
        for name in names:
            c = self._config(name)
            # far enough toward the open end to reach it from anywhere, a lost turn included
            span_rad = c.max_position_rad - c.min_position_rad + 2.0 * math.pi + 1.0
            goals[name] = ticks[name] - c.direction * ct.rad_to_ticks(span_rad)
        self._change_mode(names, ct.MODE_CURRENT_BASED_POSITION, [
            (ct.ADDR_GOAL_CURRENT, 2, {n: ct.ma_to_current_units(current_ma) for n in names}),
            (ct.ADDR_PROFILE_VELOCITY, 4, {n: ct.rpm_to_units(abs(rpm)) for n in names}),
            (ct.ADDR_GOAL_POSITION, 4, goals)])

    def finish_homing(self, name: str) -> int:
        c = self._config(name)
        # the end stop is the motor's minimum position
        zero = self._present_ticks_of([name])[name] - c.direction * ct.rad_to_ticks(c.min_position_rad)
        self.motors[name] = dataclasses.replace(c, zero_ticks=zero)
        self._ensure_mode([name], ct.MODE_VELOCITY)
        self._write1(c, ct.ADDR_LED, 1)
        self.homed[name] = True
        return zero

    def abort_homing(self, names: list[str]) -> None:
        # whatever mode the cache holds: a start_homing that failed half-way may have left the servo in
        # current-based position mode before the cache learnt it
        for name in names:
            self._modes.pop(name, None)
        self._ensure_mode(names, ct.MODE_VELOCITY)

    def hardware_error(self, name: str) -> int:
        """Hardware Error Status of one motor, read directly."""
        c = self._config(name)
        value, _ = self._retry(lambda: self._packet.read1ByteTxRx(self._port, c.servo_id,
                                                                  ct.ADDR_HARDWARE_ERROR_STATUS),
                               f"read hardware error status of {name} (id {c.servo_id})", result_index=1, error_index=2)
        return int(value)

    # ---- internals -------------------------------------------------------------------------
    def _config(self, name: str) -> MotorConfig:
        try:
            return self.motors[name]
        except KeyError:
            raise ValueError(f"unknown motor {name!r}; configured: {sorted(self.motors)}") from None

    def _ensure_mode(self, names: list[str], mode: int) -> None:
        changing = [n for n in names if self._modes.get(n) != mode]
        if not changing:
            return
        if mode == ct.MODE_VELOCITY:
            self._change_mode(changing, mode, [(ct.ADDR_GOAL_VELOCITY, 4, {n: 0 for n in changing})])
        else:  # held where each stands
            self._change_mode(changing, mode, [(ct.ADDR_GOAL_POSITION, 4, self._present_ticks_of(changing))])

    def _change_mode(self, names: list[str], mode: int, writes: list[tuple[int, int, dict[str, int]]]) -> None:
        """Operating Mode (EEPROM: torque off), then `writes` (address, size, values), then torque on, in
        sync writes: a round trip per servo and register (16 ms each behind a U2D2 at its default
        latency timer) left the servos not yet reached without an instruction past their Bus Watchdog.
        A sync write has no status packet: Operating Mode is read back, so that a mode a servo refused
        (the torque-off lost on the wire) fails here, not as a goal that never moves."""
        self._sync_write(ct.ADDR_TORQUE_ENABLE, 1, {n: 0 for n in names})
        self._sync_write(ct.ADDR_OPERATING_MODE, 1, {n: mode for n in names})
        for address, size, values in writes:
            self._sync_write(address, size, values)
        self._sync_write(ct.ADDR_TORQUE_ENABLE, 1, {n: 1 for n in names})
        reader = sdk.GroupSyncRead(self._port, self._packet, ct.ADDR_OPERATING_MODE, 1)
        for name in names:
            reader.addParam(self._config(name).servo_id)
        self._retry(reader.txRxPacket, "sync read operating mode")
        for name in names:
            c = self._config(name)
            if not reader.isAvailable(c.servo_id, ct.ADDR_OPERATING_MODE, 1):
                raise BusError(f"sync read: no operating mode from {name} (id {c.servo_id})")
            found = reader.getData(c.servo_id, ct.ADDR_OPERATING_MODE, 1)
            if found != mode:
                raise BusError(f"{name} (id {c.servo_id}) did not take operating mode {ct.MODE_NAMES[mode]}: it "
                               f"reads {ct.MODE_NAMES.get(found, found)}")
            self._modes[name] = mode
            self.stats.mode_changes += 1
            self.servo_info[name] = dataclasses.replace(self.servo_info.get(name, ServoInfo()),
                                                        operating_mode=ct.MODE_NAMES[mode])

    def _present_ticks_of(self, names: list[str]) -> dict[str, int]:
        """Present Position of each motor (raw ticks), from one sync read of every servo (it feeds
        every servo's watchdog)."""
        blocks = self._read_blocks()
        return {n: ct.PresentState.from_bytes(bytes(blocks[n][ct.STATE_START - CYCLE_START:])).position_ticks
                for n in names}

    def _write1(self, c: MotorConfig, address: int, value: int) -> None:
        self._retry(lambda: self._packet.write1ByteTxRx(self._port, c.servo_id, address, value),
                    f"write {value} to address {address} of {c.name} (id {c.servo_id})", result_index=0, error_index=1)

    def _read1(self, c: MotorConfig, address: int, what: str) -> int:
        value, _, _ = self._retry(lambda: self._packet.read1ByteTxRx(self._port, c.servo_id, address),
                                  f"read {what} of {c.name} (id {c.servo_id})", result_index=1, error_index=2)
        return int(value)

    def _write2(self, c: MotorConfig, address: int, value: int) -> None:
        self._retry(lambda: self._packet.write2ByteTxRx(self._port, c.servo_id, address, ct.to_unsigned(value, 2)),
                    f"write {value} to address {address} of {c.name} (id {c.servo_id})", result_index=0, error_index=1)

    def _write4(self, c: MotorConfig, address: int, value: int) -> None:
        self._retry(lambda: self._packet.write4ByteTxRx(self._port, c.servo_id, address, ct.to_unsigned(value, 4)),
                    f"write {value} to address {address} of {c.name} (id {c.servo_id})", result_index=0, error_index=1)

    def _sync_write4(self, address: int, values: Mapping[str, int]) -> None:
        self._sync_write(address, 4, values)

    def _sync_write(self, address: int, size: int, values: Mapping[str, int]) -> None:
        writer = sdk.GroupSyncWrite(self._port, self._packet, address, size)
        for name, value in values.items():
            data = ct.to_unsigned(int(value), size).to_bytes(size, "little")
            writer.addParam(self._config(name).servo_id, list(data))
        # sync write has no status packet: only a failed transmit can be retried
        self._retry(writer.txPacket, f"sync write address {address}")
        self.stats.writes += 1

    def _retry(self, call, what: str, result_index: int | None = None, error_index: int | None = None):
        """Run an SDK call, retrying communication failures. Returns the call's return value.
        A status packet that reports an instruction error (range, access...) is not retried."""
        attempts = self.retries + 1
        for attempt in range(attempts):
            try:
                value = call()
            except (serial.SerialException, OSError, termios.error) as exc:
                self.stats.comm_failures += 1  # the port itself failed: no retry can help
                raise BusError(f"{what}: Dynamixel port {self.port_name} failed: {describe_os_error(exc)}") from exc
            result = value if result_index is None else value[result_index]
            if result == sdk.COMM_SUCCESS:
                if error_index is not None:
                    error = value[error_index] & ~ct.STATUS_ALERT_BIT
                    if error:
                        raise BusError(f"{what}: {self._packet.getRxPacketError(error)} (error {error})")
                return value
            if result not in _RETRYABLE:
                raise BusError(f"{what}: {self._packet.getTxRxResult(result)}")
            if result == sdk.COMM_RX_TIMEOUT:
                self.stats.dropped_status += 1
            elif result == sdk.COMM_RX_CORRUPT:
                self.stats.corrupt_status += 1
            if attempt + 1 < attempts:
                self.stats.retries += 1
        self.stats.comm_failures += 1
        raise BusError(f"{what}: {self._packet.getTxRxResult(result)} after {attempts} attempts")
