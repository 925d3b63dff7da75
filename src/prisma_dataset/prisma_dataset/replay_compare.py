"""How a replay compares with its recording (ROS-free): the replay's motor positions and pad normal
forces sampled at the instants its frames were published, matched to the recorded frames, against
stated tolerances; the report as text lines and a PNG.

Matching: the replay's frame k is observed at the instant its action was published plus a lag,
sample-and-hold (the newest sample stamped at or before, within `max_age_s`), and compared with the
recorded frame k. The lag is one for the whole replay, a whole number of frame periods within
+-`max_lag_s`, the one that brings the motor positions closest (RMS over the motors): the live
graph's latency (a few ms per hop) is not the recording's, and the forces are never used to choose
it. A recorded frame whose replayed frame was skipped or has no fresh sample is left out (counted).

Verdict (exit 0 / 1): every frame played; per pad the largest |replayed - recorded| normal force at
the matched frames within `force_tolerance_n`; no pad's replayed force above the touch limit +
`overshoot_n` between the first frame and the goal's end; each motor's position RMS within
`position_tolerance_rad`; at least `min_matched_share` of the frames matched.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .figures import pyplot, save_figure
from .replay_plan import ReplayEpisode
from .sampling import NS
from .verdict import verdict_lines


@dataclass(frozen=True)
class Tolerances:
    force_tolerance_n: float = 0.2
    touch_limit_n: float = 2.0
    overshoot_n: float = 0.15
    position_tolerance_rad: float = 0.15
    max_lag_s: float = 0.1
    max_age_s: float = 0.05
    min_matched_share: float = 0.95  # of the frames: fewer matched says the replay ran too unevenly to judge


@dataclass
class Samples:
    """One stream of the replay: stamps [n] ns, values [n, ...], in stamp order once `ordered()`."""

    stamps_ns: list[int] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)

    def add(self, stamp_ns: int, value: ArrayLike) -> None:
        self.stamps_ns.append(int(stamp_ns))
        self.values.append(np.asarray(value, dtype=np.float64))

    def ordered(self) -> tuple[np.ndarray, np.ndarray]:
        stamps = np.asarray(self.stamps_ns, dtype=np.int64)
        order = np.argsort(stamps, kind="stable")
        return stamps[order], np.asarray(self.values, dtype=np.float64)[order]


@dataclass
class ReplayRecording:
    """What the replay published and observed: (frame, publish instant) per published frame, the
    motors' positions [motors] and each pad's normal force and contact flag, all by header stamp."""

    published: list[tuple[int, int]]
    positions: Samples
    forces: dict[str, Samples]  # finger -> fz samples
    contact: dict[str, Samples]  # finger -> 1/0 samples
    outcome: str
    played: bool
    skipped: int = 0
    ended_ns: int | None = None  # when the goal ended (None: unknown)
    notes: list[str] = field(default_factory=list)


def held_at(stamps_ns: np.ndarray, values: np.ndarray, instants_ns: np.ndarray, max_age_ns: int) -> np.ndarray:
    """Per instant the newest value stamped at or before it; NaN where none is within `max_age_ns`."""
    out = np.full((len(instants_ns), *values.shape[1:]), np.nan)
    if not len(stamps_ns):
        return out
    index = np.searchsorted(stamps_ns, instants_ns, side="right") - 1
    fresh = (index >= 0) & (instants_ns - stamps_ns[np.maximum(index, 0)] <= max_age_ns)
    out[fresh] = values[index[fresh]]
    return out


@dataclass
class PadComparison:
    finger: str
    max_diff_n: float  # largest |replayed - recorded| at the matched frames (NaN: none matched)
    mean_diff_n: float
    recorded_peak_n: float
    replayed_peak_n: float  # over the replay, first frame to the goal's end
    contact_agreement: float | None  # share of matched frames whose contact flag agrees


@dataclass
class ReplayComparison:
    episode: int
    frames: int
    played_frames: int
    matched_frames: int
    lag_s: float
    pads: list[PadComparison]
    position_rms_rad: dict[str, float]
    tolerances: Tolerances
    problems: list[str]
    # per recorded frame: the replay's positions [n, motors] and forces [n, fingers] (NaN unmatched)
    replay_positions: np.ndarray
    replay_forces: np.ndarray

    @property
    def ok(self) -> bool:
        return not self.problems


def _at(recording: ReplayRecording, episode: ReplayEpisode, instants: np.ndarray,
        max_age_ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    stamps, values = recording.positions.ordered()
    positions = held_at(stamps, values.reshape(len(stamps), -1), instants, max_age_ns) if len(stamps) \
        else np.full((len(instants), len(episode.motors)), np.nan)
    forces = np.full((len(instants), len(episode.fingers)), np.nan)
    contact = np.full((len(instants), len(episode.fingers)), np.nan)
    for f, finger in enumerate(episode.fingers):
        for samples, out in ((recording.forces.get(finger), forces), (recording.contact.get(finger), contact)):
            if samples is not None and samples.stamps_ns:
                s, v = samples.ordered()
                out[:, f] = held_at(s, v, instants, max_age_ns)
    return positions, forces, contact


def _rms(diff: np.ndarray) -> np.ndarray:
    """Per column, the RMS of the finite values (NaN for a column with none)."""
    finite = np.isfinite(diff)
    count = finite.sum(axis=0)
    squares = np.where(finite, diff, 0.0) ** 2
    return np.where(count > 0, np.sqrt(squares.sum(axis=0) / np.maximum(count, 1)), np.nan)


def compare(episode: ReplayEpisode, recording: ReplayRecording, tolerances: Tolerances,
            period_ns: int) -> ReplayComparison:
    """The replay against the recorded episode; `period_ns`: one frame's period at the replay's speed."""
    n = episode.frames
    frames = np.array([f for f, _ in recording.published], dtype=np.int64)
    instants = np.array([t for _, t in recording.published], dtype=np.int64)
    max_age = round(tolerances.max_age_s * NS)
    reach = int(round(tolerances.max_lag_s * NS / period_ns))
    best: tuple[float, int] | None = None
    for lag in range(-reach, reach + 1):
        positions, _, _ = _at(recording, episode, instants + lag * period_ns, max_age)
        rms = _rms(positions - episode.positions[frames]) if len(frames) else np.array([np.nan])
        score = float(np.sqrt(np.nanmean(rms ** 2))) if np.isfinite(rms).any() else np.inf
        if best is None or score < best[0] - 1e-12:
            best = (score, lag)
    lag = best[1] if best is not None else 0
    positions, forces, contact = _at(recording, episode, instants + lag * period_ns, max_age)
    replay_positions = np.full((n, len(episode.motors)), np.nan)
    replay_forces = np.full((n, len(episode.fingers)), np.nan)
    replay_contact = np.full((n, len(episode.fingers)), np.nan)
    replay_positions[frames], replay_forces[frames], replay_contact[frames] = positions, forces, contact
    matched = np.isfinite(replay_forces).all(axis=1) & np.isfinite(replay_positions).all(axis=1)

    # the replay's peak: every force sample from the first frame's publication to the goal's end
    start = int(instants[0]) if len(instants) else 0
    end = recording.ended_ns if recording.ended_ns is not None else np.iinfo(np.int64).max
    pads = []
    for f, finger in enumerate(episode.fingers):
        diff = np.abs(replay_forces[matched, f] - episode.pad_forces[matched, f])
        samples = recording.forces.get(finger)
        peak = np.nan
        if samples is not None and samples.stamps_ns:
            s, v = samples.ordered()
            window = v[(s >= start) & (s <= end)]
            peak = float(window.max()) if window.size else np.nan
        agreement = None
        if episode.contact is not None:
            both = matched & np.isfinite(replay_contact[:, f])
            if both.any():
                agreement = float(np.mean((replay_contact[both, f] > 0.5) == (episode.contact[both, f] > 0.5)))
        pads.append(PadComparison(finger, float(diff.max()) if diff.size else np.nan,
                                  float(diff.mean()) if diff.size else np.nan,
                                  float(episode.pad_forces[:, f].max()), peak, agreement))
    rms = _rms(replay_positions[matched] - episode.positions[matched]) if matched.any() \
        else np.full(len(episode.motors), np.nan)
    position_rms = {m: float(v) for m, v in zip(episode.motors, rms)}

    problems = []
    t = tolerances
    if not recording.played:
        problems.append(f"not every frame played: {recording.outcome}")
    if not matched.any():
        problems.append("no replayed frame had fresh /joint_states and wrenches to compare")
    elif recording.played and matched.sum() < t.min_matched_share * n:
        problems.append(f"{n - int(matched.sum())} of {n} frames unmatched (skipped by late ticks, or no fresh "
                        f"sample within {t.max_age_s:g} s): more than {1 - t.min_matched_share:.0%}")
    for pad in pads:
        if np.isfinite(pad.max_diff_n) and pad.max_diff_n > t.force_tolerance_n:
            problems.append(f"{pad.finger}: the replayed force differs from the recording by up to "
                            f"{pad.max_diff_n:.3f} N (tolerance {t.force_tolerance_n:g} N)")
        if np.isfinite(pad.replayed_peak_n) and pad.replayed_peak_n > t.touch_limit_n + t.overshoot_n:
            problems.append(f"{pad.finger}: the replay pressed {pad.replayed_peak_n:.3f} N, above the touch limit "
                            f"{t.touch_limit_n:g} N + {t.overshoot_n:g} N")
    for motor, value in position_rms.items():
        if np.isfinite(value) and value > t.position_tolerance_rad:
            problems.append(f"{motor}: position RMS {value:.3f} rad (tolerance {t.position_tolerance_rad:g} rad)")
    return ReplayComparison(episode.number, n, len(frames), int(matched.sum()), lag * period_ns / NS, pads,
                            position_rms, tolerances, problems, replay_positions, replay_forces)


def _n(value: float | None, unit: str, digits: int = 3) -> str:
    if value is None or not np.isfinite(value):
        return "-"
    return f"{value:.{digits}f}{unit}"


def report_lines(comparison: ReplayComparison, recording: ReplayRecording) -> list[str]:
    c, t = comparison, comparison.tolerances
    lines = [f"replay of episode {c.episode}: {c.played_frames} of {c.frames} frames played"
             f"{f' ({recording.skipped} skipped: late ticks)' if recording.skipped else ''}, {recording.outcome}",
             *(f"  note: {note}" for note in recording.notes),
             f"  matched frames: {c.matched_frames}" + (
                 f" (replayed frame k observed {c.lag_s * 1e3:+.0f} ms after its publication, the lag within "
                 f"+-{t.max_lag_s:g} s that fits the positions best)" if c.matched_frames else ""),
             "  pad normal force (N)  max|diff|  mean|diff|  recorded peak  replayed peak  contact agrees",
             ]
    for pad in c.pads:
        agrees = "-" if pad.contact_agreement is None else f"{pad.contact_agreement * 100:.0f}%"
        lines.append(f"  {pad.finger:<20} {_n(pad.max_diff_n, ''):>9}  {_n(pad.mean_diff_n, ''):>10}  "
                     f"{_n(pad.recorded_peak_n, ''):>13}  {_n(pad.replayed_peak_n, ''):>13}  {agrees:>14}")
    lines.append("  position RMS (rad): " + ", ".join(f"{m} {_n(v, '')}" for m, v in c.position_rms_rad.items()))
    lines.append(f"  tolerances: force {t.force_tolerance_n:g} N, touch limit {t.touch_limit_n:g} N + "
                 f"{t.overshoot_n:g} N, position RMS {t.position_tolerance_rad:g} rad")
    lines += verdict_lines("verdict", c.problems, "the replay matches the recording", "problem(s)")
    return lines


def plot_comparison(episode: ReplayEpisode, comparison: ReplayComparison, out: Path) -> Path:
    """Recorded against replayed: each motor's position, then each pad's normal force with the touch limit."""
    plt = pyplot()
    t = np.arange(episode.frames) / episode.fps
    rows = len(episode.motors) + 1
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2.2 * rows), sharex=True)
    for i, motor in enumerate(episode.motors):
        ax = axes[i]
        ax.plot(t, episode.positions[:, i], label="recorded")
        ax.plot(t, comparison.replay_positions[:, i], "--", label="replayed")
        ax.plot(t, episode.actions[:, i], ":", color="0.5", label="action")
        ax.set_ylabel(f"{motor} (rad)")
        ax.legend(loc="upper right", fontsize=8)
    ax = axes[-1]
    for f, finger in enumerate(episode.fingers):
        line, = ax.plot(t, episode.pad_forces[:, f], label=f"{finger} recorded")
        ax.plot(t, comparison.replay_forces[:, f], "--", color=line.get_color(), label=f"{finger} replayed")
    limit = comparison.tolerances.touch_limit_n
    ax.axhline(limit, color="k", ls="--", lw=1, label="touch limit")
    ax.set_ylabel("normal force fz (N)")
    ax.set_xlabel("time in the episode (s, at the recording's pace)")
    ax.legend(loc="upper right", ncol=3, fontsize=7)
    verdict = "matches" if comparison.ok else f"{len(comparison.problems)} problem(s)"
    return save_figure(fig, f"replay of episode {episode.number}: {verdict}", out)
