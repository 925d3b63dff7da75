"""Is a sample's header stamp one to act on? The judgement every node on the control path makes of
what it follows (the teleop node of the glove's samples, the manipulation node of the motor targets,
taxels, wrenches and joint states), ROS-free.

A sample is refused when its stamp is
- older than `max_age_ns` on arrival, by the receiving node's clock: the hand would follow the past;
  a stamp of 0 is the commonest case and named as such: its publisher never stamped it (`ros2 topic
  pub` without `header: auto`, a glove driver that leaves the header empty);
- ahead of the receiving node's clock by more than `max_ahead_ns`: its publisher's clock runs ahead
  of this computer's (not synchronised), so its age cannot be known.
The receiving node's clock is the one to compare with: under use_sim_time it is /clock, so a bag
played with `--clock` passes as live data, and a simulation whose time starts at 0 stamps its first
samples 0 legitimately (no older than its clock). A node whose clock has not started (use_sim_time
before the first /clock: now 0) judges nothing.

`StampGate` keeps one stream's judgement over time and says so once per episode: the first refused
sample gives a line for the log naming the stream, what is wrong and the fix; a sample refused for
another kind of reason gives another; the first accepted sample after refusals gives one line that it
is accepted again. While the refusal lasts, `refused` holds its line (for /diagnostics).
"""
from __future__ import annotations

from dataclasses import dataclass

NS = 1_000_000_000
ZERO, AHEAD, OLD = "zero", "ahead", "old"  # the kinds of a refused stamp

FIXES = {
    ZERO: "publish header.stamp (ros2 topic pub: header: auto)",
    AHEAD: "synchronise the publisher's clock with this computer's (NTP, chrony)",
    OLD: "stamp each sample when it is taken, on a clock synchronised with this computer's; a bag: "
         "ros2 bag play --clock with use_sim_time:=true",
}


@dataclass(frozen=True)
class StampLimits:
    """How far a stamp may lie from the receiving node's clock: older by at most `max_age_ns`, ahead
    by at most `max_ahead_ns`."""

    max_age_ns: int
    max_ahead_ns: int

    def __post_init__(self) -> None:
        for name in ("max_age_ns", "max_ahead_ns"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} {getattr(self, name)} must be > 0")

    @classmethod
    def of_seconds(cls, max_age_s: float, max_ahead_s: float) -> StampLimits:
        return cls(int(round(max_age_s * NS)), int(round(max_ahead_s * NS)))


@dataclass(frozen=True)
class StampProblem:
    """Why a stamp is refused: its kind (ZERO, AHEAD, OLD) and the words for it."""

    kind: str
    what: str

    @property
    def fix(self) -> str:
        return FIXES[self.kind]


def stamp_problem(stamp_ns: int, now_ns: int, limits: StampLimits) -> StampProblem | None:
    """None when a sample stamped `stamp_ns` and received at `now_ns` (the receiving node's clock)
    may be acted on, else what is wrong with its stamp."""
    if now_ns <= 0:  # the node's clock has not started (use_sim_time, no /clock yet): nothing to compare with
        return None
    if now_ns - stamp_ns > limits.max_age_ns:
        if stamp_ns == 0:
            return StampProblem(ZERO, "stamped 0")
        return StampProblem(OLD, f"stamped {(now_ns - stamp_ns) / NS:.2f} s before it arrived "
                                 f"(limit {limits.max_age_ns / NS:g} s)")
    if stamp_ns - now_ns > limits.max_ahead_ns:
        return StampProblem(AHEAD, f"stamped {(stamp_ns - now_ns) / NS:.2f} s ahead of this node's clock "
                                   f"(limit {limits.max_ahead_ns / NS:g} s)")
    return None


@dataclass(frozen=True)
class StampNews:
    """A line for the receiving node's log: `level` warning (refusals start) or info (accepted again)."""

    level: str
    text: str


class StampGate:
    """One stream's stamps over time (the module docstring says how)."""

    def __init__(self, stream: str, limits: StampLimits) -> None:
        self.stream = stream
        self.limits = limits
        self.problem: StampProblem | None = None  # the latest sample's, while refused
        self.refused_count = 0  # samples refused in the current episode
        self.refused_total = 0

    @property
    def refused(self) -> str | None:
        """The refusal's line while it lasts (the latest refused sample's numbers), else None."""
        return None if self.problem is None else self.describe(self.problem)

    def describe(self, problem: StampProblem) -> str:
        return f"{self.stream} {problem.what}: {problem.fix}"

    def judge(self, stamp_ns: int, now_ns: int) -> tuple[bool, StampNews | None]:
        """(whether to act on the sample, a line for the log when the episode starts, changes or ends)."""
        problem = stamp_problem(stamp_ns, now_ns, self.limits)
        before, self.problem = self.problem, problem
        if problem is None:
            if before is None:
                return True, None
            count, self.refused_count = self.refused_count, 0
            return True, StampNews("info", f"{self.stream} accepted again ({count} samples refused: "
                                           f"{before.what.split(' (')[0]})")
        self.refused_count += 1
        self.refused_total += 1
        if before is not None and before.kind == problem.kind:
            return False, None
        return False, StampNews("warning", f"{self.describe(problem)}; its samples are refused until then")
