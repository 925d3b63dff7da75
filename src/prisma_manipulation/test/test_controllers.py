"""Grasp and motion controllers with hand-made inputs: joint limits, aborts, presets, the force
keeper's hysteresis, hold, a manipulation without contact."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_hand_sim.pad_model import PadParams
from prisma_manipulation.contact_monitor import ContactMonitor
from prisma_manipulation.controllers import (
    ControlInput,
    ControlLimits,
    JointSample,
    MotorCommand,
)
from prisma_manipulation.grasp_controller import GraspController
from prisma_manipulation.motion_controllers import (
    ForceKeeper,
    HoldController,
    HorizontalController,
    VerticalController,
)
from prisma_motor_driver.backend import default_motors

MS = 1_000_000


LIMITS = ControlLimits(default_motors())


def _input(t_ns, positions, forces=None, contact=None):
    contacts = {"thumb": contact} if contact is not None else {}
    return ControlInput(t_ns, contacts, forces or {}, JointSample(t_ns, positions))


def test_grasp_runs_into_the_joint_limit_or_times_out():
    c = GraspController(LIMITS, "pinch", timeout_s=0.5)
    out = c.start(JointSample(0, {"fingers": 0.0}))
    assert out.command == MotorCommand.of(fingers=60.0)
    out = c.step(_input(10 * MS, {"fingers": 8.99}, {"index": 0.0}))
    assert out.done and out.reason == "joint_limit" and out.command.is_stop and not out.success
    c = GraspController(LIMITS, "pinch", timeout_s=0.5)
    c.start(JointSample(0, {"fingers": 0.0}))
    assert c.step(_input(490 * MS, {"fingers": 1.0}, {"index": 0.1})).reason is None
    out = c.step(_input(500 * MS, {"fingers": 1.0}, {"index": 0.1}))
    assert out.reason == "timeout" and out.command.is_stop


def test_grasp_abort_stops_everything_with_the_reason():
    c = GraspController(LIMITS, "power")
    c.start(JointSample(0, {"fingers": 0.0}))
    out = c.abort(30 * MS, "sensor_stale")
    assert out.done and out.reason == "sensor_stale" and out.command.is_stop and c.stop_ns == 30 * MS
    assert c.step(_input(40 * MS, {"fingers": 1.0})).command is None  # finished: no more commands


def test_power_preset_averages_the_pads_in_contact_and_lateral_closes_by_position():
    c = GraspController(LIMITS, "power")
    assert c.fingers_force({"index": 0.9, "middle": 0.7, "ring": 0.0, "little": 0.05}) == pytest.approx(0.8)
    lateral = GraspController(LIMITS, "lateral", lateral_closure_rad=6.0)
    lateral.start(JointSample(0, {"fingers": 0.0}))
    assert lateral.step(_input(10 * MS, {"fingers": 5.9}, {"thumb": 0.0})).command is None
    out = lateral.step(_input(20 * MS, {"fingers": 6.0}, {"thumb": 0.0}))
    assert out.phase == "close_thumb" and out.command == MotorCommand.of(thumb_flexion=60.0)
    with pytest.raises(ValueError, match="grasp 'fist'"):
        GraspController(LIMITS, "fist")


def test_force_keeper_has_hysteresis():
    keeper = ForceKeeper(target_n=1.0, band_n=0.15, speed_rpm=20.0)
    assert [keeper.update(f) for f in (1.0, 0.9, 0.84, 0.9, 0.99, 1.0, 0.9)] == [0, 0, 20, 20, 20, 0, 0]
    assert keeper.restores == 1


def test_horizontal_joint_limit_also_returns_to_start():
    monitor = ContactMonitor(0.8)
    centred = monitor.evaluate("thumb", 0, np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], np.float32))
    c = HorizontalController(LIMITS)
    c.start(JointSample(0, {"thumb_rotation": 0.5}))
    out = c.step(_input(10 * MS, {"thumb_rotation": 2.99}, contact=centred))
    assert c.reason == "joint_limit" and c.stop_ns == 10 * MS and out.command == MotorCommand.of(thumb_rotation=-20.0)
    out = c.step(_input(20 * MS, {"thumb_rotation": 0.52}, contact=centred))
    assert out.done and out.reason == "joint_limit" and out.success


def test_hold_ignores_a_contact_lost_on_both_sides():
    monitor = ContactMonitor(0.8)
    both = monitor.evaluate("thumb", 0, np.array([0.1, 2.0, 0.1, 0.1, 2.0, 0.1, 0.1, 2.0, 0.1], np.float32))
    assert set(both.lost_edges) == {"right", "left"}
    c = HoldController(LIMITS)
    c.start(JointSample(0, {"thumb_rotation": 0.0}))
    out = c.step(_input(10 * MS, {"thumb_rotation": 0.0}, contact=both))
    assert out.phase == "hold" and c.side is None


@pytest.mark.parametrize("motion", ["horizontal", "vertical", "hold"])
def test_a_manipulation_without_contact_ends_no_contact(motion):
    """An untouched pad (its ~0.43 V rest voltages, below the 0.55 V contact floor) is 'safe' by
    Algorithm 1 alone: each motion ends no_contact on the first such sample, unsuccessful, motors
    stopped, instead of sweeping on to a joint limit."""
    monitor = ContactMonitor(0.8, min_mean_voltage=0.55)
    held = monitor.evaluate("thumb", 0, np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], np.float32))
    empty = monitor.evaluate("thumb", 0, np.array(PadParams().rest_volts, np.float32))
    assert empty.mean_voltage == pytest.approx(0.436, abs=1e-3) and not empty.lost_edges  # nothing lost
    cls = {"horizontal": HorizontalController, "vertical": VerticalController, "hold": HoldController}[motion]
    c = cls(LIMITS, contact_voltage=0.55)
    start = {"fingers": 4.0, "thumb_flexion": 3.5, "thumb_rotation": 0.0}
    c.start(JointSample(0, start))
    assert not c.step(_input(10 * MS, start, contact=held)).done
    out = c.step(_input(20 * MS, start, contact=empty))
    assert out.done and out.reason == "no_contact" and not out.success and c.command.is_stop
    assert out.command == (None if motion == "hold" else MotorCommand.stop())  # a hold was not moving
    assert c.stop_ns == 20 * MS and c.events[-2].what == "no_contact:thumb"
