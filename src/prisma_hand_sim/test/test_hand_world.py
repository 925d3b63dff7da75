"""Hand/world model and its ContactSource: forces with closure, the support letting go, the
contact-source contract and time-driven disturbances."""
from __future__ import annotations

import pytest

from prisma_hand_sim.contact_source import ContactSource, HandWorldContactSource
from prisma_hand_sim.hand_world import Disturbance, HandWorld, HandWorldParams, ObjectPose
from prisma_hand_sim.sim_objects import OBJECTS, released

MS = 1_000_000


def test_force_rises_with_closure_beyond_contact_and_loads_the_motor():
    world = HandWorld(obj=OBJECTS["lateral_card"])
    obj, p = world.obj, world.params
    world.update_joints({"thumb_flexion": obj.thumb_contact_rad - 0.1}, 0)
    assert world.contact("thumb") is None and world.forces()["thumb"] == 0.0
    forces = []
    for extra in (0.5, 1.0, 1.5):
        world.update_joints({"thumb_flexion": obj.thumb_contact_rad + extra}, 0)
        forces.append(world.forces()["thumb"])
    k = world.k
    # thumb pushes the card against a stiff support: F = k*(s - h + u), support gives u = -F/5
    expected = [k * extra * p.thumb_travel_mm_per_rad / (1 + k / obj.fixture_n_per_mm) for extra in (0.5, 1.0, 1.5)]
    assert forces == pytest.approx(expected, rel=1e-9)
    assert world.motor_loads()["thumb_flexion"] == pytest.approx(forces[-1] * p.load_nm_per_n)


def test_support_lets_go_once_the_pinch_holds_and_forces_balance():
    world = HandWorld()  # default: pinch ball presented by a hand that lets go
    pose = world.grasp_pose(1.0)
    world.update_joints({"fingers": pose["fingers"], "thumb_flexion": pose["thumb_flexion"] - 0.6}, 0)
    held = world.forces()
    assert held["index"] > held["thumb"] + 0.25  # the support takes the difference
    world.update_joints({}, 100 * MS)  # held from here
    world.update_joints({}, 500 * MS)
    assert world.state.fixture_n_per_mm == world.obj.fixture_n_per_mm  # not yet: needs 0.5 s held
    world.update_joints({}, 600 * MS)  # lets go, fading with 0.2 s
    world.update_joints({}, 3000 * MS)
    balanced = world.forces()
    assert balanced["index"] == pytest.approx(balanced["thumb"], abs=0.03)  # residual support only


def test_contact_source_contract_and_time_driven_disturbance():
    source = HandWorldContactSource()
    assert isinstance(source, ContactSource)
    assert source.contact("thumb", 0) is None  # open hand
    pose = source.world.grasp_pose(1.0)
    source.update_joints(list(pose), list(pose.values()), 10 * MS)
    c = source.contact("thumb", 10 * MS)
    assert c is not None and c.normal_n > 0.3
    # foreign /joint_states samples (names without positions, an arm's joints) change nothing
    before = dict(source.world.positions)
    assert source.update_joints(["fingers", "thumb_flexion"], [1.0], 20 * MS) is False
    assert source.update_joints(["elbow", "wrist"], [], 30 * MS) is False
    assert source.update_joints(["elbow", "wrist"], [0.5, 0.7], 40 * MS) is False
    assert source.world.positions == before and source._last_ns == 10 * MS
    assert source.contact("thumb", 10 * MS) == c
    world = HandWorld(obj=released("pinch_ball"), disturbances=[Disturbance(0.1, 0.1, dx_mm=-9.0)])
    world.set_positions(world.grasp_pose(1.0))
    source = HandWorldContactSource(world)
    source.update_joints(list(world.positions), list(world.positions.values()), 0)
    assert source.contact("thumb", 50 * MS).x_mm == 0.0
    assert source.contact("thumb", 150 * MS).x_mm == pytest.approx(-4.5)  # half-way through the push
    assert source.contact("thumb", 300 * MS) is None  # slipped off the 14 mm pad


def test_replace_object_puts_a_rolled_object_back_under_the_thumb_pad_middle():
    world = HandWorld(obj="pinch_ball")
    pose = world.grasp_pose(1.0)
    world.update_joints(pose, 0)
    assert world.contact("thumb").x_mm == pytest.approx(0.0)
    with pytest.raises(ValueError, match="while index, thumb touch it: open the hand first"):
        world.replace_object()
    for step in range(1, 101):  # a horizontal manipulation: the ball rolls toward the pad's edge
        world.update_joints({"thumb_rotation": step * 0.01}, step * 10 * MS)
    rolled_x = world.contact("thumb").x_mm
    assert rolled_x == pytest.approx(3.0)
    open_hand = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
    world.update_joints(open_hand, 3000 * MS)
    world.update_joints(pose, 3010 * MS)
    # the ball stayed where it rolled to while the thumb turned back: it meets the pad off-centre
    assert world.contact("thumb").x_mm == pytest.approx(-3.0)

    world.update_joints(open_hand, 3020 * MS)
    assert "re-placed" in world.replace_object()
    world.update_joints(pose, 3030 * MS)
    assert world.contact("thumb").x_mm == pytest.approx(0.0, abs=1e-9)
    assert world.forces()["thumb"] == pytest.approx(1.0, rel=0.01)


def test_an_empty_hand_has_no_object_to_put_back():
    world = HandWorld(obj="none")
    with pytest.raises(ValueError) as refused:
        world.replace_object()
    assert str(refused.value) == ("no object to put back: the hand is empty (object 'none'); start it with one: "
                                  "sim_object:=pinch_ball|power_ball|lateral_card")


def test_object_pose_the_ball_between_the_pads_squeezed_by_their_forces():
    world = HandWorld(obj="pinch_ball")
    ball = OBJECTS["pinch_ball"]
    assert world.object_pose() == ObjectPose("sphere", (0.0, 0.0, 15.0), (30.0, 30.0, 30.0))
    world.set_positions(world.grasp_pose(1.0))
    pose = world.object_pose()
    f = world.state.finger_forces
    travel = HandWorldParams().thumb_travel_mm_per_rad
    thumb_pad = world.state.pad_positions_mm["thumb"] - travel * ball.thumb_contact_rad
    # the thumb pad is where the object's thumb side is; the z size is the ball less both indentations
    assert pose.centre_mm[2] - pose.size_mm[2] / 2 == pytest.approx(thumb_pad)
    assert pose.size_mm[2] == pytest.approx(30.0 - (f["thumb"] + f["index"]) / ball.stiffness_n_per_mm)
    assert pose.size_mm[2] == pytest.approx(25.0, abs=0.5)  # 1 N on each pad: 2.5 mm into the 0.4 N/mm foam each


def test_object_pose_none_for_an_empty_hand_and_a_box_for_the_card():
    assert HandWorld(obj="none").object_pose() is None
    assert HandWorld(obj="lateral_card").object_pose().shape == "box"
