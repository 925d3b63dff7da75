"""Bags with the teleop node's episode markers -> one episode per marked span, each frame the bag's
value at its grid instant within the span, the task and outcome the markers'; the STAG glove's
pressure sampled with its own max age; a bag without markers refused with how to mark one."""
from __future__ import annotations

import json

import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_dataset.bag_export import MAX_AGE_S, ExportError, ExportOptions, export_bags, record_topics
from prisma_dataset.cli import main
from prisma_dataset.dataset_check import check_dataset
from prisma_dataset.lerobot_format import read_dataset, write_dataset
from prisma_dataset.sampling import NS

HAND_KEYS = ["joint_states", *(f"{kind}/{f}" for kind in ("taxels", "wrench", "contact") for f in FINGERS)]
START_NS = 1_000_000_000  # conftest's bags' first stamp (checked by test_the_bags_start_where_the_spans_count_from)


def two_episodes(mark):
    return (mark("start", 0.1, 0, "pinch the ball"), mark("end", 0.5, 0, "pinch the ball", "success"),
            mark("start", 0.7, 1, "lift the card"), mark("end", 1.3, 1, "lift the card", "failure"))


def test_the_bags_start_where_the_spans_count_from(bag_start_ns):
    assert bag_start_ns == START_NS


def span_grid(recorded, keys, start_s, end_s, fps=50):
    """The grid of a span as the rule has it: from the later of the span's start and the streams'
    first instant, every 1/fps, up to the span's end."""
    first = max(recorded.streams[k][0][0] for k in keys)
    start, end = max(first, START_NS + round(start_s * 1e9)), START_NS + round(end_s * 1e9)
    return [start + k * NS // fps for k in range((end - start) * fps // NS + 1)]


def test_one_episode_per_marked_span_each_frame_the_bags_value_in_its_span(make_bag, mark, tmp_path, capsys):
    recorded = make_bag("marked", seconds=1.5, markers=two_episodes(mark))
    out = tmp_path / "ds"
    assert main(["export", str(recorded.path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    report = check_dataset(out)
    assert report.ok, report.problems
    assert report.info["total_episodes"] == 2 and report.tasks == ["pinch the ball", "lift the card"]
    assert [(e["tasks"], e["outcome"]) for e in report.episodes] == [
        (["pinch the ball"], "success"), (["lift the card"], "failure")]
    keys = [*HAND_KEYS, "motor_targets"]
    for row, (lo, hi) in zip(report.episodes, ((0.1, 0.5), (0.7, 1.3))):
        instants = span_grid(recorded, keys, lo, hi)
        assert row["length"] == len(instants)  # 0.4 s: 21 frames; 0.6 s: 31
        span = slice(row["dataset_from_index"], row["dataset_to_index"])
        for k, t in enumerate(instants):
            np.testing.assert_array_equal(report.frames["action"][span][k],
                                          recorded.at("motor_targets", t).astype(np.float32))
            np.testing.assert_array_equal(report.frames["observation.tactile"][span][k, 2],
                                          recorded.at("taxels/middle", t))
    assert [row["length"] for row in report.episodes] == [21, 31]
    assert "'pinch the ball', success: 21 frames, ended by its end marker" in printed
    assert "outcomes: 1 failure, 1 success" in printed
    assert main(["show", str(out), "--no-plots"]) == 0
    shown = capsys.readouterr().out
    assert "episode 1: 31 frames (0.62 s), task ['lift the card'], failure (let go)" in shown
    assert "outcomes: 1 failure, 1 success" in shown
    # read back for an append: the outcomes stay
    assert [e.outcome for e in read_dataset(out).episodes] == ["success", "failure"]
    notes = json.loads((out / "meta" / "prisma_export.json").read_text())
    assert [e["marked_episode"] for e in notes["episodes"]] == [0, 1]


def test_task_overrides_the_markers_and_whole_bag_ignores_them(make_bag, mark):
    recorded = make_bag("marked_task", seconds=1.5, markers=two_episodes(mark))
    renamed = export_bags([recorded.path], ExportOptions(task="grasp"))
    assert [(e.task, e.outcome) for e in renamed.episodes] == [("grasp", "success"), ("grasp", "failure")]
    whole = export_bags([recorded.path], ExportOptions(whole_bag=True))
    assert [(e.task, e.outcome, e.length) for e in whole.episodes] == [("teleoperate the PRISMA hand", "", 75)]


def test_an_unfinished_episode_a_stale_start_skipped_and_one_without_a_fresh_frame(make_bag, mark):
    markers = (mark("end", 0.05, 3, outcome="success"),  # latched from before the recording: left out
               mark("start", 0.2, 4), mark("start", 0.6, 5))  # 4's end lost; 5 open when the recording stopped
    recorded = make_bag("unfinished", seconds=1.0, markers=markers, gap=("wrench/thumb", 0.1, 0.7))
    said: list[str] = []
    dataset = export_bags([recorded.path], ExportOptions(), progress=said.append)
    # episode 4 (0.2 .. 0.6 s): the thumb's wrench silent throughout: no fresh frame, left out
    assert said[0].startswith(f"bag {recorded.path} episode 4: no frame has every stream within its max age: "
                              "/prisma/thumb/wrench's newest sample was")
    assert said[0].endswith(": left out")
    (episode,) = dataset.episodes
    assert (episode.outcome, episode.notes["outcome_reason"], episode.notes["marked_episode"]) == (
        "unfinished", "the recording ended inside the episode", 5)
    # episode 5 starts at the first frame of its span where the thumb's wrench is fresh again
    keys = [*HAND_KEYS, "motor_targets"]
    last = max(stamp for k in keys for stamp, _ in recorded.streams[k])
    instants = span_grid(recorded, keys, 0.6, (last - START_NS) / 1e9)
    thumb = [stamp for stamp, _ in recorded.streams["wrench/thumb"]]
    fresh = [t for t in instants if t - max(x for x in thumb if x <= t) <= MAX_AGE_S["wrench"] * NS]
    skipped = instants.index(fresh[0])
    assert skipped >= 4 and episode.notes["skipped_start_frames"] == skipped  # 0.6 s .. past 0.7 s
    assert episode.length == len(instants) - skipped
    np.testing.assert_array_equal(episode.values["observation.wrench"][0, 0],
                                  recorded.at("wrench/thumb", fresh[0]).astype(np.float32))


def test_a_bag_without_a_start_marker_or_a_fresh_span_is_refused(make_bag, mark):
    only_end = make_bag("only_end", seconds=0.5, markers=(mark("end", 0.1, 0, outcome="success"),))
    with pytest.raises(ExportError, match=r"has episode markers but no start among them .* or use --whole-bag"):
        export_bags([only_end.path], ExportOptions())
    stale = make_bag("stale", seconds=0.5, markers=(mark("start", 0.1, 0), mark("end", 0.3, 0)),
                     gap=("joint_states", 0.0, 0.4))
    with pytest.raises(ExportError, match=r"none of its 1 marked episodes has a frame with every stream"):
        export_bags([stale.path], ExportOptions())


def test_glove_pressure_sampled_and_held_within_its_max_age(make_bag, tmp_path):
    recorded = make_bag("stag", seconds=2.0, stag=True, shorted=(5,), targets=False)
    root = write_dataset(tmp_path / "ds", export_bags([recorded.path], ExportOptions(whole_bag=True,
                                                                                     action="positions")))
    report = check_dataset(root)
    assert report.ok, report.problems
    feature = report.info["features"]["observation.glove_pressure"]
    assert (feature["dtype"], feature["shape"], feature["names"]) == ("float32", [32, 32], ["row", "col"])
    pressure = report.frames["observation.glove_pressure"]
    keys = [*HAND_KEYS, "glove_pressure"]
    instants = span_grid(recorded, keys, 0.0, 3.0)[:len(pressure)]
    # frame 5 was shorted: the frame before it is held across (274 ms <= 0.3 s), never the short's
    for k, t in enumerate(instants):
        np.testing.assert_array_equal(pressure[k], recorded.at("glove_pressure", t))
    stamps = [stamp for stamp, _ in recorded.streams["glove_pressure"]]
    held_over = [t for t in instants if stamps[4] <= t < stamps[5]]  # recorded frame 5 is the glove's 6th
    assert held_over and all(t - stamps[4] > 137_000_000 for t in held_over[-3:])
    assert MAX_AGE_S["glove_pressure"] == 0.3
    # two shorted frames in a row (411 ms): the episode ends there
    two = make_bag("stag_two", seconds=2.0, stag=True, shorted=(5, 6), targets=False, seed=3)
    (episode,) = export_bags([two.path], ExportOptions(whole_bag=True, action="positions")).episodes
    assert episode.notes["gap"]["stream"] == "/stag/frame"
    assert episode.notes["gap"]["age_s"] > 0.3


def test_a_namespaced_recording_and_the_topics_a_recording_needs(make_bag, mark, capsys):
    recorded = make_bag("left", seconds=1.0, per_hand=True, namespace="left",
                        markers=(mark("start", 0.1, 0), mark("end", 0.5, 0, outcome="success")))
    with pytest.raises(ExportError, match=r"has no episode markers \(/prisma/teleop/episode\)"):
        export_bags([recorded.path], ExportOptions())
    with pytest.raises(ExportError, match=r"has no topic '/joint_states'"):
        export_bags([recorded.path], ExportOptions(whole_bag=True))
    (episode,) = export_bags([recorded.path], ExportOptions(namespace="left")).episodes
    assert (episode.task, episode.outcome, episode.length) == ("pinch the ball", "success", 21)
    assert main(["topics", "--namespace", "left"]) == 0
    assert capsys.readouterr().out.split() == record_topics("left") == [
        "/left/joint_states", "/left/prisma/hand/taxels", "/left/prisma/hand/wrench", "/left/prisma/hand/contact",
        "/left/prisma/teleop/motor_targets", "/left/glove/joint_states", "/left/stag/frame",
        "/left/prisma/teleop/episode"]
    assert record_topics()[0] == "/joint_states"
