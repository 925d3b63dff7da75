"""The GripperCommand controller with hand-made inputs: the thumb's ratio, the force limit while
closing (and never while opening), reaching the position, mixed directions, timeout."""
from __future__ import annotations

import pytest

from prisma_manipulation.controllers import ControlInput, ControlLimits, JointSample, MotorCommand
from prisma_manipulation.gripper_controller import GripperController
from prisma_motor_driver.backend import default_motors

MS = 1_000_000
LIMITS = ControlLimits(default_motors())  # fingers 0..9, thumb_flexion 0..7, thumb_rotation -3..3 rad
PADS = ("thumb", "index", "middle", "ring", "little")


def _joints(t_ns, fingers, flexion):
    return JointSample(t_ns, {"fingers": fingers, "thumb_flexion": flexion, "thumb_rotation": 0.0})


def _step(c, t_ms, fingers, flexion, **forces):
    """A sample at t_ms: the two motors' positions and the pads' normal forces (N)."""
    return c.step(ControlInput(t_ms * MS, {}, forces, _joints(t_ms * MS, fingers, flexion)))


def test_closing_on_an_object_stalls_at_the_force_limit():
    c = GripperController(LIMITS, 9.0, 1.0, PADS)
    assert c.targets == {"fingers": 9.0, "thumb_flexion": 7.0}  # 0.8333 x 9 = 7.5, clamped to the thumb's range
    out = c.start(_joints(0, 0.0, 0.0))
    assert out.phase == "close" and out.command == MotorCommand.of(fingers=60.0, thumb_flexion=60.0 * 0.8333)
    assert _step(c, 500, 3.1, 2.6, index=0.05, thumb=0.07).command is None  # touching: the force rises
    out = _step(c, 700, 4.2, 3.6, index=0.62, thumb=0.58, middle=0.01)
    assert out.command is None and not out.done
    out = _step(c, 710, 4.26, 3.65, index=0.96, thumb=1.01)  # the thumb pad reaches 1 N first
    assert out.done and out.success and out.reason == "force_reached" and out.command.is_stop
    assert c.stalled and not c.reached_goal
    assert (c.position, c.effort) == (4.26, 1.01)
    assert c.stop_ns == 710 * MS


def test_closing_on_nothing_reaches_the_position_each_motor_stopping_before_its_target():
    c = GripperController(LIMITS, 6.0, 1.0, PADS)
    assert c.targets["thumb_flexion"] == pytest.approx(5.0, abs=1e-3)
    c.start(_joints(0, 0.0, 0.0))
    lead_fingers, lead_thumb = c.leads["fingers"], c.leads["thumb_flexion"]
    assert lead_fingers == pytest.approx(6.2832 * 0.015, rel=1e-3)  # 60 rpm for 15 ms
    assert _step(c, 900, 5.9 - lead_fingers, 4.9 - lead_thumb).command is None
    out = _step(c, 910, 5.95 - lead_fingers, 5.0 - lead_thumb)  # the thumb is at its stop point
    assert out.command == MotorCommand.of(fingers=60.0) and not out.done
    out = _step(c, 920, 6.01 - lead_fingers, 5.05 - lead_thumb)
    assert out.done and out.success and out.reason == "reached" and out.command.is_stop
    assert c.reached_goal and not c.stalled


def test_opening_is_never_stopped_by_force():
    """Holding an object at 1.2 N and told to open with a 1 N limit: the gripper opens."""
    c = GripperController(LIMITS, 0.0, 1.0, PADS)
    out = c.start(_joints(0, 4.2, 3.5))
    assert out.phase == "open" and out.command == MotorCommand.of(fingers=-60.0, thumb_flexion=-60.0 * 0.8333)
    assert _step(c, 10, 4.14, 3.45, index=1.2, thumb=1.25).command is None
    out = _step(c, 700, 0.05, 0.05)
    assert out.done and out.reason == "reached" and c.reached_goal and not c.stalled


def test_a_gripper_already_at_its_position_ends_at_once():
    c = GripperController(LIMITS, 3.0, 1.0, PADS)
    out = c.start(_joints(0, 3.02, 2.49))
    assert out.done and out.success and out.reason == "reached" and out.command is None  # nothing was moving


def test_mixed_directions_only_the_closing_motor_stops_on_force():
    c = GripperController(LIMITS, 3.0, 0.8, PADS)  # fingers open from 4.0; the thumb closes from 1.0 to 2.5
    out = c.start(_joints(0, 4.0, 1.0))
    assert out.phase == "move" and out.command == MotorCommand.of(fingers=-60.0, thumb_flexion=60.0 * 0.8333)
    out = _step(c, 200, 3.5, 1.9, thumb=0.85)
    assert out.phase == "open" and out.command == MotorCommand.of(fingers=-60.0) and c.stalled
    out = _step(c, 300, 3.05, 1.9, thumb=0.85)
    assert out.done and out.success and out.reason == "force_reached" and not c.reached_goal
    assert c.reached == {"fingers": True, "thumb_flexion": False}


def test_timeout_and_bad_goals():
    c = GripperController(LIMITS, 9.0, 1.0, PADS, timeout_s=0.5)
    c.start(_joints(0, 0.0, 0.0))
    out = _step(c, 500, 3.1, 2.6)
    assert out.done and out.reason == "timeout" and not out.success and out.command.is_stop
    with pytest.raises(ValueError, match=r"position 9.5 rad outside the fingers motor's range \[0.0, 9.0\]"):
        GripperController(LIMITS, 9.5, 1.0, PADS)
    with pytest.raises(ValueError, match="max_effort 0.0 must be > 0"):
        GripperController(LIMITS, 3.0, 0.0, PADS)
    with pytest.raises(ValueError, match="at least one pad"):
        GripperController(LIMITS, 3.0, 1.0, ())
