"""The GripperCommand goal kind (control_msgs/action/GripperCommand on /prisma/gripper_cmd): the
fingers to a position, every configured pad's force limited (gripper_controller.py). Feedback and
result carry the fingers position (rad), the highest pad force (N), stalled and reached_goal; the
result has no text, so a failure's reason is in the log (once per episode) and on /diagnostics
(`manipulation: goals`, goal_ends.py)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from prisma_common.topics import GRIPPER_ACTION

from .controllers import Controller
from .goal_kind import Built, Feedback, Finished, GoalContext, GoalKind, Streams, Types, f32, finite
from .gripper_controller import GripperController


@dataclass(frozen=True)
class GripperRequest:
    position: float  # fingers motor target, rad: 0 = open (gripper_controller.py)
    max_effort: float = 0.0  # N on the estimated pad forces; 0 = configured default


@dataclass(frozen=True)
class GripperStatus:
    position: float = 0.0  # fingers motor angle, rad
    effort: float = 0.0  # highest estimated pad force, N
    stalled: bool = False
    reached_goal: bool = False


class GripperGoal(GoalKind[GripperRequest]):
    name, label = "gripper", "GripperCommand"
    action, action_type = GRIPPER_ACTION, "control_msgs/action/GripperCommand"
    request_type = GripperRequest
    result_has_text = False

    def resolve(self, req: GripperRequest, ctx: GoalContext) -> tuple[GripperRequest | None, str | None]:
        """max_effort 0 replaced by the configured default."""
        c = ctx.config
        fingers = ctx.limits.motors["fingers"]
        lo, hi = fingers.min_position_rad, fingers.max_position_rad
        if not finite(req.position) or not lo <= req.position <= hi:
            return None, f"position {req.position} rad outside the fingers motor's range [{lo}, {hi}] (0 = open)"
        if not finite(req.max_effort) or req.max_effort < 0:
            return None, f"max_effort {req.max_effort} must be >= 0 N (0 = gripper_max_effort {c.gripper_max_effort} N)"
        if req.max_effort > c.max_force_n:
            return None, f"max_effort {req.max_effort} above the configured limit {c.max_force_n}"
        return GripperRequest(req.position, req.max_effort or c.gripper_max_effort), None

    def streams(self, req: GripperRequest, ctx: GoalContext) -> Streams:
        """Every configured pad, taxels and wrenches: each carries its force."""
        pads = tuple(ctx.config.fingers)
        return Streams(pads, pads)

    def build(self, req: GripperRequest, ctx: GoalContext) -> Built:
        c = ctx.config
        return Built(GripperController(ctx.limits, req.position, req.max_effort, tuple(c.fingers), c.gripper_speed_rpm,
                                       c.gripper_thumb_ratio, c.gripper_timeout))

    def status(self, controller: Controller, ctx: GoalContext) -> GripperStatus:
        assert isinstance(controller, GripperController)  # built above
        return GripperStatus(controller.position, controller.effort, controller.stalled, controller.reached_goal)

    def idle_status(self, ctx: GoalContext) -> GripperStatus:
        position = ctx.joints.positions.get("fingers", 0.0) if ctx.joints is not None else 0.0
        effort = max((ctx.forces.get(f, 0.0) for f in ctx.config.fingers), default=0.0)
        return GripperStatus(position, effort)

    def request_from_msg(self, msg: Any) -> GripperRequest:
        return gripper_request_from_msg(msg)

    def request_to_msg(self, types: Types, req: GripperRequest) -> Any:
        return gripper_request_to_msg(types, req)

    def feedback_to_msg(self, types: Types, fb: Feedback) -> Any:
        return gripper_feedback_to_msg(types, fb)

    def result_to_msg(self, types: Types, done: Finished) -> Any:
        return gripper_result_to_msg(types, done)


def gripper_request_from_msg(msg: Any) -> GripperRequest:
    """control_msgs/GripperCommand goal: command.position = fingers motor rad, command.max_effort N."""
    return GripperRequest(float(msg.command.position), float(msg.command.max_effort))


def gripper_request_to_msg(types: Types, req: GripperRequest) -> Any:
    """control_msgs/GripperCommand goal: command.position = fingers motor rad, command.max_effort N."""
    command = types("control_msgs/msg/GripperCommand")(position=float(req.position), max_effort=float(req.max_effort))
    return types("control_msgs/action/GripperCommand_Goal")(command=command)


def gripper_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    s: GripperStatus = fb.status
    return types("control_msgs/action/GripperCommand_Feedback")(
        position=f32(s.position), effort=f32(s.effort), stalled=bool(s.stalled), reached_goal=bool(s.reached_goal))


def gripper_result_to_msg(types: Types, done: Finished) -> Any:
    """position = the fingers motor angle (rad), effort = the highest estimated pad force (N)."""
    s: GripperStatus = done.status
    return types("control_msgs/action/GripperCommand_Result")(
        position=f32(s.position), effort=f32(s.effort), stalled=bool(s.stalled), reached_goal=bool(s.reached_goal))


GRIPPER_GOAL = GripperGoal()
