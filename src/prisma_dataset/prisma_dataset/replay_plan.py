"""What `prisma-dataset replay` plays and in which steps (ROS-free; replay_ros.py carries the steps out).

An episode's `action` column is the three motor targets the hand followed, one per frame. A replay
publishes them on prisma/teleop/motor_targets as the teleop node does, each with a fresh stamp, and
keeps a Teleoperate goal with the teleop node's default fields running, so the manipulation node's
touch limit and stale-input stop apply as they did in the recording. The steps:

1. priming: frame 0's action, `RESUME_SAMPLES` times (the teleop node lets its targets flow that long
   before it sends a goal), then the goal is sent;
2. lead-in, once the goal runs: frame 0's action held until the motors stand within `settle_rad` of
   the recorded frame 0's positions, at least `lead_in_s`, at most `lead_in_timeout_s` (then the
   replay plays on from where the hand stands, and the comparison shows it);
3. playing: frame k's action is due k / (fps * speed) s after frame 0's; a tick that comes late
   publishes the frame due then (the ones it passed are counted as skipped, never sent late);
4. tail: the last action held `tail_s` more (the comparison looks that far past the last frame), then
   the goal is cancelled, as the teleop node cancels it when the operator lets go.
A goal that ends on its own before that (input_stale, sensor_stale, a motor fault) ends the replay
there, as does another node starting to publish the targets (its goal cancelled); one refused
`not_ready` before the lead-in is sent again after `retry_s` (the graph coming up).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prisma_common.goal_refusal import NOT_READY, refusal_code
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_teleop.node_config import TeleopConfig
from prisma_teleop.teleop_core import RESUME_SAMPLES

from .bag_export import ACTION, CONTACT, STATE, WRENCH
from .lerobot_format import read_dataset, read_info
from .sampling import NS

FZ = 2  # observation.wrench's axis of the pad's normal force (fx fy fz tx ty tz)
NEEDED = (ACTION, STATE, WRENCH)


class ReplayError(ValueError):
    """An episode that cannot be replayed as asked; the message names the value and what to do."""


@dataclass(frozen=True)
class ReplayEpisode:
    """The recorded frames a replay plays and compares with: per frame the action (the motor
    targets, rad), the motor positions (rad), each pad's normal force (N) and contact flag."""

    number: int
    fps: int
    task: str
    actions: np.ndarray  # [n, motors]
    positions: np.ndarray  # [n, motors]
    pad_forces: np.ndarray  # [n, fingers]
    contact: np.ndarray | None  # [n, fingers], 1 = feasible contact; None when not recorded
    motors: tuple[str, ...] = MOTOR_NAMES
    fingers: tuple[str, ...] = FINGERS

    @property
    def frames(self) -> int:
        return len(self.actions)

    def targets(self, frame: int) -> dict[str, float]:
        return {m: float(v) for m, v in zip(self.motors, self.actions[frame])}


def episode_count(root: str | Path) -> int:
    """How many episodes meta/info.json says the dataset holds."""
    return int(read_info(root).get("total_episodes", 0))


def load_episode(root: str | Path, number: int) -> ReplayEpisode:
    """Episode `number` of the dataset at `root`; ReplayError for a number out of range or a dataset
    without the features a replay needs (action, observation.state, observation.wrench)."""
    count = episode_count(root)
    if not 0 <= number < count:
        have = f"episodes 0 .. {count - 1}" if count else "no episode"
        raise ReplayError(f"--episode {number}: the dataset at {root} has {have}")
    dataset = read_dataset(root)
    names = {f.name: f for f in dataset.features}
    missing = [n for n in NEEDED if n not in names]
    if missing:
        raise ReplayError(f"the dataset at {root} has no {', '.join(missing)}: a replay needs the motor targets "
                          f"(action), positions (observation.state) and wrenches (observation.wrench)")
    motors = tuple(names[ACTION].names or MOTOR_NAMES)
    if names[ACTION].shape != (len(motors),) or names[WRENCH].shape != (len(FINGERS), 6):
        raise ReplayError(f"the dataset at {root}: action of shape {names[ACTION].shape} and observation.wrench "
                          f"{names[WRENCH].shape}, a replay plays ({len(MOTOR_NAMES)},) and reads "
                          f"({len(FINGERS)}, 6)")
    episode = dataset.episodes[number]
    values = episode.values
    if episode.length == 0:
        raise ReplayError(f"--episode {number}: the episode has no frame")
    return ReplayEpisode(
        number, dataset.fps, episode.task,
        np.asarray(values[ACTION], dtype=np.float64),
        np.asarray(values[STATE][:, :len(motors)], dtype=np.float64),
        np.asarray(values[WRENCH][:, :, FZ], dtype=np.float64),
        np.asarray(values[CONTACT], dtype=np.float64) if CONTACT in values else None,
        motors)


@dataclass(frozen=True)
class ReplayOptions:
    speed: float = 1.0  # 1 = the recording's pace; 0.5 = half as fast
    lead_in_s: float = 0.5
    lead_in_timeout_s: float = 5.0
    settle_rad: float = 0.05
    tail_s: float = 0.2
    retry_s: float = TeleopConfig().retry_period  # a goal refused not_ready: sent again after this

    def __post_init__(self) -> None:
        if not (math.isfinite(self.speed) and 0.05 <= self.speed <= 4.0):
            raise ReplayError(f"--speed {self.speed}: give a factor from 0.05 to 4 (1 = as recorded)")


# ---- the steps, as data: replay_ros.py carries them out ---------------------------------------
@dataclass(frozen=True)
class Publish:
    """Publish these targets stamped `stamp_ns` (the tick's instant); `frame` is the episode's frame
    (None: frame 0's or the last one's action held in the priming, the lead-in or the tail)."""

    targets: dict[str, float]
    frame: int | None
    stamp_ns: int


@dataclass(frozen=True)
class SendGoal:
    """Send the Teleoperate goal (the teleop node's default fields)."""


@dataclass(frozen=True)
class CancelGoal:
    why: str


@dataclass(frozen=True)
class Finished:
    """The replay is over: `played` when every frame was published and the goal cancelled after."""

    outcome: str
    played: bool


Step = Publish | SendGoal | CancelGoal | Finished
PRIMING, WAITING_GOAL, LEAD_IN, PLAYING, TAIL, STOPPING, DONE = (
    "priming", "waiting for the goal", "lead-in", "playing", "tail", "stopping", "done")
STARTING = (PRIMING, WAITING_GOAL)  # before the goal runs


@dataclass
class ReplayCore:
    """A replay's decisions: `tick` on the node's timer (every frame period), `on_goal_running` once
    the goal runs (its first feedback), `on_goal_ended` with its reason. Every step it returns is to be carried out
    in order."""

    episode: ReplayEpisode
    options: ReplayOptions = field(default_factory=ReplayOptions)
    phase: str = PRIMING
    primed: int = 0
    published: list[tuple[int, int]] = field(default_factory=list)  # (frame, publish instant ns)
    skipped: int = 0
    lead_in_note: str = ""
    _phase_start_ns: int = 0
    _last_due: int = -1
    _retry_at_ns: int = 0
    _stopped_why: str = ""  # why the replay cancelled its goal before the last frame

    @property
    def period_ns(self) -> int:
        """One frame's period at the replay's speed."""
        return round(NS / (self.episode.fps * self.options.speed))

    def tick(self, now_ns: int, positions: Sequence[float] | None) -> list[Step]:
        """`positions`: the motors' newest positions (rad, in the episode's motor order), None before any."""
        e, o = self.episode, self.options
        if self.phase == PRIMING:
            if now_ns < self._retry_at_ns:
                return [Publish(e.targets(0), None, now_ns)]
            self.primed += 1
            steps: list[Step] = [Publish(e.targets(0), None, now_ns)]
            if self.primed >= RESUME_SAMPLES:
                self.phase = WAITING_GOAL
                steps.append(SendGoal())
            return steps
        if self.phase in (WAITING_GOAL, LEAD_IN):
            if self.phase == LEAD_IN and self._settled(now_ns, positions):
                self.phase, self._phase_start_ns = PLAYING, now_ns
            else:
                return [Publish(e.targets(0), None, now_ns)]
        if self.phase == PLAYING:
            # a timer's tick up to a quarter period early counts as on time
            due = min((now_ns - self._phase_start_ns + self.period_ns // 4) // self.period_ns, e.frames - 1)
            if due > self._last_due:
                self.skipped += due - self._last_due - 1
                self._last_due = due
                self.published.append((int(due), now_ns))
                if due == e.frames - 1:
                    self.phase, self._phase_start_ns = TAIL, now_ns
                return [Publish(e.targets(int(due)), int(due), now_ns)]
            return [Publish(e.targets(self._last_due), None, now_ns)] if self._last_due >= 0 else []
        if self.phase == TAIL:
            if now_ns - self._phase_start_ns >= o.tail_s * NS:
                self.phase = STOPPING
                return [CancelGoal("the episode's last frame played")]
            return [Publish(e.targets(e.frames - 1), None, now_ns)]
        return []

    def _settled(self, now_ns: int, positions: Sequence[float] | None) -> bool:
        o = self.options
        waited = (now_ns - self._phase_start_ns) / NS
        if waited < o.lead_in_s:
            return False
        if positions is not None:
            off = np.abs(np.asarray(positions, dtype=np.float64) - self.episode.positions[0])
            if float(off.max()) <= o.settle_rad:
                return True
        if waited >= o.lead_in_timeout_s:
            where = "no /joint_states came" if positions is None else \
                f"{float(off.max()):.3f} rad from the recorded frame 0"
            self.lead_in_note = f"the hand did not settle at frame 0 in {o.lead_in_timeout_s:g} s ({where}); played on"
            return True
        return False

    def on_goal_running(self, now_ns: int) -> None:
        if self.phase == WAITING_GOAL:
            self.phase, self._phase_start_ns = LEAD_IN, now_ns

    def on_goal_ended(self, reason: str, now_ns: int) -> list[Step]:
        """The goal's end (its result's reason: canceled, input_stale: ..., a refusal)."""
        if self.phase == STOPPING:
            self.phase = DONE
            if self._stopped_why:
                return [Finished(self._stopped_why, False)]
            return [Finished("played every frame", True)]
        if self.phase in (WAITING_GOAL, LEAD_IN) and refusal_code(reason) == NOT_READY:
            # the graph is coming up: primed again and sent again after retry_s, as the teleop node does
            self.phase, self.primed = PRIMING, 0
            self._retry_at_ns = now_ns + round(self.options.retry_s * NS)
            return []
        self.phase, where = DONE, self._where()
        return [Finished(f"the Teleoperate goal ended {where}: {reason}", False)]

    def _where(self) -> str:
        return f"at frame {self._last_due} of {self.episode.frames}" if self.published else f"in the {self.phase}"

    def on_other_publisher(self, names: Sequence[str]) -> list[Step]:
        """Another node began publishing the targets mid-replay (a teleop node started): two sources
        would fight over the hand, so the replay stops, its goal cancelled."""
        if self.phase in (STOPPING, DONE):
            return []
        why = f"stopped {self._where()}: {', '.join(names)} began publishing the targets"
        if self.phase in STARTING:  # no goal of ours runs (one on its way is cancelled as it ends: see the node)
            self.phase = DONE
            return [CancelGoal(why), Finished(why, False)]
        self.phase, self._stopped_why = STOPPING, why
        return [CancelGoal(why)]
