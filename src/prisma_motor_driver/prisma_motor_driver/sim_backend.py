"""Simulated motors with the MotorBus interface (motor model: docs/manipulation.md).

Each motor follows its velocity command with a first-order lag (the servo's velocity loop), stops
hard at its position limits (the tendon end stops), and draws current for its load torque, for speed
(viscous loss) and, when driven into an end stop, the stall current. Time only moves when the caller
passes a later stamp_ns to `advance`/`read_state`, so runs are deterministic.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from .backend import BusError, BusStats, MotorConfig, MotorState, ServoInfo, check_velocity
from .control_table import rad_s_to_rpm, rpm_to_rad_s


@dataclass(frozen=True)
class SimMotorParams:
    tau_s: float = 0.01  # velocity-loop time constant
    torque_constant_nm_per_a: float = 1.8  # XM430-W350: 4.1 N*m stall at 2.3 A
    viscous_nm_per_rad_s: float = 0.002
    stall_current_ma: float = 2300.0
    position_gain_per_s: float = 20.0  # position mode: velocity = gain * error, capped at the profile
    substep_s: float = 0.001


@dataclass
class _Motor:
    config: MotorConfig
    position_rad: float = 0.0
    velocity_rad_s: float = 0.0
    mode: str = "velocity"  # or "position"
    command_rad_s: float = 0.0
    target_rad: float = 0.0
    profile_rad_s: float = 0.0
    torque_on: bool = True
    load_nm: float = 0.0
    hardware_error: int = 0
    at_stop: bool = False


class SimMotorBus:
    def __init__(
        self,
        motors: Mapping[str, MotorConfig],
        params: SimMotorParams | None = None,
        initial_positions: Mapping[str, float] | None = None,
        start_ns: int | None = 0,  # None: the first read sets the time (a clock not started yet)
    ) -> None:
        self.motors = dict(motors)
        self.params = params or SimMotorParams()
        self.stats = BusStats()
        # the model's zero is where it starts counting: it cannot lose it, so there is nothing to home
        self.needs_homing = False
        self.homed = {name: True for name in self.motors}
        self.servo_info: dict[str, ServoInfo] = {}
        self._m = {name: _Motor(c) for name, c in self.motors.items()}
        for name, position in (initial_positions or {}).items():
            self._m[name].position_rad = self.motors[name].clamp(position)
        self._now_ns = start_ns

    @property
    def now_ns(self) -> int | None:
        """The simulated time; None until the first read when started with start_ns=None."""
        return self._now_ns

    # ---- lifecycle -------------------------------------------------------------------------
    def open(self) -> None:
        for m in self._m.values():
            m.torque_on = True

    def close(self) -> None:
        for name in self._m:
            self.torque_off(name)

    # ---- world coupling --------------------------------------------------------------------
    def set_loads(self, loads_nm: Mapping[str, float]) -> None:
        """Load torque on each motor shaft (from the hand/world model: tendon tension x spool)."""
        for name, load in loads_nm.items():
            self._m[name].load_nm = float(load)

    def inject_hardware_error(self, name: str, bit: int) -> None:
        self._m[name].hardware_error |= 1 << bit

    def clear_hardware_error(self, name: str) -> None:
        """As a power cycle: the error is gone (the driver turns the torque back on)."""
        self._m[name].hardware_error = 0

    def positions(self) -> dict[str, float]:
        return {name: m.position_rad for name, m in self._m.items()}

    # ---- MotorBus --------------------------------------------------------------------------
    def advance(self, stamp_ns: int) -> None:
        if self._now_ns is None:
            self._now_ns = stamp_ns
            return
        dt_total = (stamp_ns - self._now_ns) * 1e-9
        if dt_total <= 0:
            return
        n = max(1, int(math.ceil(dt_total / self.params.substep_s - 1e-9)))
        dt = dt_total / n
        for m in self._m.values():
            for _ in range(n):
                self._substep(m, dt)
        self._now_ns = stamp_ns

    def _substep(self, m: _Motor, dt: float) -> None:
        p = self.params
        if not m.torque_on:
            target = 0.0
        elif m.mode == "position":
            error = m.target_rad - m.position_rad
            target = max(-m.profile_rad_s, min(m.profile_rad_s, p.position_gain_per_s * error))
        else:
            target = m.command_rad_s
        # exact first-order step toward the target velocity
        alpha = math.exp(-dt / p.tau_s)
        v0 = m.velocity_rad_s
        v1 = target + (v0 - target) * alpha
        if abs(v1 - target) < 1e-12:
            v1 = target  # settled: the decay would otherwise linger in denormals (2.5e-323 rad/s on /joint_states)
        position = m.position_rad + target * dt + (v0 - target) * p.tau_s * (1.0 - alpha)
        c = m.config
        m.at_stop = False
        if position >= c.max_position_rad and target >= 0:
            position, v1, m.at_stop = c.max_position_rad, 0.0, target > 0
        elif position <= c.min_position_rad and target <= 0:
            position, v1, m.at_stop = c.min_position_rad, 0.0, target < 0
        m.position_rad, m.velocity_rad_s = position, v1

    def read_state(self, stamp_ns: int) -> dict[str, MotorState]:
        self.advance(stamp_ns)
        self.stats.reads += 1
        return {name: self._state(m) for name, m in self._m.items()}

    def _state(self, m: _Motor) -> MotorState:
        p = self.params
        if not m.torque_on:
            current = 0.0
        elif m.at_stop:
            current = math.copysign(p.stall_current_ma, m.command_rad_s or 1.0)
        else:
            torque = m.load_nm + p.viscous_nm_per_rad_s * m.velocity_rad_s
            current = max(-p.stall_current_ma, min(p.stall_current_ma, 1000.0 * torque / p.torque_constant_nm_per_a))
        return MotorState(m.config.name, m.position_rad, rad_s_to_rpm(m.velocity_rad_s), current,
                          m.torque_on, m.hardware_error)

    def set_velocities(self, rpm: Mapping[str, float]) -> None:
        for name, value in rpm.items():
            m = self._motor(name)
            check_velocity(m.config, value)
            if m.mode != "velocity":
                self.stats.mode_changes += 1
            m.mode, m.command_rad_s = "velocity", rpm_to_rad_s(value)
        self.stats.writes += 1

    def set_positions(self, rad: Mapping[str, float], profile_rpm: float) -> None:
        for name, value in rad.items():
            m = self._motor(name)
            c = m.config
            if not c.min_position_rad <= value <= c.max_position_rad:
                raise ValueError(f"motor {name}: position {value} rad outside "
                                 f"[{c.min_position_rad}, {c.max_position_rad}]")
            check_velocity(c, profile_rpm)
            if m.mode != "position":
                self.stats.mode_changes += 1
            m.mode, m.target_rad, m.profile_rad_s = "position", value, rpm_to_rad_s(abs(profile_rpm))
        self.stats.writes += 1

    def stop(self, names: list[str] | None = None) -> None:
        for name in names if names is not None else list(self._m):
            m = self._motor(name)
            if m.mode == "velocity":
                m.command_rad_s = 0.0
            else:
                m.target_rad = m.position_rad

    def torque_off(self, name: str) -> None:
        m = self._motor(name)
        m.torque_on = False
        m.command_rad_s = 0.0

    def torque_on(self, name: str) -> None:
        m = self._motor(name)
        m.torque_on, m.mode, m.command_rad_s = True, "velocity", 0.0

    def rearm_watchdog(self, names: list[str]) -> None:
        pass  # the model has no bus to fall silent

    def start_homing(self, names: list[str], rpm: float, current_ma: float) -> None:
        raise BusError("the sim motors have no end stops to home on: they start at their zero")

    def finish_homing(self, name: str) -> int:
        raise BusError("the sim motors have no end stops to home on: they start at their zero")

    def abort_homing(self, names: list[str]) -> None:
        self.stop(names)

    def _motor(self, name: str) -> _Motor:
        try:
            return self._m[name]
        except KeyError:
            raise ValueError(f"unknown motor {name!r}; configured: {sorted(self._m)}") from None
