"""The hand's goals as a test sends and reads them: the one resend (a `not_ready` refusal while the
graph comes up), a goal's feedback and the reason of its end (its result's text, or for
GripperCommand, whose result has none, the manipulation node's `manipulation: goals` status on
/diagnostics), and a result's status name and reason.

`HandGoals` is the part of RosHarness that speaks this protocol; the rest of this module needs no
harness (tests without ROS import it too: the messages are imported where they are used)."""
from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from typing import Any

from prisma_common.goal_refusal import NOT_READY, refusal_code


def _result_text(result: Any) -> str | None:
    """The text a result carries: Grasp's, MoveMotors' or Teleoperate's reason, Manipulate's
    stop_reason; None for a result without one (control_msgs GripperCommand)."""
    return getattr(result, "reason", getattr(result, "stop_reason", None))


def refusal_for_now(result: Any) -> str | None:
    """The reason of a result that refused its goal because the graph is not ready yet (`not_ready:
    ...`: a stream it needs not flowing yet, the motor driver not up): the one refusal a test sends
    the same goal again for. Any other end (busy, sensor_stale, joint_limit, a timeout) is the
    test's outcome, never a reason to send it again. None for those."""
    reason = _result_text(result) or ""
    return reason if refusal_code(reason) == NOT_READY else None


@functools.cache
def goal_status_names() -> dict[int, str]:
    """action_msgs/GoalStatus's numbers -> names (4: "SUCCEEDED"), read from the message's own
    STATUS_* constants."""
    from action_msgs.msg import GoalStatus

    return {getattr(GoalStatus, n): n.removeprefix("STATUS_") for n in dir(GoalStatus) if n.startswith("STATUS_")}


def goal_status_name(status: int) -> str:
    """The name of a GoalStatus number ("SUCCEEDED"); the number itself, as text, for one it lacks."""
    return goal_status_names().get(status, str(status))


def goal_outcome(result: Any) -> tuple[str, str]:
    """(status name, reason) of an action's result: its text (`_result_text`), or for
    GripperCommand (no text) reached_goal, stalled or neither."""
    r = result.result
    reason = _result_text(r)
    if reason is None:
        reason = "reached_goal" if r.reached_goal else ("stalled" if r.stalled else "neither")
    return goal_status_name(result.status), reason


def gripper_goal(position: float, max_effort: float = 0.0) -> Any:
    """control_msgs/GripperCommand goal: `position` = the fingers motor angle in rad (0 = open)."""
    from control_msgs.action import GripperCommand

    goal = GripperCommand.Goal()
    goal.command.position, goal.command.max_effort = float(position), float(max_effort)
    return goal


def _has_no_reason(goal: Any) -> bool:
    """A goal whose result carries no reason text (control_msgs GripperCommand)."""
    return type(goal).__name__.startswith("GripperCommand")


class HandGoals:
    """RosHarness's goals to the hand's action servers (a mixin: RosHarness spins and collects)."""

    RETRY_SEC = 0.2  # between sends of a goal refused not_ready
    spin_until: Callable[..., bool]
    spin_for: Callable[[float], None]
    collect: Callable[..., Sequence]
    send_goal: Callable[..., Any]

    def __init__(self) -> None:
        super().__init__()
        self._feedback: dict[bytes, list] = {}  # goal id of a send_until_started goal -> its feedback messages
        self._goal_ends: Sequence | None = None  # /diagnostics, collected from the first GripperCommand sent

    def send_until_started(self, client: Any, goal: Any, timeout_sec: float = 30.0):
        """The one way a test resends a goal: again every RETRY_SEC while the server refuses it
        `not_ready` (the graph coming up; `refusal_for_now`), until `timeout_sec`. The hand's action
        servers accept every goal and abort one they cannot run yet at once, the reason in the
        result (prisma_common.goal_refusal); GripperCommand's result has no text, so its reason is
        the manipulation node's `manipulation: goals` status on /diagnostics naming the goal. Returns
        the ClientGoalHandle of the goal that started (its first feedback came) or ended any other
        way; AssertionError when it is still refused at the timeout."""
        deadline = time.monotonic() + timeout_sec
        # a client made without waiting (action_client(wait_sec=None)): a goal request sent before
        # its server is discovered gets no answer, which is not a refusal
        if not self.spin_until(client.server_is_ready, timeout_sec):
            raise AssertionError(f"{type(goal).__name__}: its action server did not appear in {timeout_sec} s")
        if _has_no_reason(goal) and self._goal_ends is None:
            from diagnostic_msgs.msg import DiagnosticArray

            self._goal_ends = self.collect(DiagnosticArray, "/diagnostics")
        while True:
            feedback: list = []
            handle = self.send_goal(client, goal, feedback)
            self._feedback[bytes(handle.goal_id.uuid)] = feedback
            if not handle.accepted:
                raise AssertionError(f"{type(goal).__name__} rejected: the hand's servers accept every goal")
            result = handle.get_result_async()
            self.spin_until(lambda: bool(feedback) or result.done(), 10.0)  # noqa: B023 - runs now
            reason = self._not_ready(goal, handle, result.result()) if result.done() else None
            if reason is None:
                return handle
            if time.monotonic() > deadline:
                raise AssertionError(f"{type(goal).__name__} still refused after {timeout_sec} s: {reason}")
            self.spin_for(self.RETRY_SEC)

    def feedback_of(self, handle: Any) -> list:
        """Every feedback message of a goal `send_until_started` sent, in arrival order (filled as the
        executor spins): the action client takes them anyway, so a test need not collect the
        feedback topic a second time."""
        return self._feedback[bytes(handle.goal_id.uuid)]

    def _not_ready(self, goal: Any, handle: Any, result: Any) -> str | None:
        """refusal_for_now of a goal's result; for a GripperCommand, of the reason the manipulation
        node put on /diagnostics for it (its log tells a storm's refusals once)."""
        if not _has_no_reason(goal):
            return refusal_for_now(result.result)
        if goal_status_name(result.status) != "ABORTED":
            return None
        why = self.goal_end_reason(handle)
        return why if why is not None and refusal_code(why) == NOT_READY else None

    def goal_end_reason(self, handle: Any, timeout_sec: float = 3.0) -> str | None:
        """The reason of a goal's end as the manipulation node's `manipulation: goals` status on
        /diagnostics names it (the goal's id in last_goal_id), waiting for it (published at the end
        and every second); None when it did not come. Needs a /diagnostics collection made before the
        goal was sent (send_until_started makes it for a GripperCommand)."""
        from prisma_manipulation.goal_ends import STATUS_NAME

        goal_id = bytes(handle.goal_id.uuid).hex()
        ends = self._goal_ends if self._goal_ends is not None else []

        def found() -> str | None:
            for msg in reversed(ends):
                for status in msg.status:
                    values = {v.key: v.value for v in status.values}
                    if status.name.endswith(STATUS_NAME) and values.get("last_goal_id") == goal_id:
                        return values.get("last_reason", "")
            return None

        self.spin_until(lambda: found() is not None, timeout_sec)
        return found()
