"""replay_compare: the replay's samples matched to the recorded frames (sample-and-hold at the
publication instants plus the lag that fits the positions), the per-pad force differences, the
touch-limit check, the position RMS and the verdict, with numbers worked out by hand."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_dataset.replay_compare import (
    ReplayRecording,
    Samples,
    Tolerances,
    compare,
    held_at,
    plot_comparison,
    report_lines,
)
from prisma_dataset.replay_plan import ReplayEpisode

MS = 1_000_000
PERIOD = 20 * MS
FRAMES = 50
T0 = 5_000 * MS  # the replay's frame 0 published here


def test_held_at_takes_the_newest_sample_within_the_max_age():
    stamps = np.array([10, 20, 30], dtype=np.int64) * MS
    values = np.array([1.0, 2.0, 3.0])
    got = held_at(stamps, values, np.array([5, 10, 19, 29, 30, 80, 81], dtype=np.int64) * MS, 50 * MS)
    # before the first sample: none; at a stamp: that sample; 50 ms after the last: still; 51: stale
    assert np.array_equal(got, [np.nan, 1.0, 1.0, 2.0, 3.0, 3.0, np.nan], equal_nan=True)
    assert np.isnan(held_at(np.array([], np.int64), np.empty(0), np.array([1]), 10)).all()


def recorded_episode() -> ReplayEpisode:
    """50 frames at 50 fps: fingers close 0.1 rad a frame; thumb and index press 0.05 N a frame from
    frame 10 on (1.95 N at frame 49); the other pads read 0."""
    k = np.arange(FRAMES, dtype=np.float64)
    positions = np.stack([0.1 * k, 0.08 * k, np.zeros(FRAMES)], axis=1)
    forces = np.zeros((FRAMES, 5))
    forces[:, 0] = forces[:, 1] = np.clip(0.05 * (k - 10), 0.0, 2.0)
    contact = (forces > 0).astype(float)
    return ReplayEpisode(3, 50, "pinch", positions + 0.2, positions, forces, contact)


def replayed(episode: ReplayEpisode, delay_ms: int = 20, force_offset: dict[str, float] | None = None,
             peak: float | None = None, position_offset: float = 0.0, played: bool = True,
             frames: int = FRAMES) -> ReplayRecording:
    """The hand doing exactly what was recorded, `delay_ms` after each frame's publication, sampled
    every 10 ms (as /joint_states and the wrenches at 100 Hz); `position_offset` on thumb_rotation,
    which stands still (an offset on a ramp would be a lag)."""
    published = [(k, T0 + k * PERIOD + (3 * MS if k % 7 == 0 else 0)) for k in range(frames)]  # a few late ticks
    positions, forces, contact = Samples(), {f: Samples() for f in FINGERS}, {f: Samples() for f in FINGERS}
    for step in range(2 * FRAMES + 20):
        t = T0 + step * 10 * MS
        k = min(max((step * 10 - delay_ms) // 20, 0), FRAMES - 1)  # the recorded frame the hand is at
        positions.add(t, episode.positions[k] + [0.0, 0.0, position_offset])
        for f, finger in enumerate(FINGERS):
            value = episode.pad_forces[k, f] + (force_offset or {}).get(finger, 0.0)
            if peak is not None and f == 0 and k == 30:
                value = peak
            forces[finger].add(t, value)
            contact[finger].add(t, episode.contact[k, f])
    outcome = "played every frame" if played else "the Teleoperate goal ended at frame 19 of 50: input_stale: x"
    return ReplayRecording(published, positions, forces, contact, outcome, played,
                           ended_ns=T0 + (frames * PERIOD if played else 20 * PERIOD))


def test_a_faithful_replay_matches_at_the_lag_that_fits_the_positions():
    episode = recorded_episode()
    c = compare(episode, replayed(episode, delay_ms=20), Tolerances(), PERIOD)
    assert c.ok, c.problems
    assert c.lag_s == pytest.approx(0.02)  # the hand 20 ms behind its targets: one frame
    assert (c.frames, c.played_frames) == (50, 50)
    assert c.matched_frames == 50
    assert [p.finger for p in c.pads] == list(FINGERS)
    thumb = c.pads[0]
    assert thumb.max_diff_n == pytest.approx(0.0, abs=1e-9) and thumb.recorded_peak_n == pytest.approx(1.95)
    assert thumb.replayed_peak_n == pytest.approx(1.95) and thumb.contact_agreement == 1.0
    assert c.position_rms_rad == pytest.approx({"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0})


def test_a_pad_pressing_more_than_recorded_fails_naming_it_and_by_how_much():
    episode = recorded_episode()
    c = compare(episode, replayed(episode, force_offset={"index": 0.25, "middle": 0.1}), Tolerances(), PERIOD)
    assert c.pads[1].max_diff_n == pytest.approx(0.25) and c.pads[1].mean_diff_n == pytest.approx(0.25)
    assert c.pads[2].max_diff_n == pytest.approx(0.1)
    # index's recorded peak 1.95 N (frame 49) + 0.25
    assert c.problems == ["index: the replayed force differs from the recording by up to 0.250 N (tolerance 0.2 N)",
                          "index: the replay pressed 2.200 N, above the touch limit 2 N + 0.15 N"]
    assert not c.ok
    lines = "\n".join(report_lines(c, replayed(episode)))
    assert "verdict: 2 problem(s)" in lines and "index: the replay pressed 2.200 N" in lines
    # a looser force tolerance and touch limit pass it
    loose = compare(episode, replayed(episode, force_offset={"index": 0.25}),
                    Tolerances(force_tolerance_n=0.3, touch_limit_n=2.2), PERIOD)
    assert loose.ok and "  verdict: the replay matches the recording" in report_lines(loose, replayed(episode))


def test_a_peak_between_frames_counts_against_the_touch_limit():
    episode = recorded_episode()
    c = compare(episode, replayed(episode, peak=2.2), Tolerances(), PERIOD)
    assert c.pads[0].replayed_peak_n == pytest.approx(2.2)
    assert "thumb: the replay pressed 2.200 N, above the touch limit 2 N + 0.15 N" in c.problems


def test_positions_off_by_more_than_the_tolerance_fail():
    episode = recorded_episode()
    c = compare(episode, replayed(episode, position_offset=0.2), Tolerances(), PERIOD)
    assert c.position_rms_rad["thumb_rotation"] == pytest.approx(0.2) and c.lag_s == pytest.approx(0.02)
    assert c.problems == ["thumb_rotation: position RMS 0.200 rad (tolerance 0.15 rad)"]


def test_a_replay_that_did_not_play_every_frame_fails_and_compares_what_it_played():
    episode = recorded_episode()
    c = compare(episode, replayed(episode, played=False, frames=20), Tolerances(), PERIOD)
    assert c.played_frames == 20 and c.matched_frames == 20
    assert c.problems == ["not every frame played: the Teleoperate goal ended at frame 19 of 50: input_stale: x"]
    assert np.isnan(c.replay_forces[20:]).all() and np.isfinite(c.replay_forces[:20]).all()


def test_nothing_observed_is_no_match():
    episode = recorded_episode()
    nothing = {f: Samples() for f in FINGERS}
    empty = ReplayRecording([(k, T0 + k * PERIOD) for k in range(FRAMES)], Samples(), nothing, nothing,
                            "played every frame", True)
    c = compare(episode, empty, Tolerances(), PERIOD)
    assert c.matched_frames == 0
    assert c.problems == ["no replayed frame had fresh /joint_states and wrenches to compare"]
    assert "matched frames: 0\n" in "\n".join(report_lines(c, empty)) + "\n"


def test_the_plot_is_written(tmp_path):
    episode = recorded_episode()
    recording = replayed(episode)
    c = compare(episode, recording, Tolerances(), PERIOD)
    out = plot_comparison(episode, c, tmp_path / "plots" / "replay.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000
