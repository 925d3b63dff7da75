"""The LeRobot v3.0 dataset layout, written with pyarrow and json (lerobot itself is not imported: its
releases that write v3.0 pin an older torch than the suite's).

    meta/info.json                               codebase_version "v3.0", fps, features, totals, paths, splits
    meta/stats.json                              per feature: min, max, mean, std, count, q01 q10 q50 q90 q99
    meta/tasks.parquet                           task_index, indexed by the task text (pandas metadata)
    meta/episodes/chunk-000/file-000.parquet     one row per episode: where its frames are, its tasks, its stats,
                                                 and this suite's `outcome` column (the episode markers')
    data/chunk-CCC/file-FFF.parquet              the frames: every feature, then timestamp, frame_index,
                                                 episode_index, index, task_index
    meta/prisma_export.json                      this suite's own notes (streams, max ages, why each episode
                                                 ended); LeRobot's loader does not read it

A feature of shape (1,) is a plain column, any other shape a nested fixed-size list of its dtype. An
episode is never split across data files; a new file starts when the current one would pass
`data_files_size_in_mb`, and file numbers roll into the next chunk every `chunks_size` files.
`stats.json` is computed over every frame (exact quantiles, not lerobot's per-episode aggregate).
The dataset is written whole or not at all: staged beside the target and renamed into place
(`prisma_common.atomic`); an append reads the existing dataset, adds the episodes and replaces it
the same way. docs/datasets.md lists the invariants and the tests that check each one.
"""
from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from prisma_common.atomic import atomic_output

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_FILES_SIZE_IN_MB = 100
VIDEO_FILES_SIZE_IN_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
INFO_PATH = "meta/info.json"
STATS_PATH = "meta/stats.json"
TASKS_PATH = "meta/tasks.parquet"
EXPORT_NOTES_PATH = "meta/prisma_export.json"
QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
STAT_NAMES = ("min", "max", "mean", "std", "count", *QUANTILES)
MB = 1024 * 1024


@dataclass(frozen=True)
class Feature:
    """One column of the frames: its dtype, the shape of one frame's value and the names of its
    elements (1-D) or axes (more dimensions)."""

    name: str
    dtype: str
    shape: tuple[int, ...]
    names: list[str] | None = None

    def info(self) -> dict[str, Any]:
        return {"dtype": self.dtype, "shape": list(self.shape), "names": self.names}

    @classmethod
    def from_info(cls, name: str, info: Mapping[str, Any]) -> Feature:
        return cls(name, str(info["dtype"]), tuple(int(n) for n in info["shape"]), info.get("names"))

    @property
    def frame_bytes(self) -> int:
        return math.prod(self.shape) * np.dtype(self.dtype).itemsize


# the columns LeRobot adds to every frame, after the recorded features
INDEX_FEATURES = (
    Feature("timestamp", "float32", (1,)),
    Feature("frame_index", "int64", (1,)),
    Feature("episode_index", "int64", (1,)),
    Feature("index", "int64", (1,)),
    Feature("task_index", "int64", (1,)),
)
INDEX_NAMES = tuple(f.name for f in INDEX_FEATURES)


@dataclass
class Episode:
    """One episode's frames: feature name -> array [length, *shape]; its task; notes kept in
    meta/prisma_export.json (where it came from, why it ended)."""

    task: str
    values: dict[str, np.ndarray]
    notes: dict[str, Any] = field(default_factory=dict)
    outcome: str = ""  # success | failure | unfinished from the episode markers; "" = not marked (--whole-bag)

    @property
    def length(self) -> int:
        return len(next(iter(self.values.values()))) if self.values else 0


@dataclass
class Dataset:
    """A whole dataset in memory: what `write_dataset` writes and `read_dataset` reads back."""

    fps: int
    features: list[Feature]  # the recorded features, without the index columns
    episodes: list[Episode]
    robot_type: str = "prisma_hand"
    export_notes: dict[str, Any] = field(default_factory=dict)  # dataset-level notes (streams, max ages)
    data_files_size_in_mb: int = DATA_FILES_SIZE_IN_MB
    chunks_size: int = CHUNKS_SIZE

    def tasks(self) -> list[str]:
        """Task texts in order of first appearance: a task's index is its place here."""
        return list(dict.fromkeys(e.task for e in self.episodes))

    @property
    def total_frames(self) -> int:
        return sum(e.length for e in self.episodes)


class DatasetFormatError(ValueError):
    """A dataset that cannot be written as given, or read back; the message names what and where."""


def timestamps(length: int, fps: int) -> np.ndarray:
    """frame_index / fps as float32: the timestamps LeRobot's loader expects, exactly."""
    return (np.arange(length, dtype=np.float64) / fps).astype(np.float32)


def feature_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """min, max, mean, std (population), count and the quantiles over the frames (axis 0); each of
    the feature's shape (count: [n]), float64."""
    data = np.asarray(values, dtype=np.float64)
    stats = {
        "min": data.min(axis=0), "max": data.max(axis=0), "mean": data.mean(axis=0), "std": data.std(axis=0),
        "count": np.array([len(data)], dtype=np.int64),
    }
    for name, q in QUANTILES.items():
        stats[name] = np.quantile(data, q, axis=0)
    return {k: np.asarray(v).reshape((1,) if k == "count" else data.shape[1:] or (1,)) for k, v in stats.items()}


def arrow_type(feature: Feature) -> pa.DataType:
    dtype = pa.from_numpy_dtype(np.dtype(feature.dtype))
    if feature.shape == (1,):
        return dtype
    for n in reversed(feature.shape):
        dtype = pa.list_(dtype, n)
    return dtype


def to_arrow(values: np.ndarray, feature: Feature) -> pa.Array:
    data = np.ascontiguousarray(values, dtype=feature.dtype)
    if data.shape[1:] != feature.shape and not (feature.shape == (1,) and data.ndim == 1):
        raise DatasetFormatError(f"feature {feature.name}: frames of shape {data.shape[1:]}, info says "
                                 f"{feature.shape}")
    array: pa.Array = pa.array(data.reshape(-1))
    if feature.shape == (1,):
        return array
    for n in reversed(feature.shape):
        array = pa.FixedSizeListArray.from_arrays(array, n)
    return array


def from_arrow(column: pa.ChunkedArray | pa.Array, feature: Feature) -> np.ndarray:
    """A column back as [rows, *shape] (a (1,) feature as [rows]); DatasetFormatError when the
    stored lists do not have the feature's shape."""
    array = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    rows = len(array)
    while pa.types.is_list(array.type) or pa.types.is_fixed_size_list(array.type) \
            or pa.types.is_large_list(array.type):
        array = array.flatten()
    flat = array.to_numpy(zero_copy_only=False)
    size = math.prod(feature.shape)
    if flat.size != rows * size:
        raise DatasetFormatError(f"column {feature.name}: {flat.size} values in {rows} rows, shape {feature.shape} "
                                 f"needs {rows * size}")
    return flat.reshape(rows) if feature.shape == (1,) else flat.reshape(rows, *feature.shape)


def _stats_to_lists(stats: Mapping[str, np.ndarray]) -> dict[str, Any]:
    return {k: np.asarray(v).tolist() for k, v in stats.items()}


def _stat_type(feature: Feature, stat: str) -> pa.DataType:
    dtype: pa.DataType = pa.int64() if stat == "count" else pa.float64()
    for n in reversed((1,) if stat == "count" else feature.shape):
        dtype = pa.list_(dtype, n)
    return dtype


def _tasks_table(tasks: Sequence[str]) -> pa.Table:
    """task_index indexed by task, as pandas writes a DataFrame whose index is `task` (LeRobot reads
    meta/tasks.parquet with pandas and looks tasks up by the index)."""
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())})
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                            "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
             "metadata": None},
            {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
             "metadata": None},
        ],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.0",
    }
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()})


def _check(dataset: Dataset) -> None:
    if not isinstance(dataset.fps, int) or dataset.fps <= 0:
        raise DatasetFormatError(f"fps {dataset.fps!r} must be a positive integer")
    names = [f.name for f in dataset.features]
    clash = sorted(set(names) & set(INDEX_NAMES))
    if clash or len(set(names)) != len(names):
        raise DatasetFormatError(f"feature names must be unique and not LeRobot's index columns: {names}")
    for number, episode in enumerate(dataset.episodes):
        if sorted(episode.values) != sorted(names):
            raise DatasetFormatError(f"episode {number} has features {sorted(episode.values)}, the dataset "
                                     f"{sorted(names)}")
        if episode.length == 0:
            raise DatasetFormatError(f"episode {number} has no frames")
        lengths = {name: len(v) for name, v in episode.values.items()}
        if len(set(lengths.values())) != 1:
            raise DatasetFormatError(f"episode {number}: features of different lengths {lengths}")


def _file_groups(dataset: Dataset) -> list[list[int]]:
    """Episode numbers per data file: a new file once the current one would pass the size limit."""
    frame_bytes = sum(f.frame_bytes for f in (*dataset.features, *INDEX_FEATURES))
    limit = dataset.data_files_size_in_mb * MB
    groups: list[list[int]] = []
    size = 0
    for number, episode in enumerate(dataset.episodes):
        episode_bytes = episode.length * frame_bytes
        if not groups or (groups[-1] and size + episode_bytes > limit):
            groups.append([])
            size = 0
        groups[-1].append(number)
        size += episode_bytes
    return groups


def _write(root: Path, dataset: Dataset) -> None:
    _check(dataset)
    tasks = dataset.tasks()
    task_index = {task: i for i, task in enumerate(tasks)}
    features = [*dataset.features, *INDEX_FEATURES]
    all_values: dict[str, list[np.ndarray]] = {f.name: [] for f in features}
    episode_rows: list[dict[str, Any]] = []
    start = 0
    for file_number, group in enumerate(_file_groups(dataset)):
        chunk_index, file_index = divmod(file_number, dataset.chunks_size)
        columns: dict[str, list[np.ndarray]] = {f.name: [] for f in features}
        for number in group:
            episode = dataset.episodes[number]
            n = episode.length
            frames = dict(episode.values)
            frames.update(timestamp=timestamps(n, dataset.fps), frame_index=np.arange(n, dtype=np.int64),
                          episode_index=np.full(n, number, dtype=np.int64),
                          index=np.arange(start, start + n, dtype=np.int64),
                          task_index=np.full(n, task_index[episode.task], dtype=np.int64))
            row: dict[str, Any] = {
                "episode_index": number, "tasks": [episode.task], "length": n, "outcome": episode.outcome,
                "data/chunk_index": chunk_index, "data/file_index": file_index,
                "dataset_from_index": start, "dataset_to_index": start + n,
                "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0,
            }
            for feature in features:
                values = np.asarray(frames[feature.name], dtype=feature.dtype)
                columns[feature.name].append(values)
                all_values[feature.name].append(values)
                for stat, value in feature_stats(values).items():
                    row[f"stats/{feature.name}/{stat}"] = value.tolist()
            episode_rows.append(row)
            start += n
        table = pa.table({f.name: to_arrow(np.concatenate(columns[f.name]), f) for f in features})
        path = root / DATA_PATH.format(chunk_index=chunk_index, file_index=file_index)
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, path)

    episode_schema = [
        ("episode_index", pa.int64()), ("tasks", pa.list_(pa.string())), ("length", pa.int64()),
        ("outcome", pa.string()),
        ("data/chunk_index", pa.int64()), ("data/file_index", pa.int64()),
        ("dataset_from_index", pa.int64()), ("dataset_to_index", pa.int64()),
        ("meta/episodes/chunk_index", pa.int64()), ("meta/episodes/file_index", pa.int64()),
        *[(f"stats/{f.name}/{stat}", _stat_type(f, stat)) for f in features for stat in STAT_NAMES],
    ]
    episodes_table = pa.table({name: pa.array([row[name] for row in episode_rows], dtype)
                               for name, dtype in episode_schema})
    path = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(episodes_table, path)
    pq.write_table(_tasks_table(tasks), root / TASKS_PATH)

    stats = {f.name: _stats_to_lists(feature_stats(np.concatenate(all_values[f.name]))) for f in features}
    (root / STATS_PATH).write_text(json.dumps(stats, indent=2) + "\n")
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": dataset.robot_type,
        "total_episodes": len(dataset.episodes),
        "total_frames": dataset.total_frames,
        "total_tasks": len(tasks),
        "chunks_size": dataset.chunks_size,
        "data_files_size_in_mb": dataset.data_files_size_in_mb,
        "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB,
        "fps": dataset.fps,
        "splits": {"train": f"0:{len(dataset.episodes)}"},
        "data_path": DATA_PATH,
        "video_path": None,  # no video features
        "features": {f.name: f.info() for f in features},
    }
    (root / INFO_PATH).write_text(json.dumps(info, indent=4) + "\n")
    notes = {**dataset.export_notes, "episodes": [dict(e.notes, episode_index=i)
                                                  for i, e in enumerate(dataset.episodes)]}
    (root / EXPORT_NOTES_PATH).write_text(json.dumps(notes, indent=2) + "\n")


def write_dataset(target: str | Path, dataset: Dataset) -> Path:
    """Write `dataset` at `target`, whole or not at all: staged in `<target>.partial-<pid>/` and
    renamed into place (an existing directory at `target` is replaced only once the new one is
    complete). DatasetFormatError for a dataset that cannot be written as given, before anything is made."""
    _check(dataset)
    with atomic_output(target) as staged:
        staged.mkdir()
        (staged / "meta").mkdir()
        _write(staged, dataset)
    return Path(target)


def read_info(root: str | Path) -> dict[str, Any]:
    path = Path(root) / INFO_PATH
    try:
        info = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise DatasetFormatError(f"{path}: not a readable LeRobot info.json ({exc})") from None
    if not isinstance(info, dict) or info.get("codebase_version") != CODEBASE_VERSION:
        got = info.get("codebase_version") if isinstance(info, dict) else None
        raise DatasetFormatError(f"{path}: codebase_version {got!r}, this tool reads {CODEBASE_VERSION!r} only")
    return info


def data_files(root: str | Path) -> list[Path]:
    """The data files in (chunk, file) order."""
    return sorted((Path(root) / "data").glob("chunk-*/file-*.parquet"))


def read_dataset(root: str | Path) -> Dataset:
    """A dataset this module wrote (or any v3.0 dataset without videos), back in memory: what an
    append adds to. DatasetFormatError naming the file for anything it cannot read."""
    root = Path(root)
    info = read_info(root)
    try:
        all_features = [Feature.from_info(name, spec) for name, spec in info["features"].items()]
        recorded = [f for f in all_features if f.name not in INDEX_NAMES]
        frames = {f.name: [] for f in all_features}  # type: dict[str, list[np.ndarray]]
        for path in data_files(root):
            table = pq.read_table(path)
            for feature in all_features:
                frames[feature.name].append(from_arrow(table.column(feature.name), feature))
        values = {name: np.concatenate(parts) if parts else np.empty(0) for name, parts in frames.items()}
        episodes_table = pq.read_table(root / EPISODES_PATH.format(chunk_index=0, file_index=0))
        notes_path = root / EXPORT_NOTES_PATH
        notes = json.loads(notes_path.read_text()) if notes_path.exists() else {}
    except (OSError, KeyError, ValueError, pa.ArrowException) as exc:
        raise DatasetFormatError(f"{root}: cannot read the dataset back ({exc})") from None
    episode_notes = notes.pop("episodes", [])
    episodes = []
    for number, row in enumerate(episodes_table.to_pylist()):
        span = slice(row["dataset_from_index"], row["dataset_to_index"])
        episode_values = {f.name: values[f.name][span] for f in recorded}
        note = dict(episode_notes[number]) if number < len(episode_notes) else {}
        note.pop("episode_index", None)
        episodes.append(Episode(row["tasks"][0], episode_values, note, row.get("outcome") or ""))
    return Dataset(int(info["fps"]), recorded, episodes, info.get("robot_type") or "prisma_hand", notes,
                   int(info.get("data_files_size_in_mb", DATA_FILES_SIZE_IN_MB)),
                   int(info.get("chunks_size", CHUNKS_SIZE)))


def append_episodes(existing: Dataset, new: Dataset) -> Dataset:
    """`existing` with `new`'s episodes added after its own; DatasetFormatError when `new` has
    another fps or other features (names, dtypes, shapes, element names) than the dataset."""
    if new.fps != existing.fps:
        raise DatasetFormatError(f"the dataset is at {existing.fps} fps, the new episodes at {new.fps} fps; "
                                 f"export them with --fps {existing.fps} or into a new dataset")
    if new.features != existing.features:
        old = {f.name: f.info() for f in existing.features}
        added = {f.name: f.info() for f in new.features}
        differ = sorted(n for n in {*old, *added} if old.get(n) != added.get(n))
        raise DatasetFormatError(f"the new episodes' features differ from the dataset's in {', '.join(differ)}; "
                                 f"export them into a new dataset")
    notes = {**existing.export_notes, **new.export_notes}
    return Dataset(existing.fps, existing.features, [*existing.episodes, *new.episodes], existing.robot_type,
                   notes, existing.data_files_size_in_mb, existing.chunks_size)
