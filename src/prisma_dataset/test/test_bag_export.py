"""Bags -> dataset: every frame read back equals the bag's value at its grid instant; a gap ends the
episode and the summary says so; append; nothing half-written; the errors a user meets."""
from __future__ import annotations

import os

import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_dataset.bag_export import ExportError, ExportOptions, export_bags
from prisma_dataset.cli import main
from prisma_dataset.dataset_check import check_dataset
from prisma_dataset.lerobot_format import write_dataset
from prisma_dataset.sampling import NS

HAND_KEYS = ["joint_states", *(f"{kind}/{f}" for kind in ("taxels", "wrench", "contact") for f in FINGERS)]


def grid_of(recorded, keys, frames, fps=50):
    start = max(recorded.streams[k][0][0] for k in keys)
    return [start + k * NS // fps for k in range(frames)]


@pytest.mark.parametrize("per_hand", [False, True], ids=["per-finger topics", "per-hand topics"])
def test_every_frame_equals_the_bags_value_at_its_grid_instant(make_bag, tmp_path, per_hand):
    recorded = make_bag(f"round_trip_{per_hand}", seconds=1.0, glove=True, per_hand=per_hand)
    root = write_dataset(tmp_path / "ds", export_bags([recorded.path], ExportOptions(whole_bag=True)))
    report = check_dataset(root)
    assert report.ok, report.problems
    frames = report.frames
    n = report.info["total_frames"]
    keys = [*HAND_KEYS, "motor_targets", "glove"]
    instants = grid_of(recorded, keys, n)
    # the grid runs from the latest first stamp to the last stamp of the bag: 1 s at 50 fps
    last = max(stamp for k in keys for stamp, _ in recorded.streams[k])
    assert instants[-1] <= last < instants[-1] + NS // 50
    assert n == 50  # (last - start) = 0.98 s of this seed's stamps: frames at 0, 20, ..., 980 ms
    for k, t in enumerate(instants):
        state = recorded.at("joint_states", t)
        np.testing.assert_array_equal(frames["observation.state"][k, :3], state[:3].astype(np.float32))
        # velocities go rad/s -> rpm -> rad/s through the converter: equal to float32 rounding
        np.testing.assert_allclose(frames["observation.state"][k, 3:], state[3:], rtol=1e-6)
        for f, finger in enumerate(FINGERS):
            np.testing.assert_array_equal(frames["observation.tactile"][k, f], recorded.at(f"taxels/{finger}", t))
            np.testing.assert_array_equal(frames["observation.wrench"][k, f],
                                          recorded.at(f"wrench/{finger}", t).astype(np.float32))
            assert frames["observation.contact"][k, f] == recorded.at(f"contact/{finger}", t)
        np.testing.assert_array_equal(frames["action"][k], recorded.at("motor_targets", t).astype(np.float32))
        np.testing.assert_array_equal(frames["observation.glove_pose"][k], recorded.at("glove", t).astype(np.float32))
    # some pads were in contact and some not: the feature is not constant
    assert 0 < frames["observation.contact"].mean() < 1
    features = report.info["features"]
    assert features["observation.state"]["names"] == ["fingers.pos", "thumb_flexion.pos", "thumb_rotation.pos",
                                                      "fingers.vel", "thumb_flexion.vel", "thumb_rotation.vel"]
    assert features["observation.tactile"]["shape"] == [5, 3, 3]
    assert features["observation.wrench"]["shape"] == [5, 6]
    assert features["observation.glove_pose"]["names"] == ["index_mcp", "thumb_cmc_flexion"]
    assert features["action"]["names"] == ["fingers", "thumb_flexion", "thumb_rotation"]


def test_positions_as_action_take_the_next_frames_positions(make_bag, tmp_path):
    recorded = make_bag("no_teleop", seconds=0.5, targets=False)
    with pytest.raises(ExportError, match=r"no topic '/prisma/teleop/motor_targets' \(the action.*--action positions"):
        export_bags([recorded.path], ExportOptions(whole_bag=True))
    root = write_dataset(tmp_path / "ds", export_bags([recorded.path], ExportOptions(whole_bag=True,
                                                                                     action="positions")))
    report = check_dataset(root)
    assert report.ok, report.problems
    state, action = report.frames["observation.state"], report.frames["action"]
    n = len(state)
    # the last grid frame has no next one and is dropped: the frames kept are the grid's first n
    instants = grid_of(recorded, HAND_KEYS, n + 1)
    np.testing.assert_array_equal(action, np.array([recorded.at("joint_states", t)[:3] for t in instants[1:]],
                                                   dtype=np.float32))
    np.testing.assert_array_equal(action[:-1], state[1:, :3])


def test_a_gap_ends_the_episode_and_the_summary_says_so(make_bag, tmp_path, capsys):
    recorded = make_bag("gap", seconds=1.0, gap=("wrench/ring", 0.4, 0.6))
    out = tmp_path / "ds"
    assert main(["export", str(recorded.path), "--whole-bag", "--out", str(out), "--task", "pinch the ball"]) == 0
    printed = capsys.readouterr().out
    report = check_dataset(out)
    assert report.ok, report.problems
    ring = [stamp for stamp, _ in recorded.streams["wrench/ring"]]
    last_ring = ring[int(np.argmax(np.diff(ring)))]  # the ring wrench's last sample before its silence
    instants = grid_of(recorded, [*HAND_KEYS, "motor_targets"], 60)
    stale = next(t for t in instants if t - last_ring > 50_000_000)
    assert report.info["total_frames"] == instants.index(stale)
    assert "ended by a gap: /prisma/ring/wrench's newest sample was" in printed
    assert "(max age 0.050 s)" in printed and "s of the bag dropped" in printed
    assert "gaps that ended episodes: 1" in printed
    assert main(["show", str(out), "--plots", str(tmp_path / "plots")]) == 0
    shown = capsys.readouterr().out
    assert "task 0: pinch the ball" in shown and "gaps that ended episodes: 1" in shown
    assert "invariants: all hold" in shown
    assert (tmp_path / "plots" / "episode_000.png").stat().st_size > 10_000


def test_append_adds_episodes_and_a_failed_export_leaves_the_dataset_as_it_was(make_bag, tmp_path, capsys):
    first, second = make_bag("a", seconds=0.4, seed=1), make_bag("b", seconds=0.6, seed=2)
    no_targets = make_bag("c", seconds=0.4, targets=False, seed=3)
    out = tmp_path / "ds"
    assert main(["export", str(first.path), "--whole-bag", "--out", str(out)]) == 0
    frames_first = check_dataset(out).info["total_frames"]
    assert main(["export", str(second.path), "--whole-bag", "--out", str(out), "--append", "--task", "fist"]) == 0
    report = check_dataset(out)
    assert report.ok, report.problems
    assert report.info["total_episodes"] == 2 and report.tasks == ["teleoperate the PRISMA hand", "fist"]
    assert report.episodes[1]["dataset_from_index"] == frames_first
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    # the second bag lacks the targets: refused before anything is read or written
    assert main(["export", str(first.path), str(no_targets.path), "--whole-bag", "--out", str(out), "--append"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/prisma/teleop/motor_targets" in err and str(no_targets.path) in err
    # at another fps: refused
    assert main(["export", str(first.path), "--whole-bag", "--out", str(out), "--append", "--fps", "25"]) == 2
    assert "at 50 fps; export with --fps 50" in capsys.readouterr().err
    # without --append an existing dataset is not replaced
    assert main(["export", str(first.path), "--whole-bag", "--out", str(out)]) == 2
    assert "already holds a dataset; add --append" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert sorted(os.listdir(tmp_path)) == ["ds"]


def test_bad_input_names_the_problem(make_bag, tmp_path, capsys):
    recorded = make_bag("plain", seconds=0.3)
    assert main(["export", str(recorded.path), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "has no episode markers (/prisma/teleop/episode)" in err and "or export the bag as one episode with " \
        "--whole-bag" in err
    assert "ros2 service call /teleop/mark_episode prisma_msgs/srv/MarkEpisode" in err
    foreign = tmp_path / "thesis"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("mine")
    assert main(["export", str(recorded.path), "--whole-bag", "--out", str(foreign)]) == 2
    assert "not a LeRobot dataset" in capsys.readouterr().err
    assert main(["show", str(foreign)]) == 2
    assert "is not a LeRobot dataset (no meta/info.json)" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_bags_with_other_features_are_not_mixed_and_show_takes_one_episode(make_bag, tmp_path, capsys):
    with_glove, without = make_bag("glove_on", seconds=0.3, glove=True), make_bag("glove_off", seconds=0.3)
    with pytest.raises(ExportError, match=rf"bag {without.path} records other features than {with_glove.path} "
                                          r"\(without observation.glove_pose\)"):
        export_bags([with_glove.path, without.path], ExportOptions(whole_bag=True))
    out = tmp_path / "ds"
    assert main(["export", str(without.path), str(without.path), "--whole-bag", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["show", str(out), "--episode", "1", "--no-plots"]) == 0
    shown = capsys.readouterr().out
    assert "episode 1:" in shown and "episode 0:" not in shown
    assert main(["show", str(out), "--episode", "2"]) == 2
    assert "--episode 2: the dataset has episodes 0 .. 1" in capsys.readouterr().err


def test_show_exits_1_and_draws_nothing_for_a_broken_dataset(make_bag, tmp_path, capsys):
    out = tmp_path / "ds"
    assert main(["export", str(make_bag("shown", seconds=0.3).path), "--whole-bag", "--out", str(out)]) == 0
    info = out / "meta" / "info.json"
    info.write_text(info.read_text().replace('"total_frames": ', '"total_frames": 1'))
    capsys.readouterr()
    assert main(["show", str(out), "--plots", str(tmp_path / "plots")]) == 1
    shown = capsys.readouterr().out
    assert "invariants: 1 broken" in shown and "the data files hold" in shown
    assert "no plots: the dataset breaks the invariants above" in shown
    assert not (tmp_path / "plots").exists()
