"""The PRISMA Hand II description: xacro -> URDF parsed by urdf_parser_py, its joints and frames, and
its tendon coupling checked against the simulator's hand model by forward kinematics.

Skips without ROS 2 (xacro and urdf_parser_py come with it; fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from prisma_testing.ros_harness import require_ros
from prisma_testing.urdf_kinematics import link_poses

require_ros()

import xacro  # noqa: E402
from urdf_parser_py.urdf import URDF  # noqa: E402

from prisma_common.hand import FINGERS, MOTOR_NAMES, TAXEL_PITCH_M  # noqa: E402
from prisma_hand_sim.hand_world import HandWorldParams  # noqa: E402
from prisma_hand_sim.pad_model import PadParams  # noqa: E402
from prisma_hand_sim.sim_objects import OBJECTS  # noqa: E402
from prisma_motor_driver.backend import DEFAULT_MAX_POSITIONS, DEFAULT_MIN_POSITIONS  # noqa: E402

URDF_XACRO = Path(__file__).resolve().parents[1] / "urdf" / "prisma_hand.urdf.xacro"
PINCH_BALL_DIAMETER_MM = 30.0  # prisma_hand_sim's pinch_ball: a 30 mm foam ball
FINGER_JOINTS = {
    "thumb": ["thumb_opposition", "thumb_cmc", "thumb_mcp", "thumb_ip"],
    "index": ["index_spread", "index_mcp", "index_pip", "index_dip"],
    "middle": ["middle_mcp", "middle_pip", "middle_dip"],
    "ring": ["ring_spread", "ring_mcp", "ring_pip", "ring_dip"],
    "little": ["little_spread", "little_mcp", "little_pip", "little_dip"],
}


def load(prefix: str = "") -> URDF:
    document = xacro.process_file(str(URDF_XACRO), mappings={"prefix": prefix})
    return URDF.from_xml_string(document.toxml())


@pytest.fixture(scope="module")
def robot() -> URDF:
    return load()


def pad(poses: dict[str, np.ndarray], finger: str) -> tuple[np.ndarray, np.ndarray]:
    """Centre (mm) and outward normal of a finger's sensor pad."""
    pose = poses[f"prisma_{finger}_pad"]
    return pose[:3, 3] * 1e3, pose[:3, 2]


def pinch_contact_angles() -> dict[str, float]:
    ball = OBJECTS["pinch_ball"]
    return {"fingers": ball.finger_contact_rad["index"], "thumb_flexion": ball.thumb_contact_rad,
            "thumb_rotation": 0.0}


def test_nineteen_hand_joints_and_three_motor_joints(robot):
    moving = [j for j in robot.joints if j.type != "fixed"]
    motors = [j.name for j in moving if j.mimic is None]
    hand = [j.name for j in moving if j.mimic is not None]
    assert sorted(motors) == sorted(MOTOR_NAMES)
    assert len(hand) == 19
    assert sorted(hand) == sorted(name for names in FINGER_JOINTS.values() for name in names)


def test_every_finger_joint_follows_its_motor(robot):
    joints = {j.name: j for j in robot.joints}
    followed = {name: joints[name].mimic.joint for names in FINGER_JOINTS.values() for name in names}
    assert followed["thumb_opposition"] == "thumb_rotation"
    assert {followed[n] for n in FINGER_JOINTS["thumb"][1:]} == {"thumb_flexion"}
    for finger in ("index", "middle", "ring", "little"):
        assert {followed[n] for n in FINGER_JOINTS[finger]} == {"fingers"}
    for names in FINGER_JOINTS.values():
        for name in names:
            assert joints[name].mimic.multiplier != 0.0, name


def test_motor_joint_limits_are_the_motor_drivers(robot):
    joints = {j.name: j for j in robot.joints}
    for name, lower, upper in zip(MOTOR_NAMES, DEFAULT_MIN_POSITIONS, DEFAULT_MAX_POSITIONS):
        assert (joints[name].limit.lower, joints[name].limit.upper) == (lower, upper)
    # a follower's limits cover what its motor's window drives it through
    for names in FINGER_JOINTS.values():
        for name in names:
            joint = joints[name]
            motor = joints[joint.mimic.joint].limit
            reach = sorted(joint.mimic.multiplier * v for v in (motor.lower, motor.upper))
            assert joint.limit.lower == pytest.approx(reach[0]) and joint.limit.upper == pytest.approx(reach[1])


def test_pads_carry_their_taxel_centres_as_the_messages_number_them(robot):
    poses = link_poses(robot, dict.fromkeys(MOTOR_NAMES, 0.0))
    pitch_m = TAXEL_PITCH_M  # dimensions.xacro's taxel_pitch is this one fact
    assert PadParams().pitch_mm * 1e-3 == pitch_m
    for finger in FINGERS:
        pad_pose = poses[f"prisma_{finger}_pad"]
        for i in range(9):
            row, col = divmod(i, 3)
            local = np.linalg.inv(pad_pose) @ poses[f"prisma_{finger}_taxel_{i}"]
            np.testing.assert_allclose(local[:3, 3], [(col - 1) * pitch_m, (row - 1) * pitch_m, 0.0], atol=1e-12)
            np.testing.assert_allclose(local[:3, :3], np.eye(3), atol=1e-12)


def test_at_the_pinch_balls_contact_angles_thumb_and_index_pads_face_each_other_one_ball_apart(robot):
    poses = link_poses(robot, pinch_contact_angles())
    thumb, thumb_normal = pad(poses, "thumb")
    index, index_normal = pad(poses, "index")
    gap = index - thumb
    assert np.linalg.norm(gap) == pytest.approx(PINCH_BALL_DIAMETER_MM, abs=2.0)
    assert thumb_normal @ index_normal < -0.95  # facing: within 18 degrees of opposite
    assert thumb_normal @ gap / np.linalg.norm(gap) > 0.85  # the index pad lies in front of the thumb pad
    # the open hand is wider than the ball by both pads' travel to it
    open_poses = link_poses(robot, dict.fromkeys(MOTOR_NAMES, 0.0))
    assert np.linalg.norm(pad(open_poses, "index")[0] - pad(open_poses, "thumb")[0]) > 2 * PINCH_BALL_DIAMETER_MM


@pytest.mark.parametrize("finger, motor, travel", [
    ("index", "fingers", HandWorldParams().finger_travel_mm_per_rad),
    ("thumb", "thumb_flexion", HandWorldParams().thumb_travel_mm_per_rad),
])
def test_pad_travel_per_motor_radian_is_the_simulators(robot, finger, motor, travel):
    """Where the pinch closes, a pad moves toward the object (along its own normal) by the
    simulator's travel per motor rad."""
    angles = pinch_contact_angles()
    step = 1e-3
    before = link_poses(robot, angles)
    after = link_poses(robot, {**angles, motor: angles[motor] + step})
    (p0, normal), (p1, _) = pad(before, finger), pad(after, finger)
    velocity = (p1 - p0) / step
    assert np.linalg.norm(velocity) == pytest.approx(travel, rel=0.03)
    assert velocity @ normal / np.linalg.norm(velocity) > 0.98


def test_thumb_rotation_moves_the_thumb_pad_sideways_as_the_simulator(robot):
    """+thumb_rotation moves the thumb pad toward its right side (-x), so the contact moves toward
    its left side and the right column empties first (the horizontal manipulation)."""
    angles = pinch_contact_angles()
    step = 1e-3
    before = link_poses(robot, angles)
    after = link_poses(robot, {**angles, "thumb_rotation": step})
    rotation = before["prisma_thumb_pad"][:3, :3]
    velocity_in_pad = rotation.T @ (pad(after, "thumb")[0] - pad(before, "thumb")[0]) / step
    assert velocity_in_pad[0] == pytest.approx(-HandWorldParams().thumb_lateral_mm_per_rad, abs=0.1)
    assert np.linalg.norm(velocity_in_pad[1:]) < 0.15 * HandWorldParams().thumb_lateral_mm_per_rad


def test_inertial_and_collision_elements_a_simulator_can_load(robot):
    masses = 0.0
    for link in robot.links:
        if link.inertial is not None:
            mass = link.inertial.mass
            inertia = link.inertial.inertia
            matrix = np.array([[inertia.ixx, inertia.ixy, inertia.ixz], [inertia.ixy, inertia.iyy, inertia.iyz],
                               [inertia.ixz, inertia.iyz, inertia.izz]])
            assert mass > 0 and np.all(np.linalg.eigvalsh(matrix) > 0), link.name
            masses += mass
        if link.visual is not None and not link.name.endswith("_spool"):
            assert link.collision is not None, link.name
    for joint in robot.joints:
        if joint.type != "fixed":
            child = next(link for link in robot.links if link.name == joint.child)
            assert child.inertial is not None, f"{joint.name} moves a link without mass"
    assert masses == pytest.approx(0.339, abs=1e-6)  # the paper's hand


def test_prefix_names_every_frame_and_keeps_the_joint_names(robot):
    left = load("left_")
    assert {link.name for link in left.links} == {f"left_{link.name}" for link in robot.links}
    assert {joint.name for joint in left.joints} == {joint.name for joint in robot.joints}
    assert {f"left_prisma_{f}_pad" for f in FINGERS} <= {link.name for link in left.links}
