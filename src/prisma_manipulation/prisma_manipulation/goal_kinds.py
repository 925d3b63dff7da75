"""The goal kinds the manipulation node serves, one action server each (goal_kind.py says what a kind
is): the one list the node, the core, the closed loop and the sim recorder read. A new kind is its
module and one line here; a test adds one the same way (`GOAL_KINDS + (MY_GOAL,)`, passed as `kinds`).
"""
from __future__ import annotations

from typing import Any

from .goal_kind import GoalKind
from .grasp_goal import GRASP_GOAL
from .gripper_goal import GRIPPER_GOAL
from .manipulate_goal import MANIPULATE_GOAL
from .teleop_goal import TELEOP_GOAL

GOAL_KINDS: tuple[GoalKind, ...] = (GRASP_GOAL, MANIPULATE_GOAL, GRIPPER_GOAL, TELEOP_GOAL)


def kind_named(name: str, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> GoalKind:
    """The kind called `name` ("grasp", `GoalKind.name`) or served on the action `name` (its server's
    last name: "teleoperate" for prisma/teleoperate); ValueError naming the choices."""
    for kind in kinds:
        if name in (kind.name, kind.action.rsplit("/", 1)[-1]):
            return kind
    raise ValueError(f"no goal kind {name!r}; have {', '.join(k.name for k in kinds)}")


def kind_of(request: Any, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> GoalKind:
    """The kind whose request `request` is (by its type); TypeError naming the kinds' requests."""
    for kind in kinds:
        if type(request) is kind.request_type:
            return kind
    raise TypeError(f"{type(request).__name__} is none of the goal requests "
                    f"{[k.request_type.__name__ for k in kinds]}")
