"""The STAG pose table with its hysteresis: every class glove_perception knows is in it, a pose held
N frames starts its grasp, a one-frame flicker starts nothing, the empty hand opens, the pressure
sets the force."""
from __future__ import annotations

import json

import pytest

from prisma_teleop.stag_poses import (
    IGNORED_POSES,
    POSE_GRASPS,
    GraspCommand,
    OpenCommand,
    PoseMapper,
    PoseMapping,
)
from prisma_testing.repo_paths import CONFIG

PRESSED = 30.0  # a grasp's total pressure: 0.4 + (30 - 5) / 60 x 1.6 = 1.067 N


def feed(mapper: PoseMapper, labels: list[str], confidence: float = 0.99, pressure: float = PRESSED) -> list:
    """The commands the frames start, with the frame index each started on."""
    return [(i, c) for i, label in enumerate(labels) if (c := mapper.update(label, confidence, pressure)) is not None]


def test_the_table_covers_every_class_the_pose_bundle_publishes():
    labels = json.loads((CONFIG / "models" / "glove_pose" / "metadata.json").read_text())["labels"]
    assert sorted(labels) == sorted([*POSE_GRASPS, *IGNORED_POSES])
    assert POSE_GRASPS == {"pinch": "pinch", "tripod": "pinch", "lateral": "lateral", "power": "power",
                           "spherical": "power", "hook": "power", "empty": None}


@pytest.mark.parametrize("pose,grasp", [("pinch", "pinch"), ("tripod", "pinch"), ("lateral", "lateral"),
                                        ("power", "power"), ("spherical", "power"), ("hook", "power")])
def test_a_pose_held_n_frames_starts_its_grasp(pose, grasp):
    mapper = PoseMapper(PoseMapping(frames=3))
    ((index, command),) = feed(mapper, [pose] * 6)
    assert index == 2  # on the third frame in a row, once
    assert command == GraspCommand(grasp, pytest.approx(1.0667, abs=1e-3), pytest.approx(1.3333, abs=1e-3), pose)


def test_a_one_frame_flicker_starts_nothing():
    mapper = PoseMapper(PoseMapping(frames=3))
    started = feed(mapper, ["pinch"] * 4 + ["power"] + ["pinch"] * 3 + ["lateral", "lateral", "pinch"] * 3)
    assert [(i, c.grasp) for i, c in started] == [(2, "pinch")]  # power once, lateral twice: never three in a row
    assert mapper.current.grasp == "pinch"


def test_a_different_pose_must_hold_n_frames_to_switch():
    mapper = PoseMapper(PoseMapping(frames=3))
    started = feed(mapper, ["pinch"] * 3 + ["power"] * 2 + ["pinch"] + ["power"] * 3)
    assert [(i, c.grasp) for i, c in started] == [(2, "pinch"), (8, "power")]


def test_a_frame_below_the_confidence_breaks_the_run():
    mapper = PoseMapper(PoseMapping(frames=3, min_confidence=0.6))
    assert mapper.update("pinch", 0.9, PRESSED) is None
    assert mapper.update("pinch", 0.9, PRESSED) is None
    assert mapper.update("pinch", 0.5, PRESSED) is None  # not counted, and the run starts over
    assert mapper.update("pinch", 0.9, PRESSED) is None
    assert mapper.update("pinch", 0.9, PRESSED) is None
    assert isinstance(mapper.update("pinch", 0.9, PRESSED), GraspCommand)


def test_another_class_of_the_same_grasp_starts_nothing_new():
    mapper = PoseMapper(PoseMapping(frames=2))
    started = feed(mapper, ["pinch"] * 2 + ["tripod"] * 4 + ["point"] * 3 + ["pinch"] * 3)
    assert [(i, c.grasp, c.pose) for i, c in started] == [(1, "pinch", "pinch")]


def test_the_empty_hand_opens_by_its_class_or_its_pressure():
    mapper = PoseMapper(PoseMapping(frames=3, empty_pressure=4.0))
    started = feed(mapper, ["power"] * 3 + ["empty"] * 3)
    assert [type(c) for _, c in started] == [GraspCommand, OpenCommand]
    by_pressure = PoseMapper(PoseMapping(frames=3, empty_pressure=4.0))
    feed(by_pressure, ["hook"] * 3)
    # the classifier still says hook, but the glove presses nothing: the hand holds nothing
    started = feed(by_pressure, ["hook"] * 3, pressure=2.0)
    assert [(i, c) for i, c in started] == [(2, OpenCommand("empty"))]


def test_the_pressure_sets_the_force_within_its_range():
    m = PoseMapping(pressure_low=5.0, pressure_high=65.0, min_force=0.4, max_force=2.0, thumb_force_ratio=1.25)
    assert [m.force(p) for p in (0.0, 5.0, 35.0, 65.0, 500.0)] == pytest.approx([0.4, 0.4, 1.2, 2.0, 2.0])
    mapper = PoseMapper(PoseMapping(frames=3))
    mapper.update("power", 0.9, 20.0)
    mapper.update("power", 0.9, 50.0)
    command = mapper.update("power", 0.9, 65.0)  # the run's mean pressure, 45: 0.4 + 40 / 60 x 1.6
    assert (command.finger_force, command.thumb_force) == pytest.approx((1.4667, 1.8333), abs=1e-4)


def test_settings_are_checked():
    with pytest.raises(ValueError, match="pressure_low 9 must be below pressure_high 9"):
        PoseMapping(pressure_low=9, pressure_high=9)
    with pytest.raises(ValueError, match="frames 0 must be >= 1"):
        PoseMapping(frames=0)
