"""The LeRobot v3.0 writer and the loader's-view checker: every invariant on a written dataset with
real numbers, and the checker catching each one broken by hand."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from prisma_dataset.dataset_check import check_dataset
from prisma_dataset.lerobot_format import (
    DATA_PATH,
    EPISODES_PATH,
    STATS_PATH,
    TASKS_PATH,
    Dataset,
    DatasetFormatError,
    Episode,
    Feature,
    append_episodes,
    read_dataset,
    write_dataset,
)

FEATURES = [
    Feature("observation.state", "float32", (2,), ["a.pos", "a.vel"]),
    Feature("observation.tactile", "float32", (2, 3, 3), ["finger", "row", "col"]),
    Feature("action", "float32", (1,), ["a"]),
]


def episode(task: str, length: int, offset: float) -> Episode:
    k = np.arange(length, dtype=np.float32)
    return Episode(task, {
        "observation.state": np.stack([k + offset, -k], axis=1),
        "observation.tactile": (np.arange(length * 18, dtype=np.float32).reshape(length, 2, 3, 3) + offset),
        "action": (k * 0.5 + offset).reshape(length),
    }, {"source": f"bag{offset:g}"})


def dataset(lengths=(3, 4, 2), tasks=("pinch", "fist", "pinch"), **options) -> Dataset:
    return Dataset(50, FEATURES, [episode(t, n, 10.0 * i) for i, (t, n) in enumerate(zip(tasks, lengths))],
                   export_notes={"tool": "test"}, **options)


@pytest.fixture
def written(tmp_path) -> Path:
    return write_dataset(tmp_path / "ds", dataset())


def test_info_json_fields_and_types(written):
    info = json.loads((written / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    assert (info["fps"], info["total_episodes"], info["total_frames"], info["total_tasks"]) == (50, 3, 9, 2)
    assert (info["chunks_size"], info["data_files_size_in_mb"]) == (1000, 100)
    assert info["splits"] == {"train": "0:3"}
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["features"]["observation.tactile"] == {"dtype": "float32", "shape": [2, 3, 3],
                                                       "names": ["finger", "row", "col"]}
    assert list(info["features"]) == ["observation.state", "observation.tactile", "action", "timestamp",
                                      "frame_index", "episode_index", "index", "task_index"]
    assert info["features"]["timestamp"] == {"dtype": "float32", "shape": [1], "names": None}
    assert info["features"]["index"] == {"dtype": "int64", "shape": [1], "names": None}
    assert check_dataset(written).ok, check_dataset(written).problems


def test_frames_columns_index_and_timestamps(written):
    table = pq.read_table(written / DATA_PATH.format(chunk_index=0, file_index=0))
    assert table.schema.field("observation.tactile").type == pa.list_(pa.list_(pa.list_(pa.float32(), 3), 3), 2)
    assert table.schema.field("action").type == pa.float32()  # shape (1,): a plain column
    assert table.column("index").to_pylist() == list(range(9))
    assert table.column("episode_index").to_pylist() == [0, 0, 0, 1, 1, 1, 1, 2, 2]
    assert table.column("frame_index").to_pylist() == [0, 1, 2, 0, 1, 2, 3, 0, 1]
    assert table.column("task_index").to_pylist() == [0, 0, 0, 1, 1, 1, 1, 0, 0]
    assert table.column("timestamp").to_numpy().tolist() == [np.float32(k / 50) for k in [0, 1, 2, 0, 1, 2, 3, 0, 1]]
    assert table.column("observation.state").to_pylist()[4] == [11.0, -1.0]
    assert table.column("observation.tactile").to_pylist()[3][1][2] == [25.0, 26.0, 27.0]  # 10 + 9 + 3 * row 2


def test_tasks_are_indexed_by_task(written):
    table = pq.read_table(written / TASKS_PATH)
    assert table.column("task").to_pylist() == ["pinch", "fist"]
    assert table.column("task_index").to_pylist() == [0, 1]
    assert json.loads(table.schema.metadata[b"pandas"])["index_columns"] == ["task"]


def test_episode_rows_locate_their_frames_and_carry_their_stats(written):
    rows = pq.read_table(written / EPISODES_PATH.format(chunk_index=0, file_index=0)).to_pylist()
    assert [(r["episode_index"], r["dataset_from_index"], r["dataset_to_index"], r["length"]) for r in rows] == \
        [(0, 0, 3, 3), (1, 3, 7, 4), (2, 7, 9, 2)]
    assert [r["tasks"] for r in rows] == [["pinch"], ["fist"], ["pinch"]]
    assert {(r["data/chunk_index"], r["data/file_index"]) for r in rows} == {(0, 0)}
    second = rows[1]
    assert second["stats/observation.state/min"] == [10.0, -3.0]
    assert second["stats/observation.state/max"] == [13.0, 0.0]
    assert second["stats/observation.state/mean"] == [11.5, -1.5]
    assert second["stats/observation.state/std"] == pytest.approx([np.sqrt(1.25)] * 2)
    assert second["stats/observation.state/count"] == [4]
    assert second["stats/observation.state/q50"] == [11.5, -1.5]
    assert second["stats/action/max"] == [11.5]
    assert second["stats/frame_index/q99"] == pytest.approx([2.97])
    assert np.asarray(second["stats/observation.tactile/min"]).shape == (2, 3, 3)


def test_stats_json_covers_every_frame(written):
    stats = json.loads((written / STATS_PATH).read_text())
    assert stats["action"]["count"] == [9]
    assert stats["action"]["min"] == [0.0] and stats["action"]["max"] == [20.5]
    assert stats["index"]["mean"] == [4.0]
    assert set(stats["observation.tactile"]) == {"min", "max", "mean", "std", "count", "q01", "q10", "q50", "q90",
                                                 "q99"}


def test_read_back_and_append_keep_every_frame(written):
    back = read_dataset(written)
    assert back.features == FEATURES and back.fps == 50
    assert [e.length for e in back.episodes] == [3, 4, 2]
    assert back.episodes[2].notes == {"source": "bag20"}
    np.testing.assert_array_equal(back.episodes[1].values["observation.tactile"],
                                  episode("fist", 4, 10.0).values["observation.tactile"])
    more = Dataset(50, FEATURES, [episode("wave", 5, 30.0)], export_notes={"tool": "test"})
    write_dataset(written, append_episodes(back, more))
    report = check_dataset(written)
    assert report.ok, report.problems
    assert report.info["total_episodes"] == 4 and report.info["total_frames"] == 14
    assert report.tasks == ["pinch", "fist", "wave"]
    assert report.frames["index"].tolist() == list(range(14))
    with pytest.raises(DatasetFormatError, match="at 50 fps, the new episodes at 30 fps"):
        append_episodes(back, Dataset(30, FEATURES, [episode("x", 2, 0.0)]))
    with pytest.raises(DatasetFormatError, match="differ from the dataset's in action"):
        append_episodes(back, Dataset(50, [*FEATURES[:2], Feature("action", "float32", (1,), ["b"])],
                                      [episode("x", 2, 0.0)]))


def test_episodes_roll_over_into_new_data_files_never_split(tmp_path):
    # 1 MB files, frames of ~1 kB: 3 episodes of 400 frames, two fit a file
    big = [Feature("observation.x", "float32", (250,), None)]
    episodes = [Episode("t", {"observation.x": np.full((400, 250), i, np.float32)}) for i in range(3)]
    root = write_dataset(tmp_path / "ds", Dataset(50, big, episodes, data_files_size_in_mb=1))
    report = check_dataset(root)
    assert report.ok, report.problems
    assert [(r["data/chunk_index"], r["data/file_index"]) for r in report.episodes] == [(0, 0), (0, 0), (0, 1)]
    assert (root / "data/chunk-000/file-001.parquet").is_file()


def test_nothing_is_left_when_writing_fails(tmp_path, monkeypatch):
    target = tmp_path / "ds"
    write_dataset(target, dataset())
    before = sorted(p.relative_to(target) for p in target.rglob("*"))
    import prisma_dataset.lerobot_format as fmt

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(fmt.pq, "write_table", fail)
    with pytest.raises(OSError, match="No space left"):
        write_dataset(target, dataset((5, 5), ("a", "b")))
    assert sorted(p.relative_to(target) for p in target.rglob("*")) == before  # the old dataset, untouched
    assert check_dataset(target).info["total_frames"] == 9
    assert os.listdir(tmp_path) == ["ds"]  # no staging directory left
    with pytest.raises(DatasetFormatError, match="episode 1 has no frames"):
        write_dataset(tmp_path / "new", dataset((2, 0), ("a", "b")))
    assert not (tmp_path / "new").exists()


def test_a_bad_dataset_is_refused_before_anything_is_written(tmp_path):
    bad_shape = Dataset(50, FEATURES, [Episode("t", {**episode("t", 2, 0).values,
                                                     "observation.state": np.zeros((2, 3), np.float32)})])
    with pytest.raises(DatasetFormatError, match=r"observation.state: frames of shape \(3,\), info says \(2,\)"):
        write_dataset(tmp_path / "a", bad_shape)
    with pytest.raises(DatasetFormatError, match="fps 0"):
        write_dataset(tmp_path / "b", Dataset(0, FEATURES, [episode("t", 2, 0)]))
    clash = Dataset(50, [Feature("index", "float32", (1,))], [Episode("t", {"index": np.zeros(2, np.float32)})])
    with pytest.raises(DatasetFormatError, match="not LeRobot's index columns"):
        write_dataset(tmp_path / "c", clash)
    assert os.listdir(tmp_path) == []


# ---------------------------------------------------------------- the checker finds each broken invariant

def rewrite_info(root: Path, **changes) -> None:
    info = json.loads((root / "meta/info.json").read_text())
    info.update(changes)
    (root / "meta/info.json").write_text(json.dumps(info))


def rewrite_column(path: Path, name: str, values: list) -> None:
    table = pq.read_table(path)
    column = table.schema.get_field_index(name)
    pq.write_table(table.set_column(column, name, pa.array(values, table.schema.field(name).type)), path)


DATA = DATA_PATH.format(chunk_index=0, file_index=0)
EPISODES = EPISODES_PATH.format(chunk_index=0, file_index=0)
BREAKS = {
    "codebase_version": (lambda r: rewrite_info(r, codebase_version="v2.1"), "codebase_version 'v2.1'"),
    "fps type": (lambda r: rewrite_info(r, fps=50.0), "'fps' is float, expected int"),
    "splits": (lambda r: rewrite_info(r, splits={"train": "0:2"}), "splits"),
    "total_frames": (lambda r: rewrite_info(r, total_frames=10), "total_frames 10, the data files hold 9"),
    "feature shape": (lambda r: rewrite_info(r, features={
        **json.loads((r / "meta/info.json").read_text())["features"],
        "observation.state": {"dtype": "float32", "shape": [3], "names": None}}), "observation.state"),
    "index dtype": (lambda r: rewrite_info(r, features={
        **json.loads((r / "meta/info.json").read_text())["features"],
        "index": {"dtype": "float32", "shape": [1], "names": None}}), "feature index must be int64"),
    "global index": (lambda r: rewrite_column(r / DATA, "index", [0, 1, 2, 3, 5, 4, 6, 7, 8]),
                     "global index is not 0, 1, ..."),
    "frame_index": (lambda r: rewrite_column(r / DATA, "frame_index", [0, 1, 2, 0, 1, 1, 3, 0, 1]),
                    "episode 1: frame_index is not 0 .. 3"),
    "timestamp": (lambda r: rewrite_column(r / DATA, "timestamp", [0, 0.02, 0.04, 0, 0.02, 0.04, 0.06, 0, 0.021]),
                  "episode 2: timestamps are not frame_index / fps"),
    "task_index": (lambda r: rewrite_column(r / DATA, "task_index", [0, 0, 0, 1, 1, 1, 1, 1, 1]),
                   "episode 2: tasks ['pinch'], its frames' task_index [1]"),
    "episode bounds": (lambda r: rewrite_column(r / EPISODES, "dataset_to_index", [3, 6, 9]), "episode 1: from 3 to 6"),
    "data file index": (lambda r: rewrite_column(r / EPISODES, "data/file_index", [0, 1, 0]),
                        "episode 1: data/chunk_index 0 data/file_index 1"),
    "episode stats": (lambda r: rewrite_column(r / EPISODES, "stats/observation.state/mean",
                                               [[1.5, -1.0], [11.5, -1.5], [20.5, -0.5]]),
                      "episode 0 observation.state: mean [1.5, -1.0] differs from the frames' [1.0, -1.0]"),
    "tasks index": (lambda r: pq.write_table(pq.read_table(r / TASKS_PATH).replace_schema_metadata({}),
                                             r / TASKS_PATH), "tasks.parquet is indexed by None"),
    "stats.json": (lambda r: (r / STATS_PATH).write_text(json.dumps({
        **json.loads((r / STATS_PATH).read_text()), "action": {"min": [0.0]}})), "stats.json action: no max"),
}


@pytest.mark.parametrize("name", sorted(BREAKS))
def test_the_checker_finds_each_broken_invariant(written, name):
    breaks, needle = BREAKS[name]
    breaks(written)
    report = check_dataset(written)
    assert not report.ok
    assert any(needle in problem for problem in report.problems), report.problems
