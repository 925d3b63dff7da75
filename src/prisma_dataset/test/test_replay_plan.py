"""replay_plan: the episode a replay plays (read from a dataset written by lerobot_format) and the
steps of a replay, tick by tick, with the instants and frames they must give."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_dataset.cli import main
from prisma_dataset.lerobot_format import Dataset, Episode, Feature, write_dataset
from prisma_dataset.replay_plan import (
    DONE,
    LEAD_IN,
    PLAYING,
    PRIMING,
    STOPPING,
    TAIL,
    WAITING_GOAL,
    CancelGoal,
    Finished,
    Publish,
    ReplayCore,
    ReplayEpisode,
    ReplayError,
    ReplayOptions,
    SendGoal,
    load_episode,
)
from prisma_teleop.teleop_core import RESUME_SAMPLES

MS = 1_000_000
FEATURES = [
    Feature("observation.state", "float32", (6,),
            [f"{m}.pos" for m in MOTOR_NAMES] + [f"{m}.vel" for m in MOTOR_NAMES]),
    Feature("observation.wrench", "float32", (5, 6), ["finger", "axis"]),
    Feature("observation.contact", "float32", (5,), list(FINGERS)),
    Feature("action", "float32", (3,), list(MOTOR_NAMES)),
]


def episode_values(length: int, offset: float) -> dict[str, np.ndarray]:
    k = np.arange(length, dtype=np.float32)
    state = np.zeros((length, 6), np.float32)
    state[:, 0], state[:, 1] = 0.1 * k + offset, 0.05 * k
    wrench = np.zeros((length, 5, 6), np.float32)
    wrench[:, 0, 2], wrench[:, 1, 2] = 0.25 * k, 0.2 * k
    wrench[:, 0, 0] = 9.0  # fx: not the normal force, never read
    contact = np.zeros((length, 5), np.float32)
    contact[2:, :2] = 1.0
    action = np.stack([0.2 * k + offset, 0.1 * k, np.full(length, -0.5, np.float32)], axis=1)
    return {"observation.state": state, "observation.wrench": wrench, "observation.contact": contact,
            "action": action}


@pytest.fixture
def dataset(tmp_path: Path) -> Path:
    episodes = [Episode("pinch the ball", episode_values(4, 0.0)), Episode("open", episode_values(6, 1.0))]
    return write_dataset(tmp_path / "ds", Dataset(50, FEATURES, episodes))


def test_an_episode_is_read_with_its_actions_positions_and_normal_forces(dataset):
    e = load_episode(dataset, 1)
    assert (e.number, e.fps, e.task, e.frames, e.motors) == (1, 50, "open", 6, MOTOR_NAMES)
    assert e.actions[3].tolist() == pytest.approx([1.6, 0.3, -0.5])
    assert e.positions[5].tolist() == pytest.approx([1.5, 0.25, 0.0])  # the positions, not the velocities
    assert e.pad_forces[4].tolist() == pytest.approx([1.0, 0.8, 0.0, 0.0, 0.0])  # fz, not fx
    assert e.contact is not None and e.contact[1].tolist() == [0.0] * 5 and e.contact[2, :2].tolist() == [1.0, 1.0]
    assert e.targets(3) == pytest.approx({"fingers": 1.6, "thumb_flexion": 0.3, "thumb_rotation": -0.5})


@pytest.mark.parametrize("number, says", [(2, "has episodes 0 .. 1"), (7, "has episodes 0 .. 1")])
def test_an_episode_out_of_range_names_the_range(dataset, number, says):
    with pytest.raises(ReplayError, match=f"--episode {number}: the dataset at .* {says}"):
        load_episode(dataset, number)


def test_a_dataset_without_actions_cannot_be_replayed(tmp_path):
    features = [f for f in FEATURES if f.name != "action"]
    values = {k: v for k, v in episode_values(3, 0.0).items() if k != "action"}
    root = write_dataset(tmp_path / "ds", Dataset(50, features, [Episode("t", values)]))
    with pytest.raises(ReplayError, match="has no action: a replay needs the motor targets"):
        load_episode(root, 0)


@pytest.mark.parametrize("speed", [0.0, 0.01, 5.0, float("nan")])
def test_a_speed_out_of_range_is_refused(speed):
    with pytest.raises(ReplayError, match=r"--speed .*: give a factor from 0.05 to 4"):
        ReplayOptions(speed=speed)


def test_the_cli_refuses_an_episode_out_of_range_in_one_line_before_any_ros(dataset, capsys):
    assert main(["replay", str(dataset), "--episode", "2", "--no-plots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--episode 2: the dataset at" in err[0] and "episodes 0 .. 1" in err[0], err
    assert main(["replay", str(dataset), "--episode", "0", "--speed", "9", "--no-plots"]) == 2
    assert "--speed 9.0: give a factor from 0.05 to 4" in capsys.readouterr().err


def test_the_cli_refuses_a_directory_that_is_no_dataset(tmp_path, capsys):
    assert main(["replay", str(tmp_path), "--episode", "0"]) == 2
    assert "is not a LeRobot dataset (no meta/info.json)" in capsys.readouterr().err


def ramp_episode(frames: int = 5, fps: int = 50) -> ReplayEpisode:
    k = np.arange(frames, dtype=np.float64)
    actions = np.stack([0.5 * k, 0.25 * k, np.zeros(frames)], axis=1)
    positions = np.stack([0.4 * k, 0.2 * k, np.zeros(frames)], axis=1)
    return ReplayEpisode(0, fps, "t", actions, positions, np.zeros((frames, 5)), None)


def run_to_playing(core: ReplayCore, t0: int) -> int:
    """Prime, start the goal, settle: the instant playing starts (frame 0 published then)."""
    for i in range(RESUME_SAMPLES):
        steps = core.tick(t0 + i * 20 * MS, None)
        assert isinstance(steps[0], Publish) and steps[0].frame is None
        assert steps[0].targets == core.episode.targets(0)
    assert isinstance(steps[-1], SendGoal) and core.phase == WAITING_GOAL
    core.on_goal_running(t0 + 70 * MS)
    assert core.phase == LEAD_IN
    # the hand stands at frame 0 already, but the lead-in lasts lead_in_s (0.5 s)
    assert core.tick(t0 + 500 * MS, [0.0, 0.0, 0.0]) == [Publish(core.episode.targets(0), None, t0 + 500 * MS)]
    start = t0 + 580 * MS
    steps = core.tick(start, [0.0, 0.0, 0.0])
    assert core.phase == PLAYING and steps == [Publish(core.episode.targets(0), 0, start)]
    return start


def test_a_replay_primes_sends_the_goal_settles_plays_each_frame_on_time_and_cancels():
    core = ReplayCore(ramp_episode())
    assert core.period_ns == 20 * MS
    start = run_to_playing(core, 1_000 * MS)
    # frame k is due k * 20 ms after frame 0; a tick 3 ms early still publishes it
    for k, at in ((1, 17), (2, 40), (3, 61)):
        steps = core.tick(start + at * MS, None)
        assert steps == [Publish(core.episode.targets(k), k, start + at * MS)]
    # a tick before the next frame is due holds the last one (not a frame of its own)
    assert core.tick(start + 62 * MS, None) == [Publish(core.episode.targets(3), None, start + 62 * MS)]
    last = start + 80 * MS
    assert core.tick(last, None) == [Publish(core.episode.targets(4), 4, last)]
    assert core.phase == TAIL
    assert core.published == [(0, start), (1, start + 17 * MS), (2, start + 40 * MS), (3, start + 61 * MS), (4, last)]
    assert core.skipped == 0
    # the tail holds the last action 0.2 s, then the goal is cancelled
    assert core.tick(last + 190 * MS, None) == [Publish(core.episode.targets(4), None, last + 190 * MS)]
    assert core.tick(last + 200 * MS, None) == [CancelGoal("the episode's last frame played")]
    assert core.phase == STOPPING and core.tick(last + 220 * MS, None) == []
    assert core.on_goal_ended("canceled", last + 230 * MS) == [Finished("played every frame", True)]
    assert core.phase == DONE


def test_a_late_tick_publishes_the_frame_due_and_counts_the_ones_it_passed():
    core = ReplayCore(ramp_episode(frames=8))
    start = run_to_playing(core, 0)
    assert core.tick(start + 65 * MS, None) == [Publish(core.episode.targets(3), 3, start + 65 * MS)]
    assert core.skipped == 2  # frames 1 and 2 were never sent
    assert [f for f, _ in core.published] == [0, 3]


def test_half_speed_doubles_the_period():
    core = ReplayCore(ramp_episode(), ReplayOptions(speed=0.5))
    assert core.period_ns == 40 * MS
    start = run_to_playing(core, 0)
    assert core.tick(start + 20 * MS, None) == [Publish(core.episode.targets(0), None, start + 20 * MS)]
    assert core.tick(start + 40 * MS, None)[0].frame == 1


def test_the_lead_in_waits_for_the_hand_at_frame_0_then_plays_on_at_its_timeout():
    episode = ramp_episode()
    core = ReplayCore(episode, ReplayOptions(lead_in_timeout_s=2.0))
    for i in range(RESUME_SAMPLES):
        core.tick(i * 20 * MS, None)
    core.on_goal_running(100 * MS)
    assert core.tick(700 * MS, [0.3, 0.0, 0.0])[0].frame is None  # 0.3 rad off the recorded 0: waits
    assert core.tick(900 * MS, [0.051, 0.0, 0.0])[0].frame is None  # just outside settle_rad 0.05
    assert core.phase == LEAD_IN
    steps = core.tick(2_100 * MS, [0.2, 0.0, 0.0])  # 2 s in the lead-in: plays on, and says so
    assert core.phase == PLAYING and steps[0].frame == 0
    assert core.lead_in_note == ("the hand did not settle at frame 0 in 2 s (0.200 rad from the recorded frame 0); "
                                 "played on")


def test_a_goal_refused_not_ready_is_sent_again_after_the_retry_period():
    core = ReplayCore(ramp_episode())
    for i in range(RESUME_SAMPLES):
        steps = core.tick(i * 20 * MS, None)
    assert isinstance(steps[-1], SendGoal)
    assert core.on_goal_ended("not_ready: no wrench/thumb received yet", 50 * MS) == []
    assert core.phase == PRIMING
    # the targets keep flowing; no goal before 0.5 s after the refusal, then primed again and sent
    sent = []
    for t in range(60, 700, 20):
        steps = core.tick(t * MS, None)
        assert isinstance(steps[0], Publish)
        sent += [t for s in steps if isinstance(s, SendGoal)]
    assert sent == [600]  # 550 ms: the retry instant; then RESUME_SAMPLES (3) ticks of priming: 560, 580, 600


def test_a_goal_ending_on_its_own_ends_the_replay_where_it_was():
    core = ReplayCore(ramp_episode())
    start = run_to_playing(core, 0)
    core.tick(start + 20 * MS, None)
    steps = core.on_goal_ended("input_stale: prisma/teleop/motor_targets silent for 160 ms", start + 30 * MS)
    assert steps == [Finished("the Teleoperate goal ended at frame 1 of 5: input_stale: prisma/teleop/motor_targets "
                              "silent for 160 ms", False)]
    assert core.phase == DONE and core.tick(start + 40 * MS, None) == []
    # a refusal other than not_ready before any frame: over, in the phase it came in
    core = ReplayCore(ramp_episode())
    for i in range(RESUME_SAMPLES):
        core.tick(i * 20 * MS, None)
    assert core.on_goal_ended("not_homed: fingers", 70 * MS) == [
        Finished("the Teleoperate goal ended in the waiting for the goal: not_homed: fingers", False)]


def test_another_publisher_of_the_targets_mid_replay_stops_it_and_cancels_the_goal():
    core = ReplayCore(ramp_episode())
    start = run_to_playing(core, 0)
    core.tick(start + 20 * MS, None)
    why = "stopped at frame 1 of 5: /teleop began publishing the targets"
    assert core.on_other_publisher(["/teleop"]) == [CancelGoal(why)]
    assert core.phase == STOPPING and core.tick(start + 40 * MS, None) == []  # nothing more published
    assert core.on_other_publisher(["/teleop"]) == []  # said once
    assert core.on_goal_ended("canceled", start + 50 * MS) == [Finished(why, False)]
    # before the goal runs: over at once (a goal on its way is cancelled by the node when it arrives)
    core = ReplayCore(ramp_episode())
    core.tick(0, None)
    why = "stopped in the priming: /a, /b began publishing the targets"
    assert core.on_other_publisher(["/a", "/b"]) == [CancelGoal(why), Finished(why, False)]
    assert core.phase == DONE


def test_without_ros_the_cli_says_so_in_one_line(dataset, monkeypatch, capsys):
    # rclpy absent (None in sys.modules makes its import fail), the replay's ROS module not loaded yet
    monkeypatch.setitem(sys.modules, "rclpy", None)
    monkeypatch.delitem(sys.modules, "prisma_dataset.replay_ros", raising=False)
    assert main(["replay", str(dataset), "--episode", "0", "--no-plots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prisma-dataset: error: replay needs ROS 2 (rclpy, prisma_msgs): "), err
