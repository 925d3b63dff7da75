"""What the manipulation node decides, without ROS: goal admission, one controller at a time,
stepping it once per sensor scan, the watchdog, and the motor commands that result.

The node feeds it messages (taxels, wrenches, joint states, a goal kind's extra inputs, MoveMotors
results, cancel requests, watchdog ticks) as plain data and carries out the returned actions:
- SendMove: send a MoveMotors velocity goal (it preempts the previous one on the motor driver);
- StopMotors: cancel the running MoveMotors goal (cancel = stop);
- Feedback / Finished: the running goal's feedback and end, with its kind's status (goal_kind.py);
- Ignored: an input set aside (a /joint_states message without the hand's joints), for the log;
- StampNews (prisma_common.sample_stamps): a stream's samples refused by their stamp (stamped 0,
  ahead of the node's clock, older than max_stamp_age on arrival), or accepted again: once per
  episode, for the log (and `stamp_status` on /diagnostics while it lasts). A refused sample moves no
  time base and no goal steps on it; a goal is not admitted while a stream it needs is refused, and
  a running one ends with the refusal.
ContactState for every finger on every sample comes from `on_taxels` whether or not a goal runs.

What differs between goal kinds is each kind's module (grasp_goal.py, manipulate_goal.py, gripper_goal.py,
teleop_goal.py: a `GoalKind` each, listed in goal_kinds.GOAL_KINDS): its request's validation and
defaults, the streams and inputs it needs, its controller, its status. The core finds a request's
kind by its type.

Its users carry its actions out through `ActionHandlers.carry_out`, the one dispatch over the
actions' types: each user (the node, the closed loop, the sim recorder) names what it does with each
type, and a type it does not name is let pass.

Goals are admitted in two steps. `accept` answers a `Refusal` (prisma_common.goal_refusal:
`invalid`, `busy`, `not_ready`, `no_contact` and why) or None: the request within the limits
(invalid), no other goal running or just accepted (busy: so goals sent together have one outcome,
the first runs, the others are refused), every stream the goal needs flowing (not_ready: its
fingers' taxels and, where it steers by force, wrenches, /joint_states, and the MoveMotors action
server), and where the kind asks for it a contact on the pad it steers by (no_contact: a
manipulation). An admitted goal holds the core until `start` runs it. The node accepts every goal
and aborts a refused one at once with the refusal as its result's reason.

Motors stop when this node is lost: every MoveMotors goal carries a short timeout (`MOVE_LEASE_S`)
and, while the controller keeps the same velocity command, the goal is re-sent every
`MOVE_REFRESH_S` (`MoveLease`, move_lease.py). A node that dies or hangs stops refreshing, the motor
driver's goal times out and the driver stops the motors. Each goal's lease counts from when the
oldest input the watchdog watches arrived, so no command outlives its data by more than a lease.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from prisma_common.diagnostics import OK, WARN, DiagnosticStatusData
from prisma_common.goal_refusal import BUSY, INVALID, NOT_READY, Refusal, refusal_code
from prisma_common.sample_stamps import StampGate, StampNews

from .contact_monitor import ContactEvaluation, ContactMonitor, check_k
from .controllers import (
    CANCELED,
    JOINT_LIMIT,
    MOTOR_FAULT,
    NO_CONTACT,
    SENSOR_STALE,
    TIMEOUT,
    ControlInput,
    ControlLimits,
    ControlOutput,
    Controller,
    JointSample,
)
from .goal_kind import Feedback, Finished, GoalContext, GoalKind, Streams
from .goal_kinds import GOAL_KINDS, kind_of
from .grasp_goal import GraspRequest, GraspStatus
from .gripper_goal import GripperRequest, GripperStatus
from .manipulate_goal import MOTIONS, ManipulateRequest, ManipulateStatus
from .move_lease import MOVE_LEASE_S, MOVE_REFRESH_S, MoveLease, SendMove, StopMotors
from .node_config import ManipulationConfig
from .sample_alignment import SampleAligner
from .watchdog import JOINT_STATES, SensorWatchdog

STAMP_STATUS = "manipulation: stamps"  # its /diagnostics status of the streams' stamps

__all__ = ["MOTIONS", "MOVE_LEASE_S", "MOVE_REFRESH_S", "ActionHandlers", "Feedback", "Finished", "GraspRequest",
           "GraspStatus", "GripperRequest", "GripperStatus", "ManipulateRequest", "ManipulateStatus", "MoveLease",
           "SendMove", "StampNews", "StopMotors"]  # the kinds' data and the core's decisions, for its users

@dataclass(frozen=True)
class Ignored:
    """An input set aside without changing any decision (the node logs the reason)."""

    topic: str
    reason: str


def _let_pass(action: Any) -> None:
    """What a user does with an action type it does not name."""


@dataclass(frozen=True)
class ActionHandlers:
    """How one user of the core carries out its decisions, a callable per action type (each lets
    its actions pass unless named): the node sends and cancels MoveMotors goals, publishes feedback,
    ends the goal and logs; the closed loop drives the sim motor driver's core; the sim recorder
    writes the messages the node would publish."""

    send_move: Callable[[SendMove], None] = _let_pass
    stop_motors: Callable[[StopMotors], None] = _let_pass
    feedback: Callable[[Feedback], None] = _let_pass
    finished: Callable[[Finished], None] = _let_pass
    ignored: Callable[[Ignored], None] = _let_pass
    stamp_news: Callable[[StampNews], None] = _let_pass

    def carry_out(self, actions: Iterable[Any]) -> None:
        """Each action, in order, to its type's callable; TypeError for an action of no such type
        (a core that decides something new must say who carries it out)."""
        for action in actions:
            handler = _HANDLER_FIELDS.get(type(action))
            if handler is None:
                raise TypeError(f"{type(action).__name__} is none of the core's actions "
                                f"{[t.__name__ for t in _HANDLER_FIELDS]}")
            getattr(self, handler)(action)


# the one place an action's type picks what is done with it
_HANDLER_FIELDS: dict[type, str] = {SendMove: "send_move", StopMotors: "stop_motors", Feedback: "feedback",
                                    Finished: "finished", Ignored: "ignored", StampNews: "stamp_news"}


class GoalRefused(ValueError):
    """A goal that may not start, with the refusal its result carries."""

    def __init__(self, refusal: Refusal) -> None:
        super().__init__(str(refusal))
        self.refusal = refusal


class ManipulationCore:
    def __init__(self, config: ManipulationConfig, kinds: tuple[GoalKind, ...] = GOAL_KINDS) -> None:
        self.config = config
        self.monitor = ContactMonitor(config.k, config.min_mean_voltage)
        self.k_parameter = config.k
        self.limits = ControlLimits(config.limits_motors(), config.limit_margin)
        self.watchdog = SensorWatchdog(int(round(config.stale_timeout * 1e9)))
        self.aligner = SampleAligner()
        self.lease = MoveLease()
        self.kinds = {k.request_type: k for k in kinds}
        self.controller: Controller | None = None
        self.goal: GoalKind | None = None  # the running goal's kind
        self.joints: JointSample | None = None
        self.forces: dict[str, float] = {}
        self.inputs: dict[str, Any] = {}  # the goal kinds' extra inputs, latest value each
        self._streams = Streams((), ())  # the running goal's
        self._required: frozenset = frozenset()
        self._input_timeout_ns = 0  # the running goal's inputs'
        self._accepted: str | None = None  # kind of a goal admitted and not started yet
        self.evaluations: dict[str, ContactEvaluation] = {}  # each finger's latest
        self.ignored_joint_states = 0
        self.stamp_limits = config.stamp_limits()
        self._stamp_gates: dict[str, StampGate] = {}  # per stream, created with its first sample
        self._input_topics = {i.stream: i.topic for k in kinds for i in k.inputs}  # the kinds' inputs' topics

    # ---- parameters ------------------------------------------------------------------------
    def set_k(self, k: float) -> None:
        """The k parameter changed: applies from the next sample (also during a goal)."""
        self.monitor.set_k(check_k(k))
        self.k_parameter = self.monitor.k

    def reconfigure(self, config: ManipulationConfig) -> None:
        """Live parameters changed (validated by ManipulationConfig): k and min_mean_voltage apply
        from the next sample, stale_timeout from the watchdog's next check, the goal defaults and
        controller settings from the next goal (a running one keeps what it started with)."""
        if config.k != self.k_parameter:
            self.set_k(config.k)
        self.monitor.min_mean_voltage = config.min_mean_voltage
        self.watchdog.stale_ns = int(round(config.stale_timeout * 1e9))
        self.stamp_limits = config.stamp_limits()
        for gate in self._stamp_gates.values():
            gate.limits = self.stamp_limits
        self.config = config

    @property
    def busy(self) -> bool:
        return self.controller is not None

    @property
    def kind(self) -> str | None:
        """The running goal's kind name ("grasp"), None when idle."""
        return self.goal.name if self.goal is not None else None

    def context(self) -> GoalContext:
        return GoalContext(self.config, self.limits, self.k_parameter, self.forces, self.joints, self.inputs)

    # ---- goal validation -------------------------------------------------------------------
    def kind_of(self, req: Any) -> GoalKind:
        """The goal kind a request belongs to (by its type); TypeError for a request of no kind it serves."""
        return self.kinds.get(type(req)) or kind_of(req, tuple(self.kinds.values()))

    def resolve(self, req: Any) -> tuple[Any, Refusal | None]:
        """The request with defaults filled in, or why it is invalid (beyond the limits)."""
        r, why = self.kind_of(req).resolve(req, self.context())
        return r, (Refusal(INVALID, why) if why else None)

    def streams(self, req: Any) -> Streams:
        """What a (resolved) request's goal needs flowing."""
        return self.kind_of(req).streams(req, self.context())

    def _busy_reason(self) -> Refusal | None:
        if self.controller is not None:
            return Refusal(BUSY, f"a {self.kind} goal is running")
        if self._accepted is not None:
            return Refusal(BUSY, f"a {self._accepted} goal was accepted and is starting")
        return None

    def readiness(self, streams: Streams, move_server_ready: bool, now_ns: int) -> Refusal | None:
        """None when a goal needing these streams can run now, else what is missing (not_ready)."""
        if not move_server_ready:
            return Refusal(NOT_READY, f"MoveMotors action server {self.config.move_action} not available "
                                      "(motor_driver not running?)")
        missing = self.watchdog.fresh(streams.watched(), now_ns)
        return Refusal(NOT_READY, missing) if missing else None

    def input_readiness(self, streams: Streams, now_ns: int) -> Refusal | None:
        """not_ready when an input the goal follows came and is already unusable (its latest sample
        refused by its stamp, or older than /joint_states by more than the goal's input timeout): the
        goal would step on it, and the motors move, before the watchdog ended it. An input that has
        not come yet is no reason: the goal waits for it."""
        timeout_ns = int(round((streams.input_timeout_s or self.config.stale_timeout) * 1e9))
        for stream in streams.inputs:
            why = self.watchdog.input_fresh(stream, timeout_ns, now_ns, self._input_topics.get(stream))
            if why is not None:
                return Refusal(NOT_READY, why)
        return None

    def contact_refusal(self, finger: str) -> Refusal | None:
        """no_contact when `finger`'s latest sample shows nothing on its pad (mean voltage below
        min_mean_voltage): a manipulation steers a held object and has nothing to steer here."""
        evaluation = self.evaluations.get(finger)
        floor = self.config.min_mean_voltage
        if evaluation is None or evaluation.mean_voltage >= floor:
            return None
        return Refusal(NO_CONTACT, f"the {finger} pad is not in contact (mean {evaluation.mean_voltage:.2f} V, "
                                   f"below min_mean_voltage {floor} V): a manipulation starts from a held "
                                   "object, grasp first")

    def accept(self, req: Any, move_server_ready: bool, now_ns: int) -> Refusal | None:
        """None = admitted (the core is held for it until it starts), else why it is refused."""
        r, refusal = self.resolve(req)
        if r is None or refusal:
            return refusal
        streams = self.streams(r)
        refusal = (self._busy_reason() or self.readiness(streams, move_server_ready, now_ns)
                   or self.input_readiness(streams, now_ns))
        if refusal is None and streams.contact is not None:
            refusal = self.contact_refusal(streams.contact)
        if refusal is None:
            self._accepted = self.kind_of(req).name
        return refusal

    # ---- goal start / end ------------------------------------------------------------------
    def refused(self, kind: str, refusal: Refusal) -> Finished:
        """The end of a goal refused before it started: the refusal as its reason, and the kind's
        status of where the hand stands (a gripper's: the fingers position and highest pad force)."""
        goal = next(k for k in self.kinds.values() if k.name == kind)
        return Finished(kind, False, str(refusal), 0.0, goal.idle_status(self.context()))

    def start(self, req: Any, now_ns: int) -> list:
        """Run the admitted goal: its first actions. GoalRefused naming why it may not start."""
        goal = self.kind_of(req)
        if self._accepted == goal.name:
            self._accepted = None  # the admitted goal starts now (or fails to)
        r, refusal = self.resolve(req)
        refusal = refusal or self._busy_reason()
        if refusal is None and self.joints is None:
            refusal = Refusal(NOT_READY, "no /joint_states received yet")
        if refusal is not None or r is None:
            raise GoalRefused(refusal or Refusal(INVALID, "no request"))
        ctx = self.context()
        built = goal.build(r, ctx)
        streams = goal.streams(r, ctx)
        self.controller, self.goal, self._streams = built.controller, goal, streams
        self._required = frozenset({("taxels", f) for f in built.controller.fingers} |
                                   {("wrench", f) for f in streams.wrenches})
        self._input_timeout_ns = int(round((streams.input_timeout_s or self.config.stale_timeout) * 1e9))
        if built.k is not None:
            self.monitor.set_k(built.k)
        self.aligner.reset()
        self.watchdog.arm(now_ns)
        assert self.joints is not None  # refused above without them
        return self._actions(built.controller.start(self.joints), now_ns)

    def _end(self) -> None:
        self.controller, self.goal = None, None
        self.watchdog.disarm()
        self.lease.release()
        self.monitor.set_k(self.k_parameter)

    # ---- inputs ----------------------------------------------------------------------------
    def _judge_stamp(self, stream: str, stamp_ns: int, receipt_ns: int) -> tuple[bool, list]:
        """Whether a sample of `stream` may be acted on by its stamp (prisma_common.sample_stamps); a
        refused one is told to the watchdog, which names it while it lasts. The log line (StampNews)
        when the stream's judgement changes."""
        gate = self._stamp_gates.get(stream)
        if gate is None:
            gate = self._stamp_gates[stream] = StampGate(self._input_topics.get(stream, stream), self.stamp_limits)
        accepted, news = gate.judge(stamp_ns, receipt_ns)
        if not accepted:
            self.watchdog.refuse(stream, gate.refused or "", receipt_ns)
        return accepted, [news] if news is not None else []

    def stamp_status(self) -> DiagnosticStatusData | None:
        """`manipulation: stamps` for /diagnostics once a sample was refused by its stamp (None before:
        a hand whose stamps were always good has nothing to say): WARN naming each stream whose latest
        sample was refused (the line says the fix), else OK; per stream its judgement."""
        total = sum(g.refused_total for g in self._stamp_gates.values())
        if total == 0:
            return None
        refused = [g.refused for g in self._stamp_gates.values() if g.refused is not None]
        values = {g.stream: g.refused or "accepted" for g in self._stamp_gates.values()}
        values["refused_samples"] = str(total)
        if refused:
            return DiagnosticStatusData(STAMP_STATUS, WARN, f"refused: {'; '.join(refused)}", values=values)
        return DiagnosticStatusData(STAMP_STATUS, OK, "every stream's stamps accepted", values=values)

    def on_taxels(self, finger: str, stamp_ns: int, voltages: np.ndarray,
                  receipt_ns: int) -> tuple[ContactEvaluation, list]:
        """A pad's scan: its contact evaluated whatever its stamp (ContactState is published for every
        sample); a goal steps on it only when its stamp is accepted."""
        evaluation = self.monitor.evaluate(finger, stamp_ns, voltages)
        self.evaluations[finger] = evaluation
        accepted, news = self._judge_stamp(f"taxels/{finger}", stamp_ns, receipt_ns)
        if not accepted:
            return evaluation, news
        self.watchdog.sample(f"taxels/{finger}", stamp_ns, receipt_ns)
        if self.controller is None:
            return evaluation, news
        self.aligner.add(("taxels", finger), stamp_ns, evaluation)
        return evaluation, news + self._try_step(receipt_ns)

    def on_wrench(self, finger: str, stamp_ns: int, normal_force_n: float, receipt_ns: int) -> list:
        accepted, news = self._judge_stamp(f"wrench/{finger}", stamp_ns, receipt_ns)
        if not accepted:
            return news
        self.forces[finger] = normal_force_n
        self.watchdog.sample(f"wrench/{finger}", stamp_ns, receipt_ns)
        if self.controller is None:
            return news
        self.aligner.add(("wrench", finger), stamp_ns, normal_force_n)
        return news + self._try_step(receipt_ns)

    def on_input(self, stream: str, stamp_ns: int, value: Any, receipt_ns: int) -> list:
        """A goal kind's extra input (`InputStream`): held and watched; it never shares a scan's
        stamp, so the controller gets its latest value on the next scan (sample-and-hold). One whose
        stamp is refused is not held: a running goal ends with the refusal at the next check, before
        any step on it."""
        accepted, news = self._judge_stamp(stream, stamp_ns, receipt_ns)
        if not accepted:
            return news
        self.inputs[stream] = value
        self.watchdog.sample(stream, stamp_ns, receipt_ns)
        return news

    def on_joints(self, sample: JointSample, receipt_ns: int) -> list:
        """A /joint_states message. One without a position for every hand motor (another driver's
        joints, empty arrays) is ignored: it moves no time base and changes no decision."""
        motors = self.config.motor_names
        missing = [m for m in motors if m not in sample.positions]
        if missing:
            self.ignored_joint_states += 1
            return [Ignored("/joint_states", f"no position for {', '.join(missing)} "
                                             f"(joints {sorted(sample.positions)}); not the hand's motor driver")]
        accepted, news = self._judge_stamp(JOINT_STATES, sample.stamp_ns, receipt_ns)
        if not accepted:  # neither the hand's position nor the time base: a running goal ends at this check
            return news + self.check(receipt_ns)
        self.joints = JointSample(sample.stamp_ns, {m: sample.positions[m] for m in motors},
                                  {m: sample.velocities[m] for m in motors if m in sample.velocities},
                                  {m: sample.currents[m] for m in motors if m in sample.currents})
        self.watchdog.reference(sample.stamp_ns, receipt_ns)
        return news + self.check(receipt_ns)

    def check(self, now_ns: int) -> list:
        """Watchdog tick: stale data aborts the goal with sensor_stale (or its kind's reason for its
        own input) and stops the motors; a running motor command is re-sent when due (MoveLease)."""
        if self.controller is None:
            return []
        watched = self._watched()
        stale = self.watchdog.check(watched, now_ns)
        if stale is not None:
            return self._abort(now_ns, SENSOR_STALE, stale)
        stale_input = self._stale_input(now_ns)
        if stale_input is not None:
            return stale_input
        refresh = self.lease.refresh(now_ns, self._data_ns(now_ns, watched))
        return [refresh] if refresh is not None else []

    def cancel(self, now_ns: int) -> list:
        return [] if self.controller is None else self._abort(now_ns, CANCELED)

    def on_move_result(self, reason: str, now_ns: int) -> list:
        """Result of our current MoveMotors goal. The driver refusing it ends the goal with the
        driver's refusal as its reason, code and why (`not_homed: fingers (id 1) not homed ...`,
        `not_ready: homing (...)`): the client learns what to do, as if it had sent the MoveMotors
        goal itself; a motor fault ends it with the driver's `motor_fault: <what failed>`. Only the
        driver's `invalid` is not the client's to act on: the client's goal was checked here, the
        motor command this node made of it was late on its way (its lease over on arrival: this node
        or the link held up) or does not fit the driver (its limits configured apart from this
        node's), so the goal ends `not_ready` with the driver's words. A timeout (the refresh came
        too late) sends the command again; at a joint limit the driver stopped the motors, so the
        command is no longer refreshed (the controller ends on the position it sees)."""
        if self.controller is None:
            return []
        code = refusal_code(reason)
        if code == INVALID:
            return self._abort(now_ns, f"{NOT_READY}: the motor driver refused this node's motor command ({reason})")
        if code is not None or reason.startswith(MOTOR_FAULT):
            return self._abort(now_ns, reason)
        if reason == TIMEOUT:
            renewed = self.lease.renew(now_ns, self._data_ns(now_ns))
            return [renewed] if renewed is not None else []
        if reason == JOINT_LIMIT:
            self.lease.release()
        return []

    # ---- internals -------------------------------------------------------------------------
    def _running(self) -> tuple[Controller, GoalKind]:
        """The running goal's controller and kind (callers check that one runs)."""
        if self.controller is None or self.goal is None:
            raise RuntimeError("no goal is running")
        return self.controller, self.goal

    def _watched(self) -> list[str]:
        """The streams the running goal's watchdog watches (besides /joint_states)."""
        controller = self._running()[0]
        return [f"taxels/{f}" for f in controller.fingers] + [f"wrench/{f}" for f in self._streams.wrenches]

    def _data_ns(self, now_ns: int, watched: list[str] | None = None) -> int:
        """When the oldest watched input arrived (`watched`: the running goal's, if its caller has them):
        a motor command's lease counts from there (SendMove)."""
        oldest = self.watchdog.oldest_receipt(self._watched() if watched is None else watched)
        return now_ns if oldest is None else oldest

    def _abort(self, now_ns: int, reason: str, detail: str = "") -> list:
        return self._actions(self._running()[0].abort(now_ns, reason), now_ns, detail)

    def _stale_input(self, now_ns: int) -> list | None:
        """The running goal ended (its kind's stale reason) when an input it follows is silent, too old
        against /joint_states or refused by its stamp; else None."""
        goal = self._running()[1]
        for spec in (i for i in goal.inputs if i.stream in self._streams.inputs):
            silent = self.watchdog.check_input(spec.stream, self._input_timeout_ns, now_ns, spec.topic)
            if silent is not None:
                return self._abort(now_ns, goal.stale_reason(spec.stream), silent)
        return None

    def _try_step(self, now_ns: int) -> list:
        ready = self.aligner.ready(self._required)
        if ready is None or self.joints is None:
            return []
        # the inputs are checked before the step, not only by the watchdog's next tick: a target that
        # is already stale must not move a motor first
        stale_input = self._stale_input(now_ns)
        if stale_input is not None:
            return stale_input
        controller = self._running()[0]
        stamp, entries = ready
        contacts = {f: entries[("taxels", f)] for f in controller.fingers}
        forces = dict(self.forces)
        forces.update({f: entries[("wrench", f)] for f in self._streams.wrenches})
        # each input's latest value (sample-and-hold), once one came for this goal: until then it waits
        inputs = {s: self.inputs[s] for s in self._streams.inputs if self.watchdog.arrived(s, self._input_timeout_ns)}
        return self._actions(controller.step(ControlInput(stamp, contacts, forces, self.joints, inputs)), now_ns)

    def _actions(self, out: ControlOutput, now_ns: int, detail: str = "") -> list:
        c, goal = self._running()
        actions: list = []
        if out.command is not None:
            actions.append(self.lease.command(out.command.velocities_rpm, now_ns, self._data_ns(now_ns)))
        status = goal.status(c, self.context())
        actions.append(Feedback(goal.name, out.phase, status))
        if out.done:
            stop_time = 0.0
            if c.stop_ns is not None and c.start_ns is not None:
                stop_time = (c.stop_ns - c.start_ns) * 1e-9
            actions.append(Finished(goal.name, out.success, out.reason or "", stop_time, status, detail))
            self._end()
        return actions
