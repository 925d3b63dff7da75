"""The goal-kind shape (goal_kind.py): the core serves every kind in its list the same way, and a
kind with an extra input stream (as teleoperation follows the glove's targets) is one class and
one more entry: it is admitted before its input flows and waits for it, steps once per scan with
the input's latest value (sample-and-hold: the input never shares a scan's stamp), ends with its own
reason when the input falls silent, and is one goal at a time with the others."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from prisma_manipulation.controllers import (
    ControlInput,
    ControlOutput,
    Controller,
    JointSample,
    MotorCommand,
)
from prisma_manipulation.goal_kind import Built, GoalContext, GoalKind, InputStream, Streams
from prisma_manipulation.goal_kinds import GOAL_KINDS
from prisma_manipulation.manipulation_core import (
    Feedback,
    Finished,
    GraspRequest,
    ManipulationCore,
    SendMove,
    StopMotors,
)
from prisma_manipulation.node_config import ManipulationConfig

MS = 1_000_000
JOINTS = {"fingers": 1.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}
VOLTS = np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], dtype=np.float32)


@dataclass(frozen=True)
class FollowRequest:
    max_force: float = 1.0


@dataclass(frozen=True)
class FollowStatus:
    target: float
    index_force: float


class FollowController(Controller):
    """Drives the fingers toward the latest target (rad) at 1 rpm per 0.1 rad of error."""

    fingers = ("index",)

    def __init__(self, limits: Any) -> None:
        super().__init__(limits)
        self.target = 0.0

    def _on_start(self, joints: JointSample) -> ControlOutput:
        return self._set(joints.stamp_ns, "wait", MotorCommand.stop())

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        if "glove/targets" not in inp.inputs:
            return self._set(inp.stamp_ns, "wait", MotorCommand.stop())
        self.target = inp.inputs["glove/targets"]
        rpm = round((self.target - inp.joints.positions["fingers"]) * 10.0, 6)
        return self._set(inp.stamp_ns, "follow", MotorCommand.of(fingers=rpm))


class FollowGoal(GoalKind[FollowRequest]):
    name, label = "follow", "Follow"
    action, action_type = "prisma/follow", "prisma_msgs/action/Grasp"
    request_type = FollowRequest
    inputs = (InputStream("glove/targets", "prisma/glove/targets", "std_msgs/msg/Float64",
                          lambda msg: (0, float(msg.data))),)

    def resolve(self, req: FollowRequest, ctx: GoalContext) -> tuple[FollowRequest | None, str | None]:
        return (req, None) if req.max_force > 0 else (None, f"max_force {req.max_force} must be > 0")

    def streams(self, req: FollowRequest, ctx: GoalContext) -> Streams:
        return Streams(("index",), ("index",), inputs=("glove/targets",))

    def build(self, req: FollowRequest, ctx: GoalContext) -> Built:
        return Built(FollowController(ctx.limits))

    def status(self, controller: Controller, ctx: GoalContext) -> FollowStatus:
        assert isinstance(controller, FollowController)
        return FollowStatus(controller.target, ctx.forces.get("index", 0.0))

    def idle_status(self, ctx: GoalContext) -> FollowStatus:
        return FollowStatus(0.0, 0.0)

    def stale_reason(self, stream: str) -> str:
        return "input_stale"


def _scan(core, t_ms, target=None, joints=True):
    """One tactile scan at t_ms; a target comes 3 ms before it, stamped then, as a glove's sample
    does: from another device, it never shares a scan's stamp."""
    t = t_ms * MS
    out = core.on_input("glove/targets", t - 3 * MS, target, t - 3 * MS) if target is not None else []
    out += core.on_joints(JointSample(t, JOINTS), t) if joints else []
    out += core.on_taxels("index", t, VOLTS, t)[1] + core.on_taxels("thumb", t, VOLTS, t)[1]
    out += core.on_wrench("index", t, 0.4, t) + core.on_wrench("thumb", t, 0.3, t)
    return out


def _moves(actions):
    return [a for a in actions if not isinstance(a, Feedback)]


def test_a_kind_with_an_extra_input_is_one_class_and_one_entry():
    core = ManipulationCore(ManipulationConfig(), kinds=GOAL_KINDS + (FollowGoal(),))
    _scan(core, 0)
    assert str(core.accept(FollowRequest(-1.0), True, 0)) == "invalid: max_force -1.0 must be > 0"
    # admitted before its input flows: the controller waits for it
    assert core.accept(FollowRequest(), True, 0) is None
    assert str(core.accept(GraspRequest("pinch"), True, 0)) == "busy: a follow goal was accepted and is starting"
    assert core.start(FollowRequest(), 0) == [Feedback("follow", "wait", FollowStatus(0.0, 0.4))]
    assert core.kind == "follow" and str(core.accept(GraspRequest("pinch"), True, 0)) == \
        "busy: a follow goal is running"
    # scans without an input step the controller without it; it waits, and waiting is never stale
    for t_ms in range(10, 300, 10):
        assert _scan(core, t_ms) == [Feedback("follow", "wait", FollowStatus(0.0, 0.4))]
    # the target comes between two scans: the next scan steps with it
    assert _scan(core, 300, target=2.0) == [
        SendMove({"fingers": 10.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}, 0.3, 300 * MS),
        Feedback("follow", "follow", FollowStatus(2.0, 0.4))]
    # the glove falls silent while the sensors flow: the goal ends with the kind's own reason, counted
    # from the last target's receipt (297 ms)
    actions = []
    for t_ms in range(310, 500, 10):
        actions += _scan(core, t_ms)
    assert [type(a) for a in actions[-3:]] == [StopMotors, Feedback, Finished]
    done = actions[-1]
    assert (done.kind, done.success, done.reason, done.detail) == ("follow", False, "input_stale",
                                                                   "prisma/glove/targets silent for 103 ms")
    assert not core.busy and core.accept(GraspRequest("pinch"), True, 400 * MS) is None


def test_a_kind_steps_once_per_scan_with_the_latest_value_of_its_input():
    """Sample-and-hold: a glove's targets at their own rate and stamps; every tactile scan steps the
    controller with the newest one received before it, held over scans without a new one."""
    core = ManipulationCore(ManipulationConfig(), kinds=(FollowGoal(),))
    _scan(core, 0, target=1.5)
    assert core.accept(FollowRequest(), True, 0) is None
    core.start(FollowRequest(), 0)
    assert _moves(_scan(core, 10)) == [SendMove({"fingers": 5.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}, 0.3,
                                                10 * MS)]
    # two targets between scans: the newer is followed; a scan without one keeps it
    core.on_input("glove/targets", 12 * MS, 3.0, 12 * MS)
    core.on_input("glove/targets", 16 * MS, 2.5, 16 * MS)
    assert _moves(_scan(core, 20)) == [SendMove({"fingers": 15.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}, 0.3,
                                                20 * MS)]
    fed = _scan(core, 30)
    assert _moves(fed) == [] and fed[-1].status == FollowStatus(2.5, 0.4)


def test_an_input_older_than_its_timeout_at_the_start_is_not_followed():
    core = ManipulationCore(ManipulationConfig(), kinds=(FollowGoal(),))
    _scan(core, 0, target=1.5)
    for t_ms in range(10, 200, 10):
        _scan(core, t_ms)
    assert core.accept(FollowRequest(), True, 190 * MS) is None
    core.start(FollowRequest(), 190 * MS)
    # 1.5 rad came 193 ms before the start (stale_timeout 0.1 s): the goal waits for a new target
    assert [(a.phase, a.status.target) for a in _scan(core, 200)] == [("wait", 0.0)]
    assert _moves(_scan(core, 210, target=0.5)) == [SendMove({"fingers": -5.0, "thumb_flexion": 0.0,
                                                              "thumb_rotation": 0.0}, 0.3, 210 * MS)]


def test_a_request_of_no_kind_is_a_type_error():
    core = ManipulationCore(ManipulationConfig())
    with pytest.raises(TypeError, match="FollowRequest is none of the goal requests"):
        core.accept(FollowRequest(), True, 0)
    assert core.refused("grasp", core.resolve(GraspRequest("roll"))[1]).reason == \
        "invalid: grasp 'roll' is not one of ['lateral', 'pinch', 'power']"
