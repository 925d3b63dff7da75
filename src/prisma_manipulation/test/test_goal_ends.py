"""GoalEnds: a GripperCommand storm's failures logged once per episode, every other kind's end logged,
and the last end on /diagnostics (`manipulation: goals`)."""
from __future__ import annotations

from prisma_common.diagnostics import OK, WARN
from prisma_manipulation.goal_ends import ABORTED, CANCELED, REFUSED, SUCCEEDED, GoalEnd, GoalEnds, same_reason
from prisma_manipulation.goal_kinds import GOAL_KINDS

NOT_HOMED = "not_homed: fingers (id 1) not homed since the servo powered up (the zero may be a turn off): home first"


def quiet_gripper() -> GoalEnds:
    """As the node makes it: quiet about the kinds whose result has no text."""
    return GoalEnds(frozenset(k.name for k in GOAL_KINDS if not k.result_has_text))


def test_only_the_gripper_kind_has_no_result_text():
    assert quiet_gripper().quiet_kinds == {"gripper"}


def test_a_gripper_storm_is_logged_once_per_episode_and_every_end_reaches_diagnostics():
    ends = quiet_gripper()
    storm = [GoalEnd("gripper", ABORTED, NOT_HOMED, f"{i:032x}") for i in range(50)]
    assert [ends.ended(e) for e in storm] == [True] + [False] * 49
    status = ends.status()
    assert (status.name, status.level) == ("manipulation: goals", WARN)
    assert status.message == f"gripper aborted: {NOT_HOMED} (50 in a row)"
    assert status.values == {"goals": "50", "last_kind": "gripper", "last_end": "aborted", "last_reason": NOT_HOMED,
                             "last_goal_id": f"{49:032x}", "in_a_row": "50"}
    # another reason is news; numbers aside it is the same reason
    assert ends.ended(GoalEnd("gripper", REFUSED, "not_ready: taxels/index silent for 110 ms"))
    assert not ends.ended(GoalEnd("gripper", REFUSED, "not_ready: taxels/index silent for 130 ms"))
    assert ends.ended(GoalEnd("gripper", REFUSED, "busy: a grasp goal is running"))
    # a goal that ran its course ends the episode: the same failure after it is logged again
    assert ends.ended(GoalEnd("gripper", SUCCEEDED, "reached"))
    assert ends.status().level == OK and ends.status().message == "gripper succeeded: reached"
    assert ends.ended(GoalEnd("gripper", ABORTED, NOT_HOMED))
    assert ends.ended(GoalEnd("gripper", CANCELED, "canceled"))


def test_a_kind_with_a_result_text_is_logged_at_every_end():
    ends = quiet_gripper()
    assert all(ends.ended(GoalEnd("grasp", ABORTED, NOT_HOMED)) for _ in range(3))
    assert ends.status().message == f"grasp aborted: {NOT_HOMED} (3 in a row)"
    # the other kind's ends in between do not make a gripper failure old news
    assert ends.ended(GoalEnd("gripper", ABORTED, NOT_HOMED))


def test_before_any_goal_the_status_says_so():
    status = GoalEnds().status()
    assert (status.level, status.message, status.values) == (OK, "no goal yet", {"goals": "0"})


def test_same_reason_ignores_numbers_only():
    index = "sensor_stale (taxels/index silent for 110 ms)"
    assert same_reason(index, "sensor_stale (taxels/index silent for 2.5 ms)")
    assert not same_reason(index, "sensor_stale (taxels/thumb silent for 110 ms)")
