"""How the manipulation node tells its goals' ends beyond their results, without ROS: which ends its
log shows, and the `manipulation: goals` status on /diagnostics (the last goal's kind, end and reason).

A kind whose result has no text (GripperCommand: position, effort, stalled, reached_goal) leaves
its client only the log and /diagnostics to learn why a goal failed. A client that sends such goals
in a storm (a teleop loop, a script resending at once) would fill the log with the same line, so
its failures are logged once per episode: the first end of a run of ends with the same reason (the
same text, numbers aside: `silent for 110 ms` and `silent for 130 ms` are one reason), and again
when the reason changes or after a goal that succeeded or was canceled. /diagnostics carries every
end: the last one, and how many came in a row with its reason. The other kinds carry their reason
in their result and are logged at every end, as before.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from prisma_common.diagnostics import OK, WARN, DiagnosticStatusData

SUCCEEDED, ABORTED, CANCELED, REFUSED = "succeeded", "aborted", "canceled", "refused"
STATUS_NAME = "manipulation: goals"
_NUMBER = re.compile(r"\d+(\.\d+)?")


@dataclass(frozen=True)
class GoalEnd:
    """One goal's end: its kind's name ("gripper"), how it ended (SUCCEEDED, ABORTED, CANCELED, or
    REFUSED before it started), the reason as its result or the log states it, and the goal's id (hex)."""

    kind: str
    end: str
    reason: str
    goal_id: str = ""

    @property
    def failed(self) -> bool:
        return self.end in (ABORTED, REFUSED)


def same_reason(a: str, b: str) -> bool:
    """Whether two reasons say the same, numbers aside (a stream silent for 110 or for 130 ms)."""
    return _NUMBER.sub("#", a) == _NUMBER.sub("#", b)


class GoalEnds:
    """The ends of the node's goals, fed one by one (`ended`). `quiet_kinds`: the kinds whose
    failures are logged once per episode (those whose result has no text)."""

    def __init__(self, quiet_kinds: frozenset[str] = frozenset()) -> None:
        self.quiet_kinds = quiet_kinds
        self.last: GoalEnd | None = None
        self.in_a_row = 0  # ends in a row with the last one's kind, end and reason
        self.count = 0
        self._episode: dict[str, GoalEnd] = {}  # per quiet kind: the failure its log line told

    def ended(self, end: GoalEnd) -> bool:
        """Record an end; True when the node logs it."""
        self.count += 1
        last = self.last
        repeated = last is not None and (last.kind, last.end) == (end.kind, end.end) and same_reason(last.reason,
                                                                                                     end.reason)
        self.in_a_row = self.in_a_row + 1 if repeated else 1
        self.last = end
        if end.kind not in self.quiet_kinds:
            return True
        if not end.failed:
            self._episode.pop(end.kind, None)  # a goal that ran its course: the next failure is news
            return True
        told = self._episode.get(end.kind)
        if told is not None and told.end == end.end and same_reason(told.reason, end.reason):
            return False
        self._episode[end.kind] = end
        return True

    def status(self) -> DiagnosticStatusData:
        """`manipulation: goals`: WARN while the last goal failed (refused or aborted), else OK."""
        end = self.last
        if end is None:
            return DiagnosticStatusData(STATUS_NAME, OK, "no goal yet", values={"goals": "0"})
        row = f" ({self.in_a_row} in a row)" if self.in_a_row > 1 else ""
        return DiagnosticStatusData(STATUS_NAME, WARN if end.failed else OK, f"{end.kind} {end.end}: {end.reason}{row}",
                                    values={"goals": str(self.count), "last_kind": end.kind, "last_end": end.end,
                                            "last_reason": end.reason, "last_goal_id": end.goal_id,
                                            "in_a_row": str(self.in_a_row)})
