"""The Teleoperate goal kind (prisma_msgs/action/Teleoperate on /prisma/teleoperate): the motors follow
the targets on prisma/teleop/motor_targets (sensor_msgs/JointState: motor angles in rad, stamped
with the glove sample they came from), touch-limited by the pads' estimated forces
(teleop_controller.py), until its client cancels it.

A goal is admitted before any target flows and waits (phase `waiting`, motors still), so an
operator can engage before moving; a target older than `input_timeout` at the start does not
count. Once targets came, their silence for `input_timeout` ends it `input_stale: <topic> silent
for N ms` with the motors stopped; a new goal follows again once they flow. It steps on every
configured pad's taxels and wrenches (each carries the touch limit), like a GripperCommand.
Feedback and result carry, per motor, the target followed and the position, the pad forces in the
order of parameter fingers and the motors held back by the touch limit; the result's reason is the
stop reason with what made it (`sensor_stale: taxels/index silent for 110 ms`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from prisma_common.hand import MOTOR_NAMES
from prisma_common.messages import ns_from_stamp, sequence_field
from prisma_common.topics import TELEOPERATE_ACTION, TELEOP_TARGETS, relative

from .controllers import Controller
from .goal_kind import Built, Feedback, Finished, GoalContext, GoalKind, InputStream, Streams, Types, f32, finite
from .node_config import MAX_INPUT_TIMEOUT_S
from .teleop_controller import PRESSING_MOTORS, TARGET_STREAM, TeleopController, TeleopTarget, pads_of

INPUT_STALE = "input_stale"
TARGETS_TOPIC = relative(TELEOP_TARGETS)


@dataclass(frozen=True)
class TeleopRequest:
    max_pad_force: float = 0.0  # N; 0 = parameter teleop_max_pad_force
    max_speed_rpm: float = 0.0  # 0 = parameter teleop_max_speed_rpm
    input_timeout_s: float = 0.0  # 0 = parameter teleop_input_timeout


@dataclass(frozen=True)
class TeleopStatus:
    motors: tuple[str, ...]
    targets: tuple[float, ...]  # rad, NaN for a motor without a target yet
    positions: tuple[float, ...]  # rad
    pad_forces: tuple[float, ...]  # N, per finger of parameter fingers
    force_limited: tuple[str, ...] = ()


class TeleopGoal(GoalKind[TeleopRequest]):
    name, label = "teleop", "Teleoperate"
    action, action_type = TELEOPERATE_ACTION, "prisma_msgs/action/Teleoperate"
    request_type = TeleopRequest
    inputs = (InputStream(TARGET_STREAM, TARGETS_TOPIC, "sensor_msgs/msg/JointState",
                          lambda msg: teleop_target_from_msg(msg)),)  # (defined below)

    def resolve(self, req: TeleopRequest, ctx: GoalContext) -> tuple[TeleopRequest | None, str | None]:
        c = ctx.config
        r = TeleopRequest(req.max_pad_force or c.teleop_max_pad_force, req.max_speed_rpm or c.teleop_max_speed_rpm,
                          req.input_timeout_s or c.teleop_input_timeout)
        for name, value, limit in (("max_pad_force", r.max_pad_force, c.max_force_n),
                                   ("max_speed_rpm", r.max_speed_rpm, c.max_speed_rpm),
                                   ("input_timeout", r.input_timeout_s, MAX_INPUT_TIMEOUT_S)):
            if not finite(value) or value <= 0:
                return None, f"{name} {value} must be > 0"
            if value > limit:
                return None, f"{name} {value} above the configured limit {limit}"
        for motor in PRESSING_MOTORS:
            if not pads_of(motor, c.fingers):
                return None, f"teleoperation limits {motor} by its pads' force, none of them in parameter fingers " \
                             f"{c.fingers}"
        return r, None

    def streams(self, req: TeleopRequest, ctx: GoalContext) -> Streams:
        """Every configured pad, taxels and wrenches (each carries the touch limit), and the targets."""
        pads = tuple(ctx.config.fingers)
        return Streams(pads, pads, inputs=(TARGET_STREAM,), input_timeout_s=req.input_timeout_s)

    def build(self, req: TeleopRequest, ctx: GoalContext) -> Built:
        return Built(TeleopController(ctx.limits, tuple(ctx.config.fingers), req.max_pad_force, req.max_speed_rpm,
                                      ctx.config.teleop_gain))

    def status(self, controller: Controller, ctx: GoalContext) -> TeleopStatus:
        assert isinstance(controller, TeleopController)  # built above
        return teleop_status(ctx, controller.targets, controller.force_limited)

    def idle_status(self, ctx: GoalContext) -> TeleopStatus:
        return teleop_status(ctx, {})

    def stale_reason(self, stream: str) -> str:
        return INPUT_STALE

    def request_from_msg(self, msg: Any) -> TeleopRequest:
        return teleop_request_from_msg(msg)

    def request_to_msg(self, types: Types, req: TeleopRequest) -> Any:
        return teleop_request_to_msg(types, req)

    def feedback_to_msg(self, types: Types, fb: Feedback) -> Any:
        return teleop_feedback_to_msg(types, fb)

    def result_to_msg(self, types: Types, done: Finished) -> Any:
        return teleop_result_to_msg(types, done)


def teleop_status(ctx: GoalContext, targets: dict[str, float], force_limited: tuple[str, ...] = ()) -> TeleopStatus:
    """Where the hand stands (NaN: not known yet) and what it follows (NaN: no target yet)."""
    positions = ctx.joints.positions if ctx.joints is not None else {}
    return TeleopStatus(MOTOR_NAMES, tuple(targets.get(m, math.nan) for m in MOTOR_NAMES),
                        tuple(positions.get(m, math.nan) for m in MOTOR_NAMES),
                        tuple(ctx.forces.get(f, math.nan) for f in ctx.config.fingers), force_limited)


def teleop_target_from_msg(msg: Any) -> tuple[int, TeleopTarget]:
    """(stamp_ns, TeleopTarget) of a sensor_msgs/JointState on prisma/teleop/motor_targets: the
    positions of the hand's motors it names (others' names, non-finite values and a position array
    not matching `name` in length carry nothing)."""
    stamp = ns_from_stamp(msg.header.stamp)
    names, positions = [str(n) for n in msg.name], list(msg.position)
    if len(names) != len(positions):
        return stamp, TeleopTarget(stamp)
    return stamp, TeleopTarget(stamp, {n: float(p) for n, p in zip(names, positions)
                                       if n in MOTOR_NAMES and math.isfinite(p)})


def teleop_request_from_msg(msg: Any) -> TeleopRequest:
    return TeleopRequest(float(msg.max_pad_force), float(msg.max_speed_rpm), float(msg.input_timeout))


def teleop_request_to_msg(types: Types, req: TeleopRequest) -> Any:
    return types("prisma_msgs/action/Teleoperate_Goal")(max_pad_force=float(req.max_pad_force),
                                                        max_speed_rpm=float(req.max_speed_rpm),
                                                        input_timeout=float(req.input_timeout_s))


def _status_fields(cls: Any, s: TeleopStatus) -> dict[str, Any]:
    return {"motors": list(s.motors), "targets": sequence_field(cls, [f32(v) for v in s.targets], np.float32),
            "positions": sequence_field(cls, [f32(v) for v in s.positions], np.float32),
            "pad_forces": sequence_field(cls, [f32(v) for v in s.pad_forces], np.float32),
            "force_limited": list(s.force_limited)}


def teleop_feedback_to_msg(types: Types, fb: Feedback) -> Any:
    cls = types("prisma_msgs/action/Teleoperate_Feedback")
    return cls(phase=fb.phase, **_status_fields(cls, fb.status))


def teleop_result_to_msg(types: Types, done: Finished) -> Any:
    """success only for a cancel (its normal end); reason = the stop reason and what made it."""
    cls = types("prisma_msgs/action/Teleoperate_Result")
    reason = done.detail if done.detail.startswith(done.reason) else f"{done.reason}: {done.detail}"
    return cls(success=bool(done.success), reason=reason if done.detail else done.reason,
               duration=f32(done.stop_time_s), **_status_fields(cls, done.status))


TELEOP_GOAL = TeleopGoal()
