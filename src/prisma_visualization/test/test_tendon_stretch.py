"""The fingers under load: motor angle less the tendon stretch, on the shipped description
(xacro -> URDF) with the simulator's tendon stiffness and pad travel.

Skips without ROS 2 (xacro comes with it; fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from prisma_testing.ros_harness import require_ros

require_ros()

import xacro  # noqa: E402
from prisma_visualization.tendon_stretch_core import TendonStretch, forces_at  # noqa: E402

from prisma_common.hand import FINGERS, MOTOR_NAMES  # noqa: E402
from prisma_common.kinematics import RobotModel  # noqa: E402
from prisma_hand_sim.hand_world import HandWorld, HandWorldParams  # noqa: E402
from prisma_hand_sim.sim_objects import OBJECTS  # noqa: E402

URDF_XACRO = Path(__file__).resolve().parents[2] / "prisma_description" / "urdf" / "prisma_hand.urdf.xacro"
PINCH = {"fingers": OBJECTS["pinch_ball"].finger_contact_rad["index"],
         "thumb_flexion": OBJECTS["pinch_ball"].thumb_contact_rad, "thumb_rotation": 0.0}


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel.from_urdf(xacro.process_file(str(URDF_XACRO)).toxml())


@pytest.fixture(scope="module")
def stretch(model) -> TendonStretch:
    return TendonStretch.from_model(model)


def pad_mm(model: RobotModel, positions: dict[str, float], finger: str) -> np.ndarray:
    return model.link_pose(f"prisma_{finger}_pad", positions)[:3, 3] * 1e3


def test_each_finger_is_loaded_through_the_joints_its_tendon_motor_moves(stretch):
    assert {f: [c.joint for c in stretch.loaded[f]] for f in FINGERS} == {
        "thumb": ["thumb_cmc", "thumb_mcp", "thumb_ip"],
        "index": ["index_spread", "index_mcp", "index_pip", "index_dip"],
        "middle": ["middle_mcp", "middle_pip", "middle_dip"],
        "ring": ["ring_spread", "ring_mcp", "ring_pip", "ring_dip"],
        "little": ["little_spread", "little_mcp", "little_pip", "little_dip"]}
    # thumb opposition follows thumb_rotation, which no pad force stretches
    assert [(c.joint, c.motor) for c in stretch.rigid] == [("thumb_opposition", "thumb_rotation")]


def test_one_newton_on_the_index_pad_opens_its_joints_by_the_stretch_through_the_ratios(stretch):
    # 1 N / 0.08 N/mm = 12.5 mm of tendon at the fingertip = 12.5 / 8 mm per rad = 1.5625 rad of the motor
    assert stretch.stretch_rad("index", 1.0) == pytest.approx(1.0 / 0.08 / 8.0) == pytest.approx(1.5625)
    motors = {"fingers": 4.0, "thumb_flexion": 3.0, "thumb_rotation": 0.5}
    rigid, loaded = stretch.joint_positions(motors, {}), stretch.joint_positions(motors, {"index": 1.0})
    opened = {j: rigid[j] - loaded[j] for j in ("index_spread", "index_mcp", "index_pip", "index_dip")}
    # dimensions.xacro: index_spread_ratio -0.012, finger_flexion_ratios 0.0604 0.0681 0.0425 rad per motor rad
    assert opened == pytest.approx({"index_spread": -0.012 * 1.5625, "index_mcp": 0.0604 * 1.5625,
                                    "index_pip": 0.0681 * 1.5625, "index_dip": 0.0425 * 1.5625})
    assert opened["index_mcp"] == pytest.approx(0.0944, abs=1e-4)
    # nothing else moves: the other fingers, the thumb and the motors themselves
    assert {j: v for j, v in loaded.items() if not j.startswith("index_")} == \
        {j: v for j, v in rigid.items() if not j.startswith("index_")}
    assert {m: loaded[m] for m in MOTOR_NAMES} == motors


def test_the_thumb_force_stretches_thumb_flexion_only(stretch):
    motors = {"fingers": 3.5, "thumb_flexion": 3.0, "thumb_rotation": 1.0}
    loaded = stretch.joint_positions(motors, {"thumb": 0.5})
    assert loaded["thumb_cmc"] == pytest.approx(0.0451 * (3.0 - 0.5 / 0.08 / 8.0))
    assert loaded["thumb_opposition"] == pytest.approx(0.0947 * 1.0)


def test_a_loaded_pad_is_drawn_back_by_its_tendon_stretch(model, stretch):
    """Pressed with 1 N, the index pad with its motor 1.5625 rad beyond the pinch contact is where
    the rigid model has it at the contact: the stretch took up the motor's travel."""
    at_contact = pad_mm(model, PINCH, "index")
    beyond = {**PINCH, "fingers": PINCH["fingers"] + stretch.stretch_rad("index", 1.0)}
    assert np.linalg.norm(pad_mm(model, beyond, "index") - at_contact) > 10.0  # rigid: 12.5 mm through the ball
    drawn = pad_mm(model, stretch.joint_positions(beyond, {"index": 1.0}), "index")
    assert np.linalg.norm(drawn - at_contact) < 0.01


def test_a_grasp_in_the_simulated_world_is_drawn_with_the_pads_where_the_world_has_them(model, stretch):
    """The simulator's pinch at its grasp pose: its forces on the description put the thumb and
    index pads as far apart as the world's pads (the ball less what they press into it)."""
    world = HandWorld(obj="pinch_ball")
    pose = world.grasp_pose(1.0)
    world.set_positions(pose)
    forces = world.forces()
    ball = OBJECTS["pinch_ball"]
    squeezed_mm = ball.size_mm[2] - (forces["thumb"] + forces["index"]) / ball.stiffness_n_per_mm
    positions = stretch.joint_positions(pose, forces)
    apart = np.linalg.norm(pad_mm(model, positions, "thumb") - pad_mm(model, positions, "index"))
    assert apart == pytest.approx(squeezed_mm, abs=1.0)
    rigid = stretch.joint_positions(pose, {})
    assert np.linalg.norm(pad_mm(model, rigid, "thumb") - pad_mm(model, rigid, "index")) < 10.0  # through it


@pytest.mark.parametrize("force", [0.0, -0.3, math.nan, math.inf])
def test_no_positive_force_no_stretch(stretch, force):
    assert stretch.stretch_rad("index", force) == 0.0


def test_a_tendon_never_opens_a_finger_past_the_open_hand(stretch):
    angles = stretch.effective_angles({"fingers": 0.5, "thumb_flexion": -0.1, "thumb_rotation": 0.0},
                                      {"index": 2.0, "thumb": 2.0})
    assert angles["index"] == 0.0 and angles["middle"] == 0.5 and angles["thumb"] == -0.1


def test_an_old_force_estimate_counts_as_none():
    latest = {"thumb": (1_000_000_000, 0.9), "index": (1_150_000_000, 0.7)}
    assert forces_at(latest, 1_200_000_000, 100_000_000) == {"index": 0.7}
    assert forces_at(latest, 1_200_000_000, 300_000_000) == {"thumb": 0.9, "index": 0.7}


def test_numbers_come_from_the_simulator(stretch):
    params = HandWorldParams()
    assert stretch.stiffness_n_per_mm == params.tendon_stiffness_n_per_mm
    assert stretch.travel_mm_per_rad == {f: params.pad_travel_mm_per_rad(f) for f in FINGERS}


def test_the_kinematics_are_robot_state_publishers(model):
    """prisma_common.kinematics against the test suite's urdf_parser_py forward kinematics, and a
    joint named in the positions wins over its mimic rule (robot_state_publisher 3.3's insert)."""
    from urdf_parser_py.urdf import URDF

    from prisma_testing.urdf_kinematics import link_poses
    robot = URDF.from_xml_string(xacro.process_file(str(URDF_XACRO)).toxml())
    motors = {"fingers": 2.7, "thumb_flexion": 1.9, "thumb_rotation": -0.8}
    expected = link_poses(robot, motors)
    for finger in FINGERS:
        np.testing.assert_allclose(model.link_pose(f"prisma_{finger}_pad", motors),
                                   expected[f"prisma_{finger}_pad"], atol=1e-12)
    assert model.joint_positions({**motors, "index_mcp": 0.25})["index_mcp"] == 0.25
