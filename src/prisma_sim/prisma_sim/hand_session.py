"""One hand scenario of the paper (docs/manipulation.md), run in the ROS-free closed loop and recorded as the ROS
graph would publish it.

The closed loop (`prisma_manipulation.closed_loop.ClosedLoop`) runs the graph's own cores on the sim
motors and the hand/world model: the motor driver's, the tactile driver's hub, the force
estimator's pipeline and the manipulation node's core, whose decisions it carries out as the node
does. `HandRecorder` only turns each period's `Scan` into the messages the nodes would publish,
with the nodes' converters:

- /joint_states from the motor driver core's states -> `joint_state_to_msg`;
- taxels: the tactile hub's frames -> `taxel_frame_to_msg`;
- wrench: the estimator pipeline's samples -> `wrench_to_msg`;
- contact: the manipulation core's Algorithm 1 evaluation of every frame -> `contact_state_to_msg`;
- the goal's status and feedback from the core's Feedback and Finished decisions, by its kind's
  converter and outcome (prisma_manipulation.goal_kinds: any kind the loop's core serves), the
  MoveMotors goals from its SendMove (a new goal preempts the running one) and StopMotors (a
  cancel), their feedback and ends from the motor driver core;
- /diagnostics once per second from each driver's core (tactile hub, estimator pipeline, motor
  driver).
Stamps are the loop's sample stamps (sim time from 0), so every topic is ordered in time.
"""
from __future__ import annotations

import dataclasses
import functools
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from prisma_common.bag import BagWriter
from prisma_common.diagnostics import diagnostics_to_msg
from prisma_common.hand import FINGERS
from prisma_common.messages import stamp_from_ns
from prisma_common.topics import CONTACT, DIAGNOSTICS, JOINT_STATES, MOVE_MOTORS, TAXELS, WRENCH
from prisma_common.typestore import types as typestore_types
from prisma_force_estimator.diagnostics import pipeline_diagnostics
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.ros_conversions import wrench_to_msg
from prisma_manipulation.closed_loop import Scan
from prisma_manipulation.goal_kind import GoalKind
from prisma_manipulation.goal_kinds import GOAL_KINDS, kind_named, kind_of
from prisma_manipulation.manipulation_core import ActionHandlers, Feedback, Finished
from prisma_manipulation.ros_conversions import contact_state_to_msg
from prisma_manipulation.scenarios import Scenario, build, scenario_request
from prisma_motor_driver.ros_conversions import joint_state_to_msg, move_feedback_to_msg
from prisma_tactile_driver.node_config import TactileDriverConfig
from prisma_tactile_driver.ros_conversions import taxel_frame_to_msg

NS = 1_000_000_000
DIAGNOSTICS_PERIOD_NS = NS  # every driver's diagnostics_period default (1 s)


@functools.cache
def goal_status() -> Any:
    """action_msgs/msg/GoalStatus as the typestore reads it: its STATUS_* numbers are what the recorded
    status messages carry (looked up at first use: `prisma-sim --list` builds no typestore)."""
    return typestore_types("action_msgs/msg/GoalStatus")


MOVE = "move"  # the motor driver's MoveMotors goals, beside the goal kinds' actions


def action_server(action: str, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> tuple[str, str]:
    """(default name, ROS type) of an action server: MOVE the motor driver's MoveMotors, any other a
    goal kind's, by its name or its server's last name ("grasp", "teleoperate": goal_kinds.kind_named)."""
    if action == MOVE:
        return MOVE_MOTORS, "prisma_msgs/action/MoveMotors"
    kind = kind_named(action, kinds)
    return f"/{kind.action}", kind.action_type


def feedback_topic(action: str, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> str:
    return f"{action_server(action, kinds)[0]}/_action/feedback"


def status_topic(action: str, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> str:
    return f"{action_server(action, kinds)[0]}/_action/status"


def message_fields(msg: Any) -> dict[str, Any]:
    """A typestore message's fields as plain values (arrays as lists, nested messages as dicts), for
    a JSON summary or a message class's keyword arguments."""
    def plain(value: Any) -> Any:
        if dataclasses.is_dataclass(value):
            return message_fields(value)
        return value.tolist() if isinstance(value, np.ndarray) else value
    # (a typestore class carries its type name as a field too, `__msgtype__`: not the message's)
    return {f.name: plain(getattr(msg, f.name)) for f in dataclasses.fields(msg) if not f.name.startswith("__")}


def goal_result(done: Finished, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> dict[str, Any]:
    """A finished goal's result as the manipulation node returns it: its kind's result message's fields."""
    return message_fields(kind_named(done.kind, kinds).result_to_msg(typestore_types, done))


# ------------------------------------------------------------------------------------------------
# The scenarios prisma-sim runs


@dataclass(frozen=True)
class HandScenarioSpec:
    name: str
    description: str

    @property
    def kind(self) -> GoalKind:
        """The kind of the goal the scenario sends."""
        return kind_of(scenario_request(self.name))

    @property
    def action(self) -> str:
        """The action the scenario's goal is sent on, by its server's last name ("grasp", "manipulate")."""
        return self.kind.action.rsplit("/", 1)[-1]

    @property
    def goal(self) -> dict:
        """The goal's fields as the action defines them (its kind's goal message)."""
        return message_fields(self.kind.request_to_msg(typestore_types, scenario_request(self.name)))

    def make(self, estimator: ForceEstimator | None = None) -> Scenario:
        return build(self.name, estimator=estimator)


HAND_SCENARIOS: dict[str, HandScenarioSpec] = {
    spec.name: spec for spec in (
        HandScenarioSpec(
            "pinch_grasp",
            "foam ball on a stand; fingers close at 60 rpm to 0.8 N on the index pad, then the thumb "
            "flexes at 60 rpm to 1 N (estimated Fz)"),
        HandScenarioSpec(
            "lateral_grasp",
            "card against the side of the index: fingers close to the lateral fist, thumb flexes at "
            "60 rpm to 1 N (estimated Fz)"),
        HandScenarioSpec(
            "horizontal",
            "ball pinched at 1 N; thumb rotates clockwise at 20 rpm until the right taxels 6-3-0 are "
            "lost, then back to the start angle"),
        HandScenarioSpec(
            "vertical",
            "ball pinched at 1 N; fingers close + thumb extends at 10 rpm until the top row 6-7-8 is "
            "lost, then the reverse until the bottom row 0-1-2 is lost"),
        HandScenarioSpec(
            "disturbance",
            "ball pinched; at 0.5 s a push slips it 4 mm toward the thumb pad's right side; the thumb "
            "rotates at 20 rpm until two left taxels are back above v_t"),
        HandScenarioSpec(
            "combined",
            "as disturbance, and the object slips to a narrower section: the estimated thumb force "
            "is restored to 1 N while the voltages steer the rotation"),
    )
}


# ------------------------------------------------------------------------------------------------
# Recording


def _goal_uuid(*parts: object) -> np.ndarray:
    """Deterministic goal id (same run -> same bag)."""
    name = "/".join(str(p) for p in parts)
    return np.frombuffer(uuid.uuid5(uuid.NAMESPACE_URL, f"prisma-sim:{name}").bytes, dtype=np.uint8).copy()


@dataclass
class GoalRecord:
    """One action goal as recorded: for summaries and tests."""

    action: str
    accepted_ns: int
    ended_ns: int | None = None
    status: int = field(default_factory=lambda: goal_status().STATUS_EXECUTING)
    feedback: int = 0


@dataclass
class _Goal:
    action: str
    goal_id: np.ndarray
    accepted_ns: int
    record: GoalRecord


@dataclass
class HandRecording:
    samples: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    counts: dict[str, int] = field(default_factory=dict)
    goals: list[GoalRecord] = field(default_factory=list)


class HandRecorder:
    """Attach to a Scenario (built with an estimator) before `run()`; writes every message to
    `writer` as the loop runs. `action`: the goal's kind, by its name or its action server's last
    name ("grasp", "teleoperate"), one of those the loop's core serves."""

    def __init__(self, scenario: Scenario, writer: BagWriter, action: str,
                 types: Callable[[str], Any] = typestore_types) -> None:
        loop = scenario.loop
        self.kinds = tuple(loop.core.kinds.values())
        self.kind = kind_named(action, self.kinds)  # ValueError naming the kinds
        if loop.pipeline is None or loop.estimator is None:
            raise ValueError(f"scenario {scenario.name} has no force estimator: its wrench topics would be empty")
        self.pipeline = loop.pipeline
        self.scenario, self.writer, self.types, self.action = scenario, writer, types, action
        self.loop = loop
        self.recording = HandRecording()
        self.tactile_config = TactileDriverConfig(backend="sim", contact_source="hand_world")
        self.contact_frame_id = loop.core.config.frame_id_format
        self.bundle_paths = {f: loop.estimator.path for f in FINGERS}
        self._next_diagnostics_ns: int | None = None
        self._goal: _Goal | None = None  # the goal of `kind`
        self._move: _Goal | None = None  # the MoveMotors goal it is running
        self._moves = 0
        self._stamp_ns = 0  # the scan whose decisions are being recorded
        # what the manipulation node publishes for its core's decisions
        self._handlers = ActionHandlers(send_move=lambda _: self._send_move(self._stamp_ns),
                                        stop_motors=lambda _: self._end_move(goal_status().STATUS_CANCELED,
                                                                             self._stamp_ns),
                                        feedback=self._record_feedback, finished=self._record_finished)
        loop.observer = self.record

    # ---- one period --------------------------------------------------------------------------
    def record(self, scan: Scan) -> None:
        t, types = scan.stamp_ns, self.types
        rec = self.recording
        rec.samples += 1
        rec.first_ns = t if rec.first_ns is None else rec.first_ns
        rec.last_ns = t
        self._write(JOINT_STATES, joint_state_to_msg(types, t, scan.states))
        for frame in scan.frames:
            self._write(TAXELS.format(finger=frame.finger),
                        taxel_frame_to_msg(types, frame, self.tactile_config.frame_id(frame.finger)))
        for finger in FINGERS:
            if finger in scan.wrenches:
                self._write(WRENCH.format(finger=finger), wrench_to_msg(types, scan.wrenches[finger]))
        for frame in scan.frames:  # the manipulation node evaluates every taxel message, also when idle
            self._write(CONTACT.format(finger=frame.finger),
                        contact_state_to_msg(types, scan.evaluations[frame.finger],
                                             self.contact_frame_id.format(finger=frame.finger)))
        if self._move is not None and scan.move_feedback is not None:
            self._write_feedback(self._move, move_feedback_to_msg(types, scan.move_feedback), t)
            self._move.record.feedback += 1
        if self._move is not None and scan.move_result is not None:  # ended on the driver (limit, timeout, fault)
            self._end_move(goal_status().STATUS_SUCCEEDED if scan.move_result.success
                           else goal_status().STATUS_ABORTED, t)
        if scan.goal_started:
            self._goal = self._new_goal(self.action, _goal_uuid(self.scenario.name, self.action), t)
        self._stamp_ns = t
        self._handlers.carry_out(scan.actions)
        if self._next_diagnostics_ns is None or t >= self._next_diagnostics_ns:
            self._next_diagnostics_ns = t + DIAGNOSTICS_PERIOD_NS
            self._write_diagnostics(t)

    def _record_feedback(self, action: Feedback) -> None:
        if self._goal is not None:
            self._write_feedback(self._goal, self.kind.feedback_to_msg(self.types, action), self._stamp_ns)
            self._goal.record.feedback += 1

    def _record_finished(self, action: Finished) -> None:
        """The goal's end as its action server ends it (its kind's outcome: SUCCEEDED, CANCELED, ABORTED)."""
        if self._goal is not None:
            status = getattr(goal_status(), f"STATUS_{self.kind.outcome(action).upper()}")
            self._end(self._goal, status, self._stamp_ns)
            self._goal = None

    # ---- messages ----------------------------------------------------------------------------
    def _write(self, topic: str, msg: Any, stamp_ns: int | None = None) -> None:
        self.writer.write(topic, msg, stamp_ns)
        self.recording.counts[topic] = self.recording.counts.get(topic, 0) + 1

    def _write_diagnostics(self, t: int) -> None:
        types, loop = self.types, self.loop
        self._write(DIAGNOSTICS, diagnostics_to_msg(types, t, loop.hub.diagnostics(t)))
        self._write(DIAGNOSTICS, diagnostics_to_msg(
            types, t, pipeline_diagnostics(self.pipeline, "force_estimator", self.bundle_paths)))
        self._write(DIAGNOSTICS, diagnostics_to_msg(types, t, loop.motor.diagnostics()))

    def _send_move(self, t: int) -> None:
        """A MoveMotors goal (a new command or its refresh): it preempts the running one."""
        if self._move is not None:
            self._end_move(goal_status().STATUS_ABORTED, t)  # preempted
        self._moves += 1
        self._move = self._new_goal(MOVE, _goal_uuid(self.scenario.name, MOVE, self._moves), t)

    def _end_move(self, status: int, t: int) -> None:
        if self._move is not None:
            self._end(self._move, status, t)
            self._move = None

    def _new_goal(self, action: str, goal_id: np.ndarray, t: int) -> _Goal:
        goal = _Goal(action, goal_id, t, GoalRecord(action, t))
        self.recording.goals.append(goal.record)
        self._write_status(goal, goal_status().STATUS_EXECUTING, t)
        return goal

    def _end(self, goal: _Goal, status: int, t: int) -> None:
        self._write_status(goal, status, t)
        goal.record.ended_ns, goal.record.status = t, status

    def _write_feedback(self, goal: _Goal, feedback: Any, t: int) -> None:
        types = self.types
        msg = types(f"{action_server(goal.action, self.kinds)[1]}_FeedbackMessage")(
            goal_id=types("unique_identifier_msgs/msg/UUID")(uuid=goal.goal_id), feedback=feedback)
        self._write(feedback_topic(goal.action, self.kinds), msg, t)

    def _write_status(self, goal: _Goal, status: int, t: int) -> None:
        types = self.types
        info = types("action_msgs/msg/GoalInfo")(goal_id=types("unique_identifier_msgs/msg/UUID")(uuid=goal.goal_id),
                                                 stamp=stamp_from_ns(types, goal.accepted_ns))
        msg = types("action_msgs/msg/GoalStatusArray")(
            status_list=[types("action_msgs/msg/GoalStatus")(goal_info=info, status=status)])
        self._write(status_topic(goal.action, self.kinds), msg, t)

    def finish(self) -> HandRecording:
        """Close open goals at the last sample (a run cut by its duration ends them aborted)."""
        t = self.recording.last_ns or 0
        self._end_move(goal_status().STATUS_ABORTED, t)
        if self._goal is not None:
            self._end(self._goal, goal_status().STATUS_ABORTED, t)
            self._goal = None
        return self.recording


def expected_hand_topics(action: str) -> dict[str, str]:
    """topic -> type of every topic a hand scenario bag holds."""
    topics = {}
    for f in FINGERS:
        topics[TAXELS.format(finger=f)] = "prisma_msgs/msg/TaxelArray"
        topics[WRENCH.format(finger=f)] = "geometry_msgs/msg/WrenchStamped"
        topics[CONTACT.format(finger=f)] = "prisma_msgs/msg/ContactState"
    topics[JOINT_STATES] = "sensor_msgs/msg/JointState"
    topics[DIAGNOSTICS] = "diagnostic_msgs/msg/DiagnosticArray"
    for a in (action, MOVE):
        topics[feedback_topic(a)] = f"{action_server(a)[1]}_FeedbackMessage"
        topics[status_topic(a)] = "action_msgs/msg/GoalStatusArray"
    return topics

