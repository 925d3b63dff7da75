"""The loader's view of a LeRobot v3.0 dataset: read the directory back with pyarrow and json and list
every broken invariant LeRobot's loader relies on (docs/datasets.md, "Invariants"). Used by the
tests and by `prisma-dataset show`; nothing here trusts the writer.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from prisma_teleop.episodes import OUTCOMES as MARKED_OUTCOMES

from .episode_spans import UNFINISHED
from .lerobot_format import (
    CODEBASE_VERSION,
    EPISODES_PATH,
    INDEX_FEATURES,
    INDEX_NAMES,
    INFO_PATH,
    STATS_PATH,
    STAT_NAMES,
    TASKS_PATH,
    DatasetFormatError,
    Feature,
    data_files,
    feature_stats,
    from_arrow,
    timestamps,
)

# meta/episodes' outcome column (the episode markers'; "" = not marked, --whole-bag)
OUTCOMES = (*MARKED_OUTCOMES, UNFINISHED, "")
# info.json: key -> the types its value may have
INFO_TYPES: dict[str, tuple[type, ...]] = {
    "codebase_version": (str,), "robot_type": (str, type(None)), "total_episodes": (int,), "total_frames": (int,),
    "total_tasks": (int,), "chunks_size": (int,), "data_files_size_in_mb": (int, float),
    "video_files_size_in_mb": (int, float), "fps": (int,), "splits": (dict,), "data_path": (str,),
    "video_path": (str, type(None)), "features": (dict,),
}
DTYPES = {"float32", "float64", "int64", "int32", "int16", "int8", "uint8", "uint16", "bool"}
STATS_RTOL, STATS_ATOL = 1e-6, 1e-9  # float64 stats recomputed from the stored float32 frames


@dataclass
class CheckReport:
    """What the check found: `problems` empty when every invariant holds."""

    root: Path
    problems: list[str] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)
    episodes: list[dict[str, Any]] = field(default_factory=list)  # meta/episodes rows (without stats)
    tasks: list[str] = field(default_factory=list)
    frames: dict[str, np.ndarray] = field(default_factory=dict)  # every column, all files in order

    @property
    def ok(self) -> bool:
        return not self.problems


def check_dataset(root: str | Path) -> CheckReport:
    report = CheckReport(Path(root))
    try:
        _check(report)
    except (OSError, ValueError, KeyError, TypeError, pa.ArrowException) as exc:
        report.problems.append(f"cannot read on: {exc}")
    return report


def _check(report: CheckReport) -> None:
    root = report.root
    problems = report.problems
    info = json.loads((root / INFO_PATH).read_text())
    report.info = info
    for key, kinds in INFO_TYPES.items():
        if key not in info:
            problems.append(f"info.json has no {key!r}")
        elif not isinstance(info[key], kinds) or isinstance(info[key], bool):
            problems.append(f"info.json {key!r} is {type(info[key]).__name__}, expected "
                            f"{' or '.join(k.__name__ for k in kinds)}")
    if problems:
        return
    if info["codebase_version"] != CODEBASE_VERSION:
        problems.append(f"codebase_version {info['codebase_version']!r}, expected {CODEBASE_VERSION!r}")
    if info["fps"] <= 0:
        problems.append(f"fps {info['fps']} must be > 0")
    if info["splits"] != {"train": f"0:{info['total_episodes']}"}:
        problems.append(f"splits {info['splits']} should be {{'train': '0:{info['total_episodes']}'}}")
    for key in ("data_path", "video_path"):
        if info[key] is not None and not {"{chunk_index", "{file_index"} <= set(re.findall(r"\{\w+", info[key])):
            problems.append(f"{key} {info[key]!r} lacks {{chunk_index}} or {{file_index}}")
    features = _features(info["features"], problems)
    if problems:
        return
    fps = int(info["fps"])

    # data files: columns, types, global index
    columns: dict[str, list[np.ndarray]] = {name: [] for name in features}
    file_of_row: list[tuple[int, int]] = []
    for path in data_files(root):
        chunk, file = (int(x) for x in re.findall(r"\d+", str(path.relative_to(root)))[-2:])
        expected = root / info["data_path"].format(chunk_index=chunk, file_index=file)
        if expected != path:
            problems.append(f"{path.relative_to(root)} is not where data_path puts chunk {chunk} file {file}")
        table = pq.read_table(path)
        if table.column_names != list(features):
            problems.append(f"{path.relative_to(root)} has columns {table.column_names}, info.json's features "
                            f"are {list(features)}")
            return
        for name, feature in features.items():
            columns[name].append(from_arrow(table.column(name), feature))
        file_of_row += [(chunk, file)] * table.num_rows
    frames = {name: np.concatenate(parts) if parts else np.empty(0) for name, parts in columns.items()}
    report.frames = frames
    total = len(file_of_row)
    if total != info["total_frames"]:
        problems.append(f"total_frames {info['total_frames']}, the data files hold {total}")
    if not np.array_equal(frames["index"], np.arange(total)):
        problems.append("the global index is not 0, 1, ... in file order")

    tasks = _check_tasks(root, info, problems)
    report.tasks = tasks
    if total and tasks and not (0 <= frames["task_index"].min() and frames["task_index"].max() < len(tasks)):
        problems.append("a frame's task_index is not in tasks.parquet")

    # episodes
    episodes = pq.read_table(root / EPISODES_PATH.format(chunk_index=0, file_index=0)).to_pylist()
    report.episodes = [{k: v for k, v in row.items() if not k.startswith("stats/")} for row in episodes]
    if len(episodes) != info["total_episodes"]:
        problems.append(f"total_episodes {info['total_episodes']}, meta/episodes has {len(episodes)} rows")
    end = 0
    for number, row in enumerate(episodes):
        _check_episode(row, number, end, features, frames, file_of_row, tasks, fps, problems)
        end = row["dataset_to_index"]
    if episodes and end != total:
        problems.append(f"the last episode ends at {end}, the data has {total} frames")

    # dataset-wide stats
    stats = json.loads((root / STATS_PATH).read_text())
    for name in features:
        if name not in stats:
            problems.append(f"stats.json has no {name}")
            continue
        if total:
            _compare_stats(f"stats.json {name}", {k: np.asarray(v) for k, v in stats[name].items()},
                           frames[name], problems)


def _features(spec: dict[str, Any], problems: list[str]) -> dict[str, Feature]:
    features = {}
    for name, item in spec.items():
        if not isinstance(item, dict) or not isinstance(item.get("dtype"), str) \
                or not isinstance(item.get("shape"), list) \
                or not all(isinstance(n, int) and n > 0 for n in item["shape"]) or "names" not in item:
            problems.append(f"feature {name}: needs dtype (str), shape (list of positive ints) and names, has {item}")
            continue
        if item["dtype"] not in DTYPES:
            problems.append(f"feature {name}: dtype {item['dtype']!r} is not a numeric dtype")
            continue
        names = item["names"]
        if len(item["shape"]) == 1 and item["shape"] != [1] and isinstance(names, list) \
                and len(names) != item["shape"][0]:
            problems.append(f"feature {name}: {len(names)} names for shape {item['shape']}")
        features[name] = Feature.from_info(name, item)
    for index in INDEX_FEATURES:
        got = features.get(index.name)
        if got is None or (got.dtype, got.shape) != (index.dtype, index.shape):
            problems.append(f"feature {index.name} must be {index.dtype} of shape {list(index.shape)}, is "
                            f"{got.info() if got else 'missing'}")
    if list(features)[-len(INDEX_NAMES):] != list(INDEX_NAMES):
        problems.append(f"the index columns {list(INDEX_NAMES)} must come last, in that order")
    return features


def _check_tasks(root: Path, info: dict[str, Any], problems: list[str]) -> list[str]:
    table = pq.read_table(root / TASKS_PATH)
    pandas_meta = json.loads((table.schema.metadata or {}).get(b"pandas", b"{}"))
    if pandas_meta.get("index_columns") != ["task"]:
        problems.append(f"tasks.parquet is indexed by {pandas_meta.get('index_columns')}, not by ['task']")
    if set(table.column_names) != {"task", "task_index"}:
        problems.append(f"tasks.parquet has columns {table.column_names}, expected task_index and task")
        return []
    tasks = table.column("task").to_pylist()
    if table.column("task_index").to_pylist() != list(range(len(tasks))):
        problems.append("tasks.parquet's task_index is not 0, 1, ... in row order")
    if len(set(tasks)) != len(tasks):
        problems.append("tasks.parquet holds a task twice")
    if len(tasks) != info["total_tasks"]:
        problems.append(f"total_tasks {info['total_tasks']}, tasks.parquet has {len(tasks)}")
    return tasks


def _check_episode(row: dict[str, Any], number: int, start: int, features: dict[str, Feature],
                   frames: dict[str, np.ndarray], file_of_row: list[tuple[int, int]], tasks: list[str], fps: int,
                   problems: list[str]) -> None:
    where = f"episode {number}"
    if row.get("outcome") not in (None, *OUTCOMES):  # this suite's column: a dataset without it is read as well
        problems.append(f"{where}: outcome {row['outcome']!r} is none of {', '.join(map(repr, OUTCOMES))}")
    if row["episode_index"] != number:
        problems.append(f"{where}: episode_index {row['episode_index']}, rows must be 0, 1, ... in order")
    lo, hi, length = row["dataset_from_index"], row["dataset_to_index"], row["length"]
    if lo != start or hi - lo != length or length <= 0:
        problems.append(f"{where}: from {lo} to {hi} with length {length}, expected to start at {start} and "
                        f"to - from = length > 0")
        return
    if hi > len(file_of_row):
        problems.append(f"{where}: ends at {hi}, past the data's {len(file_of_row)} frames")
        return
    files = set(file_of_row[lo:hi])
    if files != {(row["data/chunk_index"], row["data/file_index"])}:
        problems.append(f"{where}: data/chunk_index {row['data/chunk_index']} data/file_index "
                        f"{row['data/file_index']}, its frames are in {sorted(files)}")
    span = slice(lo, hi)
    if not np.array_equal(frames["episode_index"][span], np.full(length, number)):
        problems.append(f"{where}: frames {lo}..{hi - 1} are not all episode_index {number}")
    if not np.array_equal(frames["frame_index"][span], np.arange(length)):
        problems.append(f"{where}: frame_index is not 0 .. {length - 1}")
    if not np.array_equal(frames["timestamp"][span], timestamps(length, fps)):
        problems.append(f"{where}: timestamps are not frame_index / fps (float32)")
    task_numbers = sorted(set(frames["task_index"][span].tolist()))
    named = [tasks[i] for i in task_numbers if 0 <= i < len(tasks)]
    if len(named) != len(task_numbers) or sorted(named) != sorted(row["tasks"]):
        problems.append(f"{where}: tasks {row['tasks']}, its frames' task_index {task_numbers} name other tasks")
    for name in features:
        stats = {}
        for stat in STAT_NAMES:
            key = f"stats/{name}/{stat}"
            if key not in row or row[key] is None:
                problems.append(f"{where}: no {key}")
                break
            stats[stat] = np.asarray(row[key])
        else:
            _compare_stats(f"{where} {name}", stats, frames[name][span], problems)


def _compare_stats(where: str, stored: dict[str, np.ndarray], values: np.ndarray, problems: list[str]) -> None:
    recomputed = feature_stats(values)
    for stat, expected in recomputed.items():
        got = stored.get(stat)
        if got is None:
            problems.append(f"{where}: no {stat}")
        elif got.shape != expected.shape or not np.allclose(got, expected, STATS_RTOL, STATS_ATOL, equal_nan=True):
            problems.append(f"{where}: {stat} {got.tolist()} differs from the frames' {expected.tolist()}")


def require_valid(root: str | Path) -> CheckReport:
    """check_dataset, raising DatasetFormatError with the first problems when any invariant fails."""
    report = check_dataset(root)
    if not report.ok:
        raise DatasetFormatError(f"{root}: " + "; ".join(report.problems[:3]))
    return report
