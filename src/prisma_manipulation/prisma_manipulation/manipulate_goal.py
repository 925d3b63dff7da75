"""The Manipulate goal kind (prisma_msgs/action/Manipulate on /prisma/manipulate): a horizontal,
vertical or hold motion steered by the monitored pad's contact (motion_controllers.py), with the
goal's own k while it runs. It starts only from a held object (no_contact otherwise). Feedback
carries the pad's feasibility and threshold, the result the stop reason and time."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from prisma_common.topics import MANIPULATE_ACTION

from .contact_monitor import check_k
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
from .motion_controllers import ForceKeeper, HoldController, HorizontalController, VerticalController

MOTIONS = ("horizontal", "vertical", "hold")


@dataclass(frozen=True)
class ManipulateRequest:
    motion: str
    speed_rpm: float = 0.0
    k: float = 0.0  # 0 = the node's k parameter
    use_force: bool = False
    timeout_s: float = 0.0


@dataclass(frozen=True)
class ManipulateStatus:
    finger_force: float  # N: the index and thumb pads' latest estimated forces
    thumb_force: float
    feasible: bool  # the monitored pad's latest sample (Algorithm 1)
    threshold: float  # its v_t = k * mean voltage


class ManipulateGoal(GoalKind[ManipulateRequest]):
    name, label = "manipulate", "Manipulate"
    action, action_type = MANIPULATE_ACTION, "prisma_msgs/action/Manipulate"
    request_type = ManipulateRequest

    def resolve(self, req: ManipulateRequest, ctx: GoalContext) -> tuple[ManipulateRequest | None, str | None]:
        c = ctx.config
        if req.motion not in MOTIONS:
            return None, f"motion {req.motion!r} is not one of {list(MOTIONS)}"
        default_speed = {"horizontal": c.horizontal_speed_rpm, "vertical": c.vertical_speed_rpm,
                         "hold": c.hold_speed_rpm}[req.motion]
        r = ManipulateRequest(req.motion, req.speed_rpm or default_speed, req.k or ctx.k_parameter,
                              bool(req.use_force), req.timeout_s or c.manipulate_timeout)
        if not finite(r.speed_rpm) or r.speed_rpm <= 0:
            return None, f"speed_rpm {r.speed_rpm} must be > 0"
        if r.speed_rpm > c.max_speed_rpm:
            return None, f"speed_rpm {r.speed_rpm} above the configured limit {c.max_speed_rpm}"
        try:
            check_k(r.k)
        except ValueError as exc:
            return None, str(exc)
        if r.motion == "hold" and r.k <= c.hold_min_k:
            return None, f"k {r.k} too low for hold: needs k > {c.hold_min_k}"
        if not finite(r.timeout_s) or r.timeout_s < 0:
            return None, f"timeout {r.timeout_s} must be >= 0"
        return r, fingers_configured(c, f"motion {r.motion}", self.streams(r, ctx).taxels)

    def streams(self, req: ManipulateRequest, ctx: GoalContext) -> Streams:
        """The monitored pad's taxels (+ the thumb's), the thumb's wrench with use_force, and a
        contact on the monitored pad: a manipulation steers a held object."""
        finger = ctx.config.monitored_finger
        taxels = (finger,) if finger == "thumb" else (finger, "thumb")
        return Streams(taxels, ("thumb",) if req.use_force else (), contact=finger)

    def build(self, req: ManipulateRequest, ctx: GoalContext) -> Built:
        c = ctx.config
        keeper = ForceKeeper(c.force_target_n, c.force_band_n, c.force_speed_rpm) if req.use_force else None
        finger, contact = c.monitored_finger, c.min_mean_voltage
        controller: Controller
        if req.motion == "horizontal":
            controller = HorizontalController(ctx.limits, req.speed_rpm, finger, timeout_s=req.timeout_s,
                                              force_keeper=keeper, contact_voltage=contact)
        elif req.motion == "vertical":
            controller = VerticalController(ctx.limits, req.speed_rpm, finger, req.timeout_s, keeper, contact)
        else:
            controller = HoldController(ctx.limits, req.speed_rpm, finger, req.timeout_s, force_keeper=keeper,
                                        contact_voltage=contact)
        return Built(controller, k=req.k)

    def status(self, controller: Controller, ctx: GoalContext) -> ManipulateStatus:
        return ManipulateStatus(ctx.forces.get("index", 0.0), ctx.forces.get("thumb", 0.0),
                                getattr(controller, "feasible", False), getattr(controller, "threshold", 0.0))

    def idle_status(self, ctx: GoalContext) -> ManipulateStatus:
        return ManipulateStatus(0.0, 0.0, False, 0.0)

    def request_from_msg(self, msg: Any) -> ManipulateRequest:
        return manipulate_request_from_msg(msg)

    def request_to_msg(self, types: Types, req: ManipulateRequest) -> Any:
        return manipulate_request_to_msg(types, req)

    def feedback_to_msg(self, types: Types, fb: Feedback) -> Any:
        return manipulate_feedback_to_msg(types, fb)

    def result_to_msg(self, types: Types, done: Finished) -> Any:
        return manipulate_result_to_msg(types, done)


def manipulate_request_from_msg(msg: Any) -> ManipulateRequest:
    return ManipulateRequest(str(msg.motion), float(msg.speed_rpm), float(msg.k), bool(msg.use_force),
                             float(msg.timeout))


def manipulate_request_to_msg(types: Types, req: ManipulateRequest) -> Any:
    return types("prisma_msgs/action/Manipulate_Goal")(motion=req.motion, speed_rpm=float(req.speed_rpm),
                                                       k=float(req.k), use_force=bool(req.use_force),
                                                       timeout=float(req.timeout_s))


def manipulate_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    s: ManipulateStatus = fb.status
    return types("prisma_msgs/action/Manipulate_Feedback")(phase=fb.phase, feasible=bool(s.feasible),
                                                           threshold=f32(s.threshold))


def manipulate_result_to_msg(types: Types, done: Finished) -> Any:
    return types("prisma_msgs/action/Manipulate_Result")(success=bool(done.success), stop_reason=done.reason,
                                                         stop_time=f32(done.stop_time_s))


MANIPULATE_GOAL = ManipulateGoal()
