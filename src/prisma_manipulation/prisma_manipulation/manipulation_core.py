"""What the manipulation node decides, without ROS: goal validation, one controller at a time,
stepping it once per sensor scan, the watchdog, and the motor commands that result.

The node feeds it messages (taxels, wrenches, joint states, MoveMotors results, cancel requests,
watchdog ticks) as plain data and carries out the returned actions:
- SendMove: send a MoveMotors velocity goal (it preempts the previous one on the motor driver);
- StopMotors: cancel the running MoveMotors goal (cancel = stop);
- Feedback / Finished: the Grasp, Manipulate or GripperCommand goal's feedback and end;
- Ignored: an input set aside (a /joint_states message without the hand's joints), for the log.
ContactState for every finger on every sample comes from `on_taxels` whether or not a goal runs.

Goals are admitted in two steps. `accept_grasp` / `accept_manipulate` / `accept_gripper` answer a
`Refusal` (prisma_common.goal_refusal: `invalid`, `busy`, `not_ready`, `no_contact` and why) or
None: the request within the limits (invalid), no other goal running or just accepted (busy: so
goals sent together have one outcome, the first runs, the others are refused), every stream the
goal needs flowing (not_ready: its fingers' taxels and, where it steers by force, wrenches,
/joint_states, and the MoveMotors action server), and for a manipulation a contact on the pad it
steers by (no_contact). An admitted goal holds the core until `start_grasp` / `start_manipulate` /
`start_gripper` runs it. The node accepts every goal and aborts a refused one at once with the
refusal as its result's reason.

Motors stop when this node is lost: every MoveMotors goal carries a short timeout (`MOVE_LEASE_S`)
and, while the controller keeps the same velocity command, the goal is re-sent every
`MOVE_REFRESH_S` (`MoveLease`). A node that dies or hangs stops refreshing, the motor driver's goal
times out and the driver stops the motors.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from prisma_common.goal_refusal import BUSY, INVALID, NOT_READY, Refusal, refusal_code

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
from .grasp_controller import GRASP_PRESETS, GraspController
from .gripper_controller import GripperController
from .motion_controllers import ForceKeeper, HoldController, HorizontalController, VerticalController
from .node_config import ManipulationConfig
from .sample_alignment import SampleAligner
from .watchdog import SensorWatchdog

GRASP = "grasp"
MANIPULATE = "manipulate"
GRIPPER = "gripper"
MOTIONS = ("horizontal", "vertical", "hold")

# MoveMotors goals last this long on the motor driver unless re-sent: the motors stop within it (+ one
# driver tick) when this node dies. Re-sent every MOVE_REFRESH_S, so two refreshes may be late (a busy
# executor) before the motors stop under a live controller.
MOVE_LEASE_S = 0.3
MOVE_REFRESH_S = 0.1


@dataclass(frozen=True)
class GraspRequest:
    grasp: str
    finger_force: float = 0.0  # 0 = configured default
    thumb_force: float = 0.0
    speed_rpm: float = 0.0
    timeout_s: float = 0.0


@dataclass(frozen=True)
class ManipulateRequest:
    motion: str
    speed_rpm: float = 0.0
    k: float = 0.0  # 0 = the node's k parameter
    use_force: bool = False
    timeout_s: float = 0.0


@dataclass(frozen=True)
class GripperRequest:
    position: float  # fingers motor target, rad: 0 = open (gripper_controller.py)
    max_effort: float = 0.0  # N on the estimated pad forces; 0 = configured default


@dataclass(frozen=True)
class SendMove:
    velocities_rpm: dict[str, float]
    timeout_s: float


@dataclass(frozen=True)
class StopMotors:
    pass


@dataclass(frozen=True)
class Ignored:
    """An input set aside without changing any decision (the node logs the reason)."""

    topic: str
    reason: str


@dataclass(frozen=True)
class Feedback:
    kind: str
    phase: str
    finger_force: float
    thumb_force: float
    feasible: bool
    threshold: float
    # a gripper goal's: fingers position (rad), highest pad force (N), and how it stands
    position: float = 0.0
    effort: float = 0.0
    stalled: bool = False
    reached_goal: bool = False


@dataclass(frozen=True)
class Finished:
    kind: str
    success: bool
    reason: str
    stop_time_s: float  # from goal start to the stop (0 when it never stopped on its own)
    finger_force: float
    thumb_force: float
    detail: str = ""
    position: float = 0.0  # a gripper goal's, as in Feedback
    effort: float = 0.0
    stalled: bool = False
    reached_goal: bool = False


class GoalRefused(ValueError):
    """A goal that may not start, with the refusal its result carries."""

    def __init__(self, refusal: Refusal) -> None:
        super().__init__(str(refusal))
        self.refusal = refusal


def _finite(x: float) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


class MoveLease:
    """The MoveMotors goals that carry one velocity command: sent with a `lease_s` timeout, re-sent
    every `refresh_s` while the command holds, so the motor driver stops the motors on its own when
    the sender is gone. The off-robot recorder (prisma_bringup.hand_session) runs the same decisions."""

    def __init__(self, lease_s: float = MOVE_LEASE_S, refresh_s: float = MOVE_REFRESH_S) -> None:
        if not 0 < refresh_s < lease_s:
            raise ValueError(f"refresh {refresh_s} s must be > 0 and below the lease {lease_s} s")
        self.lease_s = lease_s
        self.refresh_ns = int(round(refresh_s * 1e9))
        self.velocities: dict[str, float] | None = None  # the command being kept alive, None = none
        self.sent_ns = 0

    def command(self, velocities_rpm: Mapping[str, float], now_ns: int) -> SendMove | StopMotors:
        """A new command from the controller: a goal for motion, a cancel for a stop."""
        if all(v == 0.0 for v in velocities_rpm.values()):
            self.velocities = None
            return StopMotors()
        self.velocities = dict(velocities_rpm)
        return self._send(self.velocities, now_ns)

    def refresh(self, now_ns: int) -> SendMove | None:
        """The same command again when the last goal is `refresh_s` old."""
        if self.velocities is None or now_ns - self.sent_ns < self.refresh_ns:
            return None
        return self._send(self.velocities, now_ns)

    def renew(self, now_ns: int) -> SendMove | None:
        """The driver ended the goal by its timeout before the refresh came: send it again now."""
        return None if self.velocities is None else self._send(self.velocities, now_ns)

    def release(self) -> None:
        """Nothing to keep alive (goal over, or the driver stopped the motors at a limit)."""
        self.velocities = None

    def _send(self, velocities: dict[str, float], now_ns: int) -> SendMove:
        self.sent_ns = now_ns
        return SendMove(dict(velocities), self.lease_s)


class ManipulationCore:
    def __init__(self, config: ManipulationConfig) -> None:
        self.config = config
        self.monitor = ContactMonitor(config.k, config.min_mean_voltage)
        self.k_parameter = config.k
        self.limits = ControlLimits(config.limits_motors(), config.limit_margin)
        self.watchdog = SensorWatchdog(int(round(config.stale_timeout * 1e9)))
        self.aligner = SampleAligner()
        self.lease = MoveLease()
        self.controller: Controller | None = None
        self.kind: str | None = None
        self.joints: JointSample | None = None
        self.forces: dict[str, float] = {}
        self._force_fingers: tuple[str, ...] = ()
        self._required: frozenset = frozenset()
        self._accepted: str | None = None  # kind of a goal admitted and not started yet
        self.evaluations: dict[str, ContactEvaluation] = {}  # each finger's latest
        self.stale_reason = ""
        self.ignored_joint_states = 0

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
        self.config = config

    @property
    def busy(self) -> bool:
        return self.controller is not None

    # ---- goal validation -------------------------------------------------------------------
    def resolve_grasp(self, req: GraspRequest) -> tuple[GraspRequest | None, Refusal | None]:
        """The request with defaults filled in, or why it is invalid (beyond the limits)."""
        r, why = self._resolve_grasp(req)
        return r, (Refusal(INVALID, why) if why else None)

    def _resolve_grasp(self, req: GraspRequest) -> tuple[GraspRequest | None, str | None]:
        c = self.config
        if req.grasp not in GRASP_PRESETS:
            return None, f"grasp {req.grasp!r} is not one of {sorted(GRASP_PRESETS)}"
        r = GraspRequest(req.grasp, req.finger_force or c.grasp_finger_force, req.thumb_force or c.grasp_thumb_force,
                         req.speed_rpm or c.grasp_speed_rpm, req.timeout_s or c.grasp_timeout)
        for name, value, limit in (("finger_force", r.finger_force, c.max_force_n),
                                   ("thumb_force", r.thumb_force, c.max_force_n),
                                   ("speed_rpm", r.speed_rpm, c.max_speed_rpm)):
            if not _finite(value) or value <= 0:
                return None, f"{name} {value} must be > 0"
            if value > limit:
                return None, f"{name} {value} above the configured limit {limit}"
        if not _finite(r.timeout_s) or r.timeout_s < 0:
            return None, f"timeout {r.timeout_s} must be >= 0"
        return r, self._fingers_configured(f"grasp {r.grasp}", self.grasp_streams(r)[0])

    def resolve_manipulate(self, req: ManipulateRequest) -> tuple[ManipulateRequest | None, Refusal | None]:
        """The request with defaults filled in, or why it is invalid (beyond the limits)."""
        r, why = self._resolve_manipulate(req)
        return r, (Refusal(INVALID, why) if why else None)

    def _resolve_manipulate(self, req: ManipulateRequest) -> tuple[ManipulateRequest | None, str | None]:
        c = self.config
        if req.motion not in MOTIONS:
            return None, f"motion {req.motion!r} is not one of {list(MOTIONS)}"
        default_speed = {"horizontal": c.horizontal_speed_rpm, "vertical": c.vertical_speed_rpm,
                         "hold": c.hold_speed_rpm}[req.motion]
        r = ManipulateRequest(req.motion, req.speed_rpm or default_speed, req.k or self.k_parameter,
                              bool(req.use_force), req.timeout_s or c.manipulate_timeout)
        if not _finite(r.speed_rpm) or r.speed_rpm <= 0:
            return None, f"speed_rpm {r.speed_rpm} must be > 0"
        if r.speed_rpm > c.max_speed_rpm:
            return None, f"speed_rpm {r.speed_rpm} above the configured limit {c.max_speed_rpm}"
        try:
            check_k(r.k)
        except ValueError as exc:
            return None, str(exc)
        if r.motion == "hold" and r.k <= c.hold_min_k:
            return None, f"k {r.k} too low for hold: needs k > {c.hold_min_k}"
        if not _finite(r.timeout_s) or r.timeout_s < 0:
            return None, f"timeout {r.timeout_s} must be >= 0"
        return r, self._fingers_configured(f"motion {r.motion}", self.manipulate_streams(r)[0])

    def resolve_gripper(self, req: GripperRequest) -> tuple[GripperRequest | None, Refusal | None]:
        """The request with max_effort 0 replaced by the configured default, or why it is invalid."""
        c = self.config
        fingers = self.limits.motors["fingers"]
        lo, hi = fingers.min_position_rad, fingers.max_position_rad
        why = None
        if not _finite(req.position) or not lo <= req.position <= hi:
            why = f"position {req.position} rad outside the fingers motor's range [{lo}, {hi}] (0 = open)"
        elif not _finite(req.max_effort) or req.max_effort < 0:
            why = f"max_effort {req.max_effort} must be >= 0 N (0 = gripper_max_effort {c.gripper_max_effort} N)"
        elif req.max_effort > c.max_force_n:
            why = f"max_effort {req.max_effort} above the configured limit {c.max_force_n}"
        if why:
            return None, Refusal(INVALID, why)
        return GripperRequest(req.position, req.max_effort or c.gripper_max_effort), None

    def grasp_streams(self, r: GraspRequest) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(fingers whose taxels, fingers whose wrenches) a grasp steps on: the thumb and the preset's pads."""
        fingers = ("thumb",) + GRASP_PRESETS[r.grasp].force_fingers
        return fingers, fingers

    def manipulate_streams(self, r: ManipulateRequest) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(taxel fingers, wrench fingers) of a manipulation: the monitored pad (+ thumb), the
        thumb's force with use_force."""
        finger = self.config.monitored_finger
        taxels = (finger,) if finger == "thumb" else (finger, "thumb")
        return taxels, ("thumb",) if r.use_force else ()

    def _fingers_configured(self, what: str, fingers: tuple[str, ...]) -> str | None:
        missing = [f for f in fingers if f not in self.config.fingers]
        if missing:
            return f"{what} needs the {', '.join(missing)} pad(s), not in parameter fingers {self.config.fingers}"
        return None

    def gripper_streams(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(taxel fingers, wrench fingers) of a gripper goal: every configured pad carries its force."""
        pads = tuple(self.config.fingers)
        return pads, pads

    def _busy_reason(self) -> Refusal | None:
        if self.controller is not None:
            return Refusal(BUSY, f"a {self.kind} goal is running")
        if self._accepted is not None:
            return Refusal(BUSY, f"a {self._accepted} goal was accepted and is starting")
        return None

    def readiness(self, taxel_fingers: tuple[str, ...], wrench_fingers: tuple[str, ...],
                  move_server_ready: bool, now_ns: int) -> Refusal | None:
        """None when a goal needing these streams can run now, else what is missing (not_ready)."""
        if not move_server_ready:
            return Refusal(NOT_READY, f"MoveMotors action server {self.config.move_action} not available "
                                      "(motor_driver not running?)")
        streams = [f"taxels/{f}" for f in taxel_fingers] + [f"wrench/{f}" for f in wrench_fingers]
        missing = self.watchdog.fresh(streams, now_ns)
        return Refusal(NOT_READY, missing) if missing else None

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

    def accept_grasp(self, req: GraspRequest, move_server_ready: bool, now_ns: int) -> Refusal | None:
        """None = admitted (the core is held for it until it starts), else why it is refused."""
        r, refusal = self.resolve_grasp(req)
        if r is None or refusal:
            return refusal
        return self._admit(GRASP, self.grasp_streams(r), move_server_ready, now_ns)

    def accept_manipulate(self, req: ManipulateRequest, move_server_ready: bool, now_ns: int) -> Refusal | None:
        r, refusal = self.resolve_manipulate(req)
        if r is None or refusal:
            return refusal
        return self._admit(MANIPULATE, self.manipulate_streams(r), move_server_ready, now_ns,
                           self.config.monitored_finger)

    def accept_gripper(self, req: GripperRequest, move_server_ready: bool, now_ns: int) -> Refusal | None:
        r, refusal = self.resolve_gripper(req)
        if r is None or refusal:
            return refusal
        return self._admit(GRIPPER, self.gripper_streams(), move_server_ready, now_ns)

    def _admit(self, kind: str, streams: tuple[tuple[str, ...], tuple[str, ...]], move_server_ready: bool,
               now_ns: int, contact_finger: str | None = None) -> Refusal | None:
        refusal = self._busy_reason() or self.readiness(*streams, move_server_ready, now_ns)
        if refusal is None and contact_finger is not None:
            refusal = self.contact_refusal(contact_finger)
        if refusal is None:
            self._accepted = kind
        return refusal

    # ---- goal start / end ------------------------------------------------------------------
    def refused(self, kind: str, refusal: Refusal) -> Finished:
        """The end of a goal refused before it started: the refusal as its reason, and where the
        hand stands (the fingers position and the highest pad force, for a gripper's result)."""
        position = self.joints.positions.get("fingers", 0.0) if self.joints is not None else 0.0
        effort = max((self.forces.get(f, 0.0) for f in self.config.fingers), default=0.0)
        return Finished(kind, False, str(refusal), 0.0, 0.0, 0.0, position=position, effort=effort)

    def _startable(self, kind: str, resolved: tuple[Any, Refusal | None]) -> Any:
        """The resolved request of a goal that may start now; GoalRefused naming why it may not."""
        if self._accepted == kind:
            self._accepted = None  # the admitted goal starts now (or fails to)
        request, refusal = resolved
        refusal = refusal or self._busy_reason()
        if refusal is None and self.joints is None:
            refusal = Refusal(NOT_READY, "no /joint_states received yet")
        if refusal is not None or request is None:
            raise GoalRefused(refusal or Refusal(INVALID, "no request"))
        return request

    def start_grasp(self, req: GraspRequest, now_ns: int) -> list:
        r: GraspRequest = self._startable(GRASP, self.resolve_grasp(req))
        c = self.config
        controller = GraspController(self.limits, r.grasp, r.finger_force, r.thumb_force, r.speed_rpm,
                                     r.timeout_s, c.contact_force_n, c.lateral_closure)
        return self._start(GRASP, controller, self.grasp_streams(r)[1], now_ns)

    def start_manipulate(self, req: ManipulateRequest, now_ns: int) -> list:
        r: ManipulateRequest = self._startable(MANIPULATE, self.resolve_manipulate(req))
        c = self.config
        keeper = ForceKeeper(c.force_target_n, c.force_band_n, c.force_speed_rpm) if r.use_force else None
        finger = c.monitored_finger
        controller: Controller
        contact = c.min_mean_voltage
        if r.motion == "horizontal":
            controller = HorizontalController(self.limits, r.speed_rpm, finger, timeout_s=r.timeout_s,
                                              force_keeper=keeper, contact_voltage=contact)
        elif r.motion == "vertical":
            controller = VerticalController(self.limits, r.speed_rpm, finger, r.timeout_s, keeper, contact)
        else:
            controller = HoldController(self.limits, r.speed_rpm, finger, r.timeout_s, force_keeper=keeper,
                                        contact_voltage=contact)
        self.monitor.set_k(r.k)
        return self._start(MANIPULATE, controller, self.manipulate_streams(r)[1], now_ns)

    def start_gripper(self, req: GripperRequest, now_ns: int) -> list:
        r: GripperRequest = self._startable(GRIPPER, self.resolve_gripper(req))
        c = self.config
        pads, force_pads = self.gripper_streams()
        controller = GripperController(self.limits, r.position, r.max_effort, pads, c.gripper_speed_rpm,
                                       c.gripper_thumb_ratio, c.gripper_timeout)
        return self._start(GRIPPER, controller, force_pads, now_ns)

    def _start(self, kind: str, controller: Controller, force_fingers: tuple[str, ...], now_ns: int) -> list:
        self.controller, self.kind, self._force_fingers = controller, kind, force_fingers
        self._required = frozenset({("taxels", f) for f in controller.fingers} |
                                   {("wrench", f) for f in force_fingers})
        self.aligner.reset()
        self.watchdog.arm(now_ns)
        assert self.joints is not None  # _startable refused the goal without them
        return self._actions(controller.start(self.joints), now_ns)

    def _end(self) -> None:
        self.controller, self.kind = None, None
        self.watchdog.disarm()
        self.lease.release()
        self.monitor.set_k(self.k_parameter)

    # ---- inputs ----------------------------------------------------------------------------
    def on_taxels(self, finger: str, stamp_ns: int, voltages: np.ndarray,
                  receipt_ns: int) -> tuple[ContactEvaluation, list]:
        evaluation = self.monitor.evaluate(finger, stamp_ns, voltages)
        self.evaluations[finger] = evaluation
        self.watchdog.sample(f"taxels/{finger}", stamp_ns, receipt_ns)
        if self.controller is None:
            return evaluation, []
        self.aligner.add(("taxels", finger), stamp_ns, evaluation)
        return evaluation, self._try_step(receipt_ns)

    def on_wrench(self, finger: str, stamp_ns: int, normal_force_n: float, receipt_ns: int) -> list:
        self.forces[finger] = normal_force_n
        self.watchdog.sample(f"wrench/{finger}", stamp_ns, receipt_ns)
        if self.controller is None:
            return []
        self.aligner.add(("wrench", finger), stamp_ns, normal_force_n)
        return self._try_step(receipt_ns)

    def on_joints(self, sample: JointSample, receipt_ns: int) -> list:
        """A /joint_states message. One without a position for every hand motor (another driver's
        joints, empty arrays) is ignored: it moves no time base and changes no decision."""
        motors = self.config.motor_names
        missing = [m for m in motors if m not in sample.positions]
        if missing:
            self.ignored_joint_states += 1
            return [Ignored("/joint_states", f"no position for {', '.join(missing)} "
                                             f"(joints {sorted(sample.positions)}); not the hand's motor driver")]
        self.joints = JointSample(sample.stamp_ns, {m: sample.positions[m] for m in motors},
                                  {m: sample.velocities[m] for m in motors if m in sample.velocities},
                                  {m: sample.currents[m] for m in motors if m in sample.currents})
        self.watchdog.reference(sample.stamp_ns, receipt_ns)
        return self.check(receipt_ns)

    def check(self, now_ns: int) -> list:
        """Watchdog tick: stale data aborts the goal with sensor_stale and stops the motors; a
        running motor command is re-sent when due (MoveLease)."""
        if self.controller is None:
            return []
        streams = [f"taxels/{f}" for f in self.controller.fingers] + [f"wrench/{f}" for f in self._force_fingers]
        stale = self.watchdog.check(streams, now_ns)
        if stale is not None:
            self.stale_reason = stale
            return self._abort(now_ns, SENSOR_STALE, stale)
        refresh = self.lease.refresh(now_ns)
        return [refresh] if refresh is not None else []

    def cancel(self, now_ns: int) -> list:
        if self.controller is None:
            return []
        return self._abort(now_ns, CANCELED)

    def on_move_result(self, reason: str, now_ns: int) -> list:
        """Result of our current MoveMotors goal: a motor fault, or the driver refusing the goal
        (its bus down), ends the goal with motor_fault; a timeout (the refresh came too late) sends
        the command again; at a joint limit the driver stopped the motors, so the command is no
        longer refreshed (the controller ends on the position it sees)."""
        if self.controller is None:
            return []
        if reason.startswith(MOTOR_FAULT) or refusal_code(reason) is not None:
            return self._abort(now_ns, MOTOR_FAULT, reason)
        if reason == TIMEOUT:
            renewed = self.lease.renew(now_ns)
            return [renewed] if renewed is not None else []
        if reason == JOINT_LIMIT:
            self.lease.release()
        return []

    # ---- internals -------------------------------------------------------------------------
    def _running(self) -> tuple[Controller, str]:
        """The running goal's controller and kind (callers check that one runs)."""
        if self.controller is None or self.kind is None:
            raise RuntimeError("no goal is running")
        return self.controller, self.kind

    def _abort(self, now_ns: int, reason: str, detail: str = "") -> list:
        return self._actions(self._running()[0].abort(now_ns, reason), now_ns, detail)

    def _try_step(self, now_ns: int) -> list:
        ready = self.aligner.ready(self._required)
        if ready is None or self.joints is None:
            return []
        controller = self._running()[0]
        stamp, entries = ready
        contacts = {f: entries[("taxels", f)] for f in controller.fingers}
        forces = dict(self.forces)
        forces.update({f: entries[("wrench", f)] for f in self._force_fingers})
        return self._actions(controller.step(ControlInput(stamp, contacts, forces, self.joints)), now_ns)

    def _forces(self) -> tuple[float, float]:
        c = self.controller
        if isinstance(c, GraspController):
            return c.finger_force, c.thumb_force
        return self.forces.get("index", 0.0), self.forces.get("thumb", 0.0)

    def _actions(self, out: ControlOutput, now_ns: int, detail: str = "") -> list:
        c, kind = self._running()
        actions: list = []
        if out.command is not None:
            actions.append(self.lease.command(out.command.velocities_rpm, now_ns))
        finger_force, thumb_force = self._forces()
        feasible = getattr(c, "feasible", False)
        threshold = getattr(c, "threshold", 0.0)
        gripper: dict[str, Any] = {}
        if isinstance(c, GripperController):
            gripper = {"position": c.position, "effort": c.effort, "stalled": c.stalled,
                       "reached_goal": c.reached_goal}
        actions.append(Feedback(kind, out.phase, finger_force, thumb_force, feasible, threshold, **gripper))
        if out.done:
            stop_time = 0.0
            if c.stop_ns is not None and c.start_ns is not None:
                stop_time = (c.stop_ns - c.start_ns) * 1e-9
            actions.append(Finished(kind, out.success, out.reason or "", stop_time, finger_force, thumb_force, detail,
                                    **gripper))
            self._end()
        return actions
