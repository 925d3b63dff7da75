"""TeleopController: proportional following capped in speed, stopping at the target, the touch limit
(no closing at the pad force limit, opening always), targets clamped into the motor windows, the
command rate, and a cancel as its normal end."""
from __future__ import annotations

import math

import pytest

from prisma_manipulation.controllers import CANCELED, ControlInput, ControlLimits, JointSample
from prisma_manipulation.node_config import ManipulationConfig
from prisma_manipulation.teleop_controller import (
    FOLLOWING,
    HOLDING,
    TARGET_STREAM,
    WAITING,
    TeleopController,
    TeleopTarget,
)

MS = 1_000_000
PADS = ("thumb", "index", "middle", "ring", "little")
OPEN = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
LIMITS = ControlLimits(ManipulationConfig().limits_motors(), 0.02)  # fingers [0, 9], thumb_flexion [0, 7], rot [-3, 3]
RPM_PER_RAD = 10.0 * 60 / (2 * math.pi)  # gain 10 1/s: 95.5 rpm per rad of error


def controller(max_pad_force=2.0, max_speed_rpm=40.0, gain=10.0):
    c = TeleopController(LIMITS, PADS, max_pad_force, max_speed_rpm, gain)
    c.start(JointSample(0, OPEN))
    return c


def step(c, t_ms, positions=None, target=None, forces=None):
    inputs = {TARGET_STREAM: TeleopTarget(t_ms * MS - 3 * MS, target)} if target is not None else {}
    return c.step(ControlInput(t_ms * MS, {}, forces or {}, JointSample(t_ms * MS, {**OPEN, **(positions or {})}),
                               inputs))


def test_waits_without_a_target_and_a_far_target_closes_at_the_capped_speed():
    c = controller()
    out = step(c, 10)
    assert (out.phase, out.command, c.targets) == (WAITING, None, {})
    out = step(c, 20, target={"fingers": 9.0, "thumb_flexion": 3.0, "thumb_rotation": -1.0})
    # 95.5 rpm per rad of error, capped at the goal's 40 rpm (below the motors' 70)
    assert out.phase == FOLLOWING and dict(out.command.velocities_rpm) == {"fingers": 40.0, "thumb_flexion": 40.0,
                                                                          "thumb_rotation": -40.0}
    assert controller(max_speed_rpm=90.0).speed_caps == {"fingers": 70.0, "thumb_flexion": 70.0,
                                                         "thumb_rotation": 70.0}
    # near the target the speed is proportional: 0.2 rad -> 19.1 rpm (60 ms later: the command period passed)
    out = step(c, 80, positions={"fingers": 8.78, "thumb_flexion": 2.8, "thumb_rotation": -0.8})
    assert out.command.velocities_rpm["fingers"] == pytest.approx(0.2 * RPM_PER_RAD)
    assert out.command.velocities_rpm["thumb_rotation"] == pytest.approx(-0.2 * RPM_PER_RAD)


def test_stops_at_the_target_within_the_tolerance_and_moves_again_at_twice_it():
    c = controller()
    step(c, 10, target={"fingers": 2.0})
    # a motor without a target stands still; one within 0.02 rad of its target stops
    out = step(c, 20, positions={"fingers": 1.985})
    assert dict(out.command.velocities_rpm) == {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
    assert step(c, 30, positions={"fingers": 1.965}).command is None  # 0.035 rad off: still stopped
    out = step(c, 40, positions={"fingers": 1.955})  # 0.045 rad: moves again
    assert out.command.velocities_rpm["fingers"] == pytest.approx(0.045 * RPM_PER_RAD)


def test_the_touch_limit_holds_closing_and_always_lets_open():
    c = controller(max_pad_force=2.0)
    target = {"fingers": 6.0, "thumb_flexion": 5.0, "thumb_rotation": 1.0}
    out = step(c, 10, positions={"fingers": 4.0, "thumb_flexion": 3.0}, target=target,
               forces={"index": 2.01, "thumb": 1.2})
    # index at the limit: the fingers do not close; the thumb (1.2 N) closes, the rotation is never limited
    assert out.phase == HOLDING and c.force_limited == ("fingers",)
    assert dict(out.command.velocities_rpm) == {"fingers": 0.0, "thumb_flexion": 40.0, "thumb_rotation": 40.0}
    # the thumb pad reaches the limit too; any finger pad holds the fingers motor (the little's here)
    out = step(c, 20, positions={"fingers": 4.0, "thumb_flexion": 3.1}, target=target,
               forces={"index": 1.0, "little": 2.3, "thumb": 2.0})
    assert c.force_limited == ("fingers", "thumb_flexion")
    assert dict(out.command.velocities_rpm) == {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 40.0}
    # opening is allowed above the limit
    out = step(c, 30, positions={"fingers": 4.0, "thumb_flexion": 3.1}, target={"fingers": 3.0, "thumb_flexion": 2.5},
               forces={"index": 2.5, "thumb": 2.5})
    assert out.phase == FOLLOWING and c.force_limited == ()
    assert out.command.velocities_rpm["fingers"] == -40.0 and out.command.velocities_rpm["thumb_flexion"] == -40.0
    # closing again: held until the pads read 0.05 N below the limit, then slowly (near the limit)
    forces = {"index": 1.97, "thumb": 1.97}
    out = step(c, 40, positions={"fingers": 3.9, "thumb_flexion": 3.0}, target=target, forces=forces)
    assert out.command.velocities_rpm["fingers"] == 0.0 and c.force_limited == ("fingers", "thumb_flexion")
    out = step(c, 50, positions={"fingers": 3.9, "thumb_flexion": 3.0}, target=target,
               forces={"index": 1.94, "thumb": 1.94})
    assert out.command.velocities_rpm["fingers"] == 10.0 and c.force_limited == ()


def test_a_closing_motor_slows_within_half_a_newton_of_the_limit():
    c = controller(max_pad_force=2.0)
    target = {"fingers": 8.0, "thumb_flexion": 6.0, "thumb_rotation": 2.0}
    speeds = []
    for i, force in enumerate((1.0, 1.5, 1.6, 1.8, 1.9, 1.99)):
        step(c, 10 + 60 * i, positions={"thumb_rotation": 0.5}, target=target, forces={"index": force, "thumb": force})
        speeds.append(dict(c.command.velocities_rpm))  # 60 ms apart: each change is sent
    # 40 rpm until 1.5 N, then 40 x (2 N - force) / 0.5 N, at least a quarter (10 rpm); the rotation
    # presses no pad: full speed
    assert [s["fingers"] for s in speeds[1:]] == pytest.approx([40.0, 32.0, 16.0, 10.0, 10.0])
    assert speeds[0] == {"fingers": 40.0, "thumb_flexion": 40.0, "thumb_rotation": 40.0}
    assert all(s["thumb_flexion"] == s["fingers"] and s["thumb_rotation"] == 40.0 for s in speeds[2:4])
    # opening is never slowed
    out = step(c, 400, positions={"fingers": 9.0}, target=target, forces={"index": 1.9})
    assert out.command.velocities_rpm["fingers"] == -40.0


def test_targets_are_clamped_into_the_motor_windows_and_bad_values_ignored():
    c = controller()
    step(c, 10, target={"fingers": 12.0, "thumb_flexion": -1.0, "thumb_rotation": -5.0})
    assert c.targets == {"fingers": 8.98, "thumb_flexion": 0.02, "thumb_rotation": -2.98}
    step(c, 20, target={"fingers": math.nan, "thumb_flexion": math.inf, "wrist": 1.0})
    assert c.targets == {"fingers": 8.98, "thumb_flexion": 0.02, "thumb_rotation": -2.98}


def test_a_speed_change_waits_for_the_command_period_a_start_stop_or_turn_does_not():
    c = controller()
    assert step(c, 10, positions={"fingers": 1.0}, target={"fingers": 1.3}).command.velocities_rpm["fingers"] == \
        pytest.approx(0.3 * RPM_PER_RAD)
    # 10 ms later the proportional speed changed: kept until 50 ms after the last command
    assert step(c, 20, positions={"fingers": 1.1}).command is None
    assert step(c, 50, positions={"fingers": 1.15}).command is None
    assert step(c, 60, positions={"fingers": 1.2}).command.velocities_rpm["fingers"] == \
        pytest.approx(0.1 * RPM_PER_RAD)
    # the target moves behind the motor: it turns at once
    assert step(c, 70, positions={"fingers": 1.2}, target={"fingers": 0.5}).command.velocities_rpm["fingers"] == -40.0
    # and stops at once at the target
    out = step(c, 80, positions={"fingers": 0.51})
    assert out.command is not None and out.command.is_stop


def test_it_never_ends_on_its_own_and_a_cancel_is_its_success():
    c = controller()
    for t_ms in range(10, 2000, 10):
        assert not step(c, t_ms, target={"fingers": 1.0}).done
    out = c.abort(2000 * MS, CANCELED)
    assert (out.done, out.reason, out.success) == (True, CANCELED, True)
    c = controller()
    step(c, 10, target={"fingers": 1.0})
    out = c.abort(20 * MS, "input_stale")
    assert (out.done, out.reason, out.success, out.command.is_stop) == (True, "input_stale", False, True)


@pytest.mark.parametrize("name, value", [("max_pad_force", 0.0), ("max_speed_rpm", -1.0), ("gain", math.nan)])
def test_bad_settings_are_refused_naming_them(name, value):
    settings = {"max_pad_force": 2.0, "max_speed_rpm": 40.0, "gain": 10.0} | {name: value}
    with pytest.raises(ValueError, match=f"{name} {value} must be > 0"):
        TeleopController(LIMITS, PADS, settings["max_pad_force"], settings["max_speed_rpm"], settings["gain"])
