"""The shape every goal kind of the manipulation node has (issue 28): a kind declares its action (name
and ROS type), how its request is validated, the streams it needs, how it builds its controller, how
it reports feedback and result, in core data and as its action's messages (both ways: the goal too),
and how the action server ends a finished goal (`outcome`). ManipulationCore keeps what is common to
all of them (one goal at a time, admission, the MoveMotors lease, the watchdog, stepping once per
scan); the node, the closed loop and the sim recorder serve every kind through one generic path and
read each of these facts from the kind. A new kind is one new module (a `GoalKind` subclass and its
request, status and converters) and one line in goal_kinds.GOAL_KINDS (issue 42; the test suite's
test_fifth_goal_kind.py adds one that way).

A kind's extra input (a teleoperation goal following the glove's targets, issue 27) is one more
`InputStream` in `GoalKind.inputs` (topic, message type, converter): the node subscribes to it and
the core holds its latest value. An input comes from another device at its own rate, so it never
shares a tactile scan's stamp: the controller is stepped once per scan, as for every kind, with the
latest value of each input (`ControlInput.inputs`; sample-and-hold). A goal of that kind is admitted
before its input flows and its controller waits for it (`ControlInput.inputs` lacks it); a value
older than the input's timeout at the start does not count. Once one came during the goal, the input
silent (by receipt) or older than /joint_states (by stamp) longer than `Streams.input_timeout_s`
ends the goal with the kind's `stale_reason`, as stale taxels end it sensor_stale.

Everything here is ROS-free: the converters take a message-class lookup `types(name)` as
ros_conversions' do.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from . import goal_ends
from .controllers import CANCELED, SENSOR_STALE, ControlLimits, Controller, JointSample
from .node_config import ManipulationConfig

Types = Callable[[str], Any]
R = TypeVar("R")  # a kind's request dataclass


@dataclass(frozen=True)
class Feedback:
    """A running goal's feedback: the controller's phase and the kind's own status dataclass."""

    kind: str
    phase: str
    status: Any


@dataclass(frozen=True)
class Finished:
    """A goal's end. stop_time_s: from goal start to the stop (0 when it never stopped on its own);
    status: the kind's own dataclass, as in Feedback."""

    kind: str
    success: bool
    reason: str
    stop_time_s: float
    status: Any
    detail: str = ""


@dataclass(frozen=True)
class Streams:
    """What a goal needs flowing to be admitted and keeps watched while it runs: the fingers whose
    taxels and whose wrenches it steps on, and the pad that must show a contact for it to start
    (None: no such condition). Also the extra inputs of its kind (`InputStream.stream`), which it
    waits for rather than needs at admission, and how long they may fall silent once they came
    (None: stale_timeout)."""

    taxels: tuple[str, ...]
    wrenches: tuple[str, ...]
    inputs: tuple[str, ...] = ()
    contact: str | None = None
    input_timeout_s: float | None = None

    def watched(self) -> list[str]:
        """The watchdog's names of the sensor streams (not the inputs: the goal waits for those)."""
        return [f"taxels/{f}" for f in self.taxels] + [f"wrench/{f}" for f in self.wrenches]


@dataclass(frozen=True)
class InputStream:
    """An extra input of a goal kind: the node subscribes `topic` (`msg_type`, a ROS type name) and
    passes `(stamp_ns, value) = from_msg(msg)` to `ManipulationCore.on_input(stream, ...)`."""

    stream: str
    topic: str
    msg_type: str
    from_msg: Callable[[Any], tuple[int, Any]]


@dataclass(frozen=True)
class GoalContext:
    """What a kind reads from the core to validate a request, build a controller and report."""

    config: ManipulationConfig
    limits: ControlLimits
    k_parameter: float
    forces: Mapping[str, float]  # latest normal force per finger, N
    joints: JointSample | None
    inputs: Mapping[str, Any]  # the kinds' extra inputs, latest value each (`InputStream.stream`)


@dataclass(frozen=True)
class Built:
    """A kind's controller for one goal, and the k the contact monitor uses while it runs (None: the
    k parameter)."""

    controller: Controller
    k: float | None = None


class GoalKind(Generic[R]):
    """One goal kind. Subclasses set the class attributes and implement the methods below; the
    defaults cover a kind without extra inputs that ends sensor_stale on any silent stream."""

    name: str  # the core's name ("grasp"): Feedback.kind, Finished.kind, the log
    label: str  # the action type's short name in the log ("Grasp")
    action: str  # the action server's name
    action_type: str  # the action's ROS type ("prisma_msgs/action/Grasp")
    request_type: type
    inputs: tuple[InputStream, ...] = ()
    # whether its result carries the reason's text; without it (GripperCommand) the node's log and
    # /diagnostics tell why a goal failed (goal_ends.py)
    result_has_text = True

    def resolve(self, req: R, ctx: GoalContext) -> tuple[R | None, str | None]:
        """The request with its defaults filled in, or why it is invalid."""
        raise NotImplementedError

    def streams(self, req: R, ctx: GoalContext) -> Streams:
        raise NotImplementedError

    def build(self, req: R, ctx: GoalContext) -> Built:
        raise NotImplementedError

    def status(self, controller: Controller, ctx: GoalContext) -> Any:
        """The kind's status for Feedback / Finished while its controller runs."""
        raise NotImplementedError

    def idle_status(self, ctx: GoalContext) -> Any:
        """The status a refused goal's result carries (where the hand stands)."""
        raise NotImplementedError

    def stale_reason(self, stream: str) -> str:
        """The end reason when `stream` falls silent during a goal."""
        return SENSOR_STALE

    def outcome(self, done: Finished) -> str:
        """How its action server ends a finished goal (goal_ends: SUCCEEDED, CANCELED or ABORTED): a
        cancel as canceled, whatever its success (a teleoperation's cancel is its normal end)."""
        if done.reason == CANCELED:
            return goal_ends.CANCELED
        return goal_ends.SUCCEEDED if done.success else goal_ends.ABORTED

    def request_from_msg(self, msg: Any) -> R:
        raise NotImplementedError

    def request_to_msg(self, types: Types, req: R) -> Any:
        """The goal message of a request, as a client sends it (the sim's summaries, a recorder)."""
        raise NotImplementedError

    def feedback_to_msg(self, types: Types, fb: Feedback) -> Any:
        raise NotImplementedError

    def result_to_msg(self, types: Types, done: Finished) -> Any:
        raise NotImplementedError


def finite(x: float) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def f32(x: float) -> float:
    """A float32 message field's value: non-finite values are sent as NaN."""
    return float(x) if math.isfinite(x) else float("nan")


def fingers_configured(config: ManipulationConfig, what: str, fingers: tuple[str, ...]) -> str | None:
    """Why a goal needing `fingers` cannot run with this node's parameter fingers, or None."""
    missing = [f for f in fingers if f not in config.fingers]
    if missing:
        return f"{what} needs the {', '.join(missing)} pad(s), not in parameter fingers {config.fingers}"
    return None
