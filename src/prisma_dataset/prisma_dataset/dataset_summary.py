"""`prisma-dataset show`: a dataset's summary (episodes, frames, tasks, what ended each episode and
how much of its bag was dropped, the invariant check) and one picture per episode (motor positions
against the actions, the five fingertips' normal forces)."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.hand import FINGERS, MOTOR_NAMES

from .bag_export import ACTION, STATE, WRENCH
from .dataset_check import CheckReport
from .lerobot_format import EXPORT_NOTES_PATH

FZ = 2  # observation.wrench's axis of the pad's normal force (fx fy fz tx ty tz)


def export_notes(root: Path) -> dict[str, Any]:
    path = root / EXPORT_NOTES_PATH
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def summary_lines(report: CheckReport, episode: int | None = None) -> list[str]:
    info, notes = report.info, export_notes(report.root)
    episode_notes = {n.get("episode_index"): n for n in notes.get("episodes", [])}
    lines = [f"dataset {report.root}: LeRobot {info.get('codebase_version')}, {info.get('fps')} fps, "
             f"{info.get('total_episodes')} episodes, {info.get('total_frames')} frames, "
             f"{info.get('total_tasks')} tasks"]
    for number, task in enumerate(report.tasks):
        lines.append(f"  task {number}: {task}")
    if notes.get("max_age_s"):
        ages = ", ".join(f"{k} {v:g} s" for k, v in notes["max_age_s"].items())
        lines.append(f"  sampling: sample-and-hold, max age {ages}; action: {notes.get('action')}")
    gaps = 0
    for row in report.episodes:
        number = row["episode_index"]
        if episode is not None and number != episode:
            continue
        note = episode_notes.get(number, {})
        seconds = row["length"] / info["fps"] if info.get("fps") else float("nan")
        line = f"  episode {number}: {row['length']} frames ({seconds:.2f} s), task {row['tasks']}"
        if note:
            line += f", from {note.get('source')}, ended by {note.get('ended')}"
            if note.get("gap"):
                gaps += 1
                line += f"; {note.get('dropped_s', 0):.2f} s of the bag dropped"
        lines.append(line)
    lines.append(f"  gaps that ended episodes: {gaps}")
    if report.ok:
        lines.append("  invariants: all hold (info.json, features, index, episodes, timestamps, tasks, stats)")
    else:
        lines.append(f"  invariants: {len(report.problems)} broken")
        lines += [f"    {p}" for p in report.problems]
    return lines


def plot_episode(report: CheckReport, number: int, out: Path) -> Path:
    """motor positions against the actions, and the five fingertips' normal forces, of one episode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    row = report.episodes[number]
    span = slice(row["dataset_from_index"], row["dataset_to_index"])
    t = report.frames["timestamp"][span]
    state, action = report.frames[STATE][span], report.frames[ACTION][span]
    wrench = report.frames[WRENCH][span]
    fig, axes = plt.subplots(len(MOTOR_NAMES) + 1, 1, figsize=(9, 10), sharex=True)
    for i, motor in enumerate(MOTOR_NAMES):
        ax = axes[i]
        ax.plot(t, state[:, i], label="position")
        ax.plot(t, action[:, i], "--", label="action")
        ax.set_ylabel(f"{motor} (rad)")
        ax.legend(loc="upper right")
    ax = axes[-1]
    for f, finger in enumerate(FINGERS):
        ax.plot(t, wrench[:, f, FZ], label=finger)
    ax.set_ylabel("normal force fz (N)")
    ax.set_xlabel("time in the episode (s)")
    ax.legend(loc="upper right", ncol=len(FINGERS))
    fig.suptitle(f"episode {number}: {row['tasks'][0]}")
    fig.tight_layout()
    with atomic_output(out) as staged:
        fig.savefig(staged, dpi=80)
    plt.close(fig)
    return out


def episode_numbers(report: CheckReport, episode: int | None) -> list[int]:
    return [r["episode_index"] for r in report.episodes if episode is None or r["episode_index"] == episode]


def has_plot_features(report: CheckReport) -> bool:
    return all(np.asarray(report.frames.get(k, [])).size for k in (STATE, ACTION, WRENCH))
