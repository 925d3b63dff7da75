"""The Grasp goal kind (prisma_msgs/action/Grasp on /prisma/grasp): a force-controlled grasp by
preset (grasp_controller.py). Its feedback and result carry the finger and thumb forces the
controller steers by."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from prisma_common.topics import GRASP_ACTION

from .controllers import Controller
from .goal_kind import (
    Built,
    Feedback,
    Finished,
    GoalContext,
    GoalKind,
    Streams,
    Types,
    f32,
    fingers_configured,
    finite,
)
from .grasp_controller import GRASP_PRESETS, GraspController


@dataclass(frozen=True)
class GraspRequest:
    grasp: str
    finger_force: float = 0.0  # 0 = configured default
    thumb_force: float = 0.0
    speed_rpm: float = 0.0
    timeout_s: float = 0.0


@dataclass(frozen=True)
class GraspStatus:
    finger_force: float  # N: the preset's finger force (pinch: the index pad's), as the controller uses it
    thumb_force: float


class GraspGoal(GoalKind[GraspRequest]):
    name, label = "grasp", "Grasp"
    action, action_type = GRASP_ACTION, "prisma_msgs/action/Grasp"
    request_type = GraspRequest

    def resolve(self, req: GraspRequest, ctx: GoalContext) -> tuple[GraspRequest | None, str | None]:
        c = ctx.config
        if req.grasp not in GRASP_PRESETS:
            return None, f"grasp {req.grasp!r} is not one of {sorted(GRASP_PRESETS)}"
        r = GraspRequest(req.grasp, req.finger_force or c.grasp_finger_force, req.thumb_force or c.grasp_thumb_force,
                         req.speed_rpm or c.grasp_speed_rpm, req.timeout_s or c.grasp_timeout)
        for name, value, limit in (("finger_force", r.finger_force, c.max_force_n),
                                   ("thumb_force", r.thumb_force, c.max_force_n),
                                   ("speed_rpm", r.speed_rpm, c.max_speed_rpm)):
            if not finite(value) or value <= 0:
                return None, f"{name} {value} must be > 0"
            if value > limit:
                return None, f"{name} {value} above the configured limit {limit}"
        if not finite(r.timeout_s) or r.timeout_s < 0:
            return None, f"timeout {r.timeout_s} must be >= 0"
        return r, fingers_configured(c, f"grasp {r.grasp}", self.streams(r, ctx).taxels)

    def streams(self, req: GraspRequest, ctx: GoalContext) -> Streams:
        """The thumb and the preset's pads, taxels and wrenches."""
        fingers = ("thumb",) + GRASP_PRESETS[req.grasp].force_fingers
        return Streams(fingers, fingers)

    def build(self, req: GraspRequest, ctx: GoalContext) -> Built:
        c = ctx.config
        return Built(GraspController(ctx.limits, req.grasp, req.finger_force, req.thumb_force, req.speed_rpm,
                                     req.timeout_s, c.contact_force_n, c.lateral_closure))

    def status(self, controller: Controller, ctx: GoalContext) -> GraspStatus:
        assert isinstance(controller, GraspController)  # built above
        return GraspStatus(controller.finger_force, controller.thumb_force)

    def idle_status(self, ctx: GoalContext) -> GraspStatus:
        return GraspStatus(0.0, 0.0)

    def request_from_msg(self, msg: Any) -> GraspRequest:
        return grasp_request_from_msg(msg)

    def request_to_msg(self, types: Types, req: GraspRequest) -> Any:
        return grasp_request_to_msg(types, req)

    def feedback_to_msg(self, types: Types, fb: Feedback) -> Any:
        return grasp_feedback_to_msg(types, fb)

    def result_to_msg(self, types: Types, done: Finished) -> Any:
        return grasp_result_to_msg(types, done)


def grasp_request_from_msg(msg: Any) -> GraspRequest:
    return GraspRequest(str(msg.grasp), float(msg.finger_force), float(msg.thumb_force), float(msg.speed_rpm),
                        float(msg.timeout))


def grasp_request_to_msg(types: Types, req: GraspRequest) -> Any:
    return types("prisma_msgs/action/Grasp_Goal")(grasp=req.grasp, finger_force=float(req.finger_force),
                                                  thumb_force=float(req.thumb_force), speed_rpm=float(req.speed_rpm),
                                                  timeout=float(req.timeout_s))


def grasp_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    s: GraspStatus = fb.status
    return types("prisma_msgs/action/Grasp_Feedback")(phase=fb.phase, finger_force=f32(s.finger_force),
                                                      thumb_force=f32(s.thumb_force))


def grasp_result_to_msg(types: Types, done: Finished) -> Any:
    s: GraspStatus = done.status
    return types("prisma_msgs/action/Grasp_Result")(success=bool(done.success), reason=done.reason,
                                                    finger_force=f32(s.finger_force),
                                                    thumb_force=f32(s.thumb_force))


GRASP_GOAL = GraspGoal()
