"""`prisma-dataset show`: a dataset's summary (episodes, frames, tasks, each episode's outcome and
the outcomes counted, what ended each episode and how much of its bag was dropped, the invariant
check) and one picture per episode: motor positions against the actions, the five fingertips'
normal forces with the touch limit, and the taxel voltages of every pad at the first contact (the
first frame with any `observation.contact`) and at the peak force (the frame of the largest normal
force on any pad)."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_manipulation.node_config import ManipulationConfig

from .bag_export import ACTION, CONTACT, STATE, TACTILE, WRENCH
from .dataset_check import CheckReport
from .figures import pyplot, save_figure
from .lerobot_format import EXPORT_NOTES_PATH
from .verdict import verdict_lines

FZ = 2  # observation.wrench's axis of the pad's normal force (fx fy fz tx ty tz)
# the touch limit a Teleoperate goal with max_pad_force 0 gets: the manipulation node's default
DEFAULT_TOUCH_LIMIT_N = ManipulationConfig().teleop_max_pad_force


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
    outcomes: Counter[str] = Counter()
    for row in report.episodes:
        number = row["episode_index"]
        if episode is not None and number != episode:
            continue
        note = episode_notes.get(number, {})
        seconds = row["length"] / info["fps"] if info.get("fps") else float("nan")
        line = f"  episode {number}: {row['length']} frames ({seconds:.2f} s), task {row['tasks']}"
        if row.get("outcome"):
            line += f", {row['outcome']}"
            if note.get("outcome_reason"):
                line += f" ({note['outcome_reason']})"
        outcomes[row.get("outcome") or "not marked"] += 1
        if note:
            line += f", from {note.get('source')}, ended by {note.get('ended')}"
            if note.get("gap"):
                gaps += 1
                line += f"; {note.get('dropped_s', 0):.2f} s of the bag dropped"
        lines.append(line)
    lines.append(f"  outcomes: {', '.join(f'{n} {o}' for o, n in sorted(outcomes.items())) or 'no episode'}")
    lines.append(f"  gaps that ended episodes: {gaps}")
    lines += verdict_lines("invariants", report.problems,
                           "all hold (info.json, features, index, episodes, timestamps, tasks, stats)", "broken")
    return lines


def moments(frames: dict[str, np.ndarray], span: slice) -> list[tuple[str, int]]:
    """(label, frame in the episode) of the first contact (when any pad reports one) and of the peak
    normal force on any pad."""
    found = []
    if CONTACT in frames:
        touching = np.flatnonzero(frames[CONTACT][span].max(axis=1) > 0)
        if touching.size:
            found.append(("first contact", int(touching[0])))
    fz = frames[WRENCH][span][:, :, FZ]
    if fz.size and np.isfinite(fz).any():  # an axis the bundle does not estimate is NaN
        found.append(("peak force", int(np.argmax(np.where(np.isfinite(fz), fz, -np.inf).max(axis=1)))))
    return found


def plot_episode(report: CheckReport, number: int, out: Path, touch_limit_n: float = DEFAULT_TOUCH_LIMIT_N) -> Path:
    """One episode: motor positions against the actions, the normal forces with the touch limit,
    and the taxel heat maps at the first contact and the peak force."""
    plt = pyplot()
    row = report.episodes[number]
    span = slice(row["dataset_from_index"], row["dataset_to_index"])
    t = report.frames["timestamp"][span]
    state, action = report.frames[STATE][span], report.frames[ACTION][span]
    wrench = report.frames[WRENCH][span]
    shown = moments(report.frames, span) if TACTILE in report.frames else []
    rows = len(MOTOR_NAMES) + 1
    fig = plt.figure(figsize=(9, 10 + 1.6 * len(shown)))
    grid = fig.add_gridspec(rows + len(shown), len(FINGERS), height_ratios=[1.0] * rows + [0.8] * len(shown))
    axes = [fig.add_subplot(grid[0, :])]
    axes += [fig.add_subplot(grid[i, :], sharex=axes[0]) for i in range(1, rows)]
    for i, motor in enumerate(MOTOR_NAMES):
        ax = axes[i]
        ax.plot(t, state[:, i], label="position")
        ax.plot(t, action[:, i], "--", label="action")
        ax.set_ylabel(f"{motor} (rad)")
        ax.legend(loc="upper right")
    ax = axes[-1]
    for f, finger in enumerate(FINGERS):
        ax.plot(t, wrench[:, f, FZ], label=finger)
    ax.axhline(touch_limit_n, color="k", ls="--", lw=1, label="touch limit")
    for _, frame in shown:
        ax.axvline(t[frame], color="0.5", lw=1)
    ax.set_ylabel("normal force fz (N)")
    ax.set_xlabel("time in the episode (s)")
    ax.legend(loc="upper right", ncol=3, fontsize=8)
    tactile = report.frames[TACTILE][span] if shown else np.empty(0)
    for k, (label, frame) in enumerate(shown):
        top = float(np.nanmax(tactile[frame])) or 1.0
        for f, finger in enumerate(FINGERS):
            pad = fig.add_subplot(grid[rows + k, f])
            image = pad.imshow(tactile[frame, f], origin="lower", vmin=0.0, vmax=top, cmap="viridis")
            pad.set_xticks([])
            pad.set_yticks([])
            pad.set_title(f"{finger}" + (f"\n{label} {t[frame]:.2f} s" if f == 0 else ""), fontsize=8)
        fig.colorbar(image, ax=pad, fraction=0.046, label="V")
    return save_figure(fig, f"episode {number}: {row['tasks'][0]}", out)


def episode_numbers(report: CheckReport, episode: int | None) -> list[int]:
    return [r["episode_index"] for r in report.episodes if episode is None or r["episode_index"] == episode]


def has_plot_features(report: CheckReport) -> bool:
    return all(np.asarray(report.frames.get(k, [])).size for k in (STATE, ACTION, WRENCH))
