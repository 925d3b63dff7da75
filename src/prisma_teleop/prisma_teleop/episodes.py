"""Episodes of a demonstration, ROS-free: when one starts and ends, its task and its outcome, as the
markers the teleop node publishes on prisma/teleop/episode (prisma_msgs/msg/EpisodeMarker) and
prisma-dataset export cuts episodes by (docs/datasets.md, "Episode markers").

`EpisodeMarks` (owned by the teleop core, `_Engaging.episodes`; prisma-sim's sessions use it the
same way) returns every decision as an `EpisodeMarker` (data); the node publishes it. Rules:
- engaging starts an episode when none is open, with the task of `episode_task` (the parameter);
- letting go ends the open one; so does the Teleoperate goal ending for good (a fault: the teleop
  core disengages), with outcome failure and the goal's end reason;
- the operator's service: `mark("start", task)` starts one (refused while one is open: end it
  first), `mark("end", outcome=...)` ends the open one with the operator's outcome (success or
  failure); without an outcome it is derived, as when letting go:
- derived outcome: a goal still running at the end: success (the operator ended a demonstration
  that ran); else the last goal's end in the episode decides: `succeeded` (a Grasp or an open
  GripperCommand that reached its end) is success, any other end (sensor_stale, motor_fault,
  input_stale, a refusal) is failure with that reason; no goal in the episode: failure.
Indices count from 0 and are never reused while the node runs; a start and its end share one.
"""
from __future__ import annotations

from dataclasses import dataclass

START, END = "start", "end"
EVENTS = (START, END)
SUCCESS, FAILURE = "success", "failure"
OUTCOMES = (SUCCESS, FAILURE)
DEFAULT_TASK = "teleoperate the PRISMA hand"
# the end reasons of a goal that did reach its end (GoalKeeper.last_end's words)
SUCCEEDED = "succeeded"


@dataclass(frozen=True)
class EpisodeMarker:
    """One marker: prisma_msgs/msg/EpisodeMarker without ROS (`stamp_ns`: its header stamp)."""

    stamp_ns: int
    episode: int
    event: str
    task: str
    outcome: str = ""
    reason: str = ""

    def describe(self) -> str:
        if self.event == START:
            return f"episode {self.episode} started ({self.reason}): {self.task}"
        return f"episode {self.episode} ended {self.outcome} ({self.reason}): {self.task}"


class EpisodeRefused(ValueError):
    """A service request that cannot be carried out; the message says why and what to do."""


class EpisodeMarks:
    """The open episode, if any, and what ends it (the module docstring gives the rules)."""

    def __init__(self, task: str = DEFAULT_TASK) -> None:
        self.task = task  # the parameter episode_task: the task of an episode engaging starts
        self.open: EpisodeMarker | None = None  # the open episode's start marker
        self.next_index = 0
        self.last: EpisodeMarker | None = None  # the last end marker
        self._goal_running = False
        self._last_goal_end: tuple[bool, str] | None = None  # in the open episode: (succeeded, reason)

    # ---- what the teleop core tells it --------------------------------------------------------
    def goal_started(self) -> None:
        self._goal_running = True

    def goal_ended(self, reason: str, success: bool) -> None:
        """Any goal's end (`reason` as GoalKeeper.last_end says it: `succeeded`, `canceled`,
        `sensor_stale: ...`)."""
        self._goal_running = False
        if self.open is not None:
            self._last_goal_end = (success and reason in (SUCCEEDED, ""), reason or SUCCEEDED)

    def engaged(self, now_ns: int) -> list[EpisodeMarker]:
        """Engaging: a new episode, unless one is open (started by the service)."""
        return [] if self.open is not None else [self._start(now_ns, self.task, "engaged")]

    def let_go(self, now_ns: int, why: str = "let go") -> list[EpisodeMarker]:
        """Letting go: the open episode ends with the derived outcome."""
        if self.open is None:
            return []
        outcome, reason = self.derived_outcome()
        return [self._end(now_ns, outcome, f"{why}; {reason}")]

    def failed(self, now_ns: int, reason: str) -> list[EpisodeMarker]:
        """The goal ended for good and teleoperation disengaged: failure with the goal's reason."""
        if self.open is None:
            return []
        self._goal_running = False
        return [self._end(now_ns, FAILURE, f"the goal ended {reason}")]

    def mark(self, event: str, now_ns: int, task: str = "", outcome: str = "") -> EpisodeMarker:
        """The operator's service; EpisodeRefused says why it cannot be done."""
        if event == START:
            if self.open is not None:
                raise EpisodeRefused(f"episode {self.open.episode} ({self.open.task}) is open: end it first "
                                     f"(event 'end', outcome success or failure)")
            if outcome:
                raise EpisodeRefused(f"outcome {outcome!r} given to a start: an outcome belongs to an end")
            return self._start(now_ns, task.strip() or self.task, "the operator")
        if event == END:
            if self.open is None:
                raise EpisodeRefused("no episode is open: start one (event 'start', or engage)")
            if outcome and outcome not in OUTCOMES:
                raise EpisodeRefused(f"outcome {outcome!r}: give {' or '.join(OUTCOMES)}, or nothing to derive it "
                                     f"from the goal's end")
            if task:
                raise EpisodeRefused(f"task {task!r} given to an end: the task is the start's "
                                     f"({self.open.task})")
            if outcome:
                return self._end(now_ns, outcome, "the operator")
            derived, reason = self.derived_outcome()
            return self._end(now_ns, derived, f"the operator; {reason}")
        raise EpisodeRefused(f"event {event!r}: give {' or '.join(EVENTS)}")

    # ---- what it says -------------------------------------------------------------------------
    def derived_outcome(self) -> tuple[str, str]:
        """(outcome, why) of the open episode, were it to end now without the operator's word."""
        if self._goal_running:
            return SUCCESS, "a goal was running"
        if self._last_goal_end is None:
            return FAILURE, "no goal ran in the episode"
        succeeded, reason = self._last_goal_end
        return (SUCCESS if succeeded else FAILURE), f"the last goal ended {reason}"

    def status(self, now_ns: int) -> dict[str, str]:
        """The teleop status's values (/diagnostics)."""
        if self.open is not None:
            seconds = (now_ns - self.open.stamp_ns) / 1e9
            episode = f"{self.open.episode} open for {seconds:.1f} s: {self.open.task}"
        else:
            episode = "none open"
        last = self.last.describe() if self.last is not None else "none"
        return {"episode": episode, "episode_task": self.task, "last_episode": last}

    # ---- the markers --------------------------------------------------------------------------
    def _start(self, now_ns: int, task: str, reason: str) -> EpisodeMarker:
        marker = EpisodeMarker(now_ns, self.next_index, START, task, "", reason)
        self.open, self.next_index, self._last_goal_end = marker, self.next_index + 1, None
        return marker

    def _end(self, now_ns: int, outcome: str, reason: str) -> EpisodeMarker:
        assert self.open is not None
        marker = EpisodeMarker(now_ns, self.open.episode, END, self.open.task, outcome, reason)
        self.open, self.last, self._last_goal_end = None, marker, None
        return marker
