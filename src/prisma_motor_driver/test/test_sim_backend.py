"""Simulated motors: velocity response, limits, current, position mode."""
from __future__ import annotations

import math

import pytest

from prisma_motor_driver.backend import default_motors
from prisma_motor_driver.sim_backend import SimMotorBus

MS = 1_000_000


def test_sim_motor_velocity_response_limits_and_current():
    bus = SimMotorBus(default_motors())
    bus.set_velocities({"fingers": 60.0})
    s = bus.read_state(10 * MS)["fingers"]
    assert s.velocity_rpm == pytest.approx(60.0 * (1 - math.exp(-1.0)), rel=1e-6)  # tau = 10 ms
    w = 2 * math.pi  # 60 rpm
    assert s.position_rad == pytest.approx(w * 0.01 - w * 0.01 * (1 - math.exp(-1.0)), rel=1e-6)
    idle = bus.read_state(200 * MS)["fingers"].current_ma
    bus.set_loads({"fingers": 0.1})
    loaded = bus.read_state(210 * MS)["fingers"].current_ma
    assert loaded - idle == pytest.approx(1000 * 0.1 / 1.8, rel=1e-3)  # current rises with load
    s = bus.read_state(20_000 * MS)["fingers"]  # long past the 9 rad limit
    assert s.position_rad == 9.0 and s.velocity_rpm == 0.0 and s.current_ma == 2300.0  # stalled
    bus.torque_off("fingers")
    assert bus.read_state(20_010 * MS)["fingers"].current_ma == 0.0


def test_sim_position_mode_reaches_target_at_profile_speed():
    bus = SimMotorBus(default_motors())
    bus.set_positions({"thumb_rotation": 1.0}, profile_rpm=30.0)
    assert bus.read_state(200 * MS)["thumb_rotation"].position_rad == pytest.approx(math.pi * 0.2, abs=0.05)
    assert bus.read_state(2000 * MS)["thumb_rotation"].position_rad == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ValueError, match="position 4.0 rad outside"):
        bus.set_positions({"thumb_rotation": 4.0}, 30.0)
