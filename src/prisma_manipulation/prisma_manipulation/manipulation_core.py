"""What the manipulation node decides, without ROS: goal validation, one controller at a time,
stepping it once per sensor scan, the watchdog, and the motor commands that result.

The node feeds it messages (taxels, wrenches, joint states, MoveMotors results, cancel requests,
watchdog ticks) as plain data and carries out the returned actions:
- SendMove: send a MoveMotors velocity goal (it preempts the previous one on the motor driver);
- StopMotors: cancel the running MoveMotors goal (cancel = stop);
- Feedback / Finished: the Grasp or Manipulate goal's feedback and end.
ContactState for every finger on every sample comes from `on_taxels` whether or not a goal runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .contact_monitor import ContactEvaluation, ContactMonitor, check_k
from .controllers import (
    CANCELED,
    MOTOR_FAULT,
    SENSOR_STALE,
    ControlInput,
    ControlLimits,
    ControlOutput,
    Controller,
    JointSample,
)
from .grasp_controller import GRASP_PRESETS, GraspController
from .motion_controllers import ForceKeeper, HoldController, HorizontalController, VerticalController
from .node_config import ManipulationConfig
from .sample_alignment import SampleAligner
from .watchdog import SensorWatchdog

GRASP = "grasp"
MANIPULATE = "manipulate"
MOTIONS = ("horizontal", "vertical", "hold")


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
class SendMove:
    velocities_rpm: dict[str, float]
    timeout_s: float


@dataclass(frozen=True)
class StopMotors:
    pass


@dataclass(frozen=True)
class Feedback:
    kind: str
    phase: str
    finger_force: float
    thumb_force: float
    feasible: bool
    threshold: float


@dataclass(frozen=True)
class Finished:
    kind: str
    success: bool
    reason: str
    stop_time_s: float  # from goal start to the stop (0 when it never stopped on its own)
    finger_force: float
    thumb_force: float
    detail: str = ""


def _finite(x: float) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


class ManipulationCore:
    def __init__(self, config: ManipulationConfig) -> None:
        self.config = config
        self.monitor = ContactMonitor(config.k, config.min_mean_voltage)
        self.k_parameter = config.k
        self.limits = ControlLimits(config.limits_motors(), config.limit_margin)
        self.watchdog = SensorWatchdog(int(round(config.stale_timeout * 1e9)))
        self.aligner = SampleAligner()
        self.controller: Controller | None = None
        self.kind: str | None = None
        self.joints: JointSample | None = None
        self.forces: dict[str, float] = {}
        self._force_fingers: tuple[str, ...] = ()
        self._required: frozenset = frozenset()
        self.stale_reason = ""

    # ---- parameters ------------------------------------------------------------------------
    def set_k(self, k: float) -> None:
        """The k parameter changed: applies from the next sample (also during a goal)."""
        self.monitor.set_k(check_k(k))
        self.k_parameter = self.monitor.k

    @property
    def busy(self) -> bool:
        return self.controller is not None

    # ---- goal validation -------------------------------------------------------------------
    def _common_checks(self) -> str | None:
        if self.busy:
            return f"a {self.kind} goal is running"
        if self.joints is None:
            return "no /joint_states received yet"
        return None

    def resolve_grasp(self, req: GraspRequest) -> tuple[GraspRequest | None, str | None]:
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
        return r, self._common_checks()

    def resolve_manipulate(self, req: ManipulateRequest) -> tuple[ManipulateRequest | None, str | None]:
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
        return r, self._common_checks()

    # ---- goal start / end ------------------------------------------------------------------
    def start_grasp(self, req: GraspRequest, now_ns: int) -> list:
        r, reason = self.resolve_grasp(req)
        if reason:
            raise ValueError(reason)
        c = self.config
        controller = GraspController(self.limits, r.grasp, r.finger_force, r.thumb_force, r.speed_rpm,
                                     r.timeout_s, c.contact_force_n, c.lateral_closure)
        return self._start(GRASP, controller, ("thumb",) + controller.preset.force_fingers, now_ns)

    def start_manipulate(self, req: ManipulateRequest, now_ns: int) -> list:
        r, reason = self.resolve_manipulate(req)
        if reason:
            raise ValueError(reason)
        c = self.config
        keeper = ForceKeeper(c.force_target_n, c.force_band_n, c.force_speed_rpm) if r.use_force else None
        finger = c.monitored_finger
        if r.motion == "horizontal":
            controller = HorizontalController(self.limits, r.speed_rpm, finger, timeout_s=r.timeout_s,
                                              force_keeper=keeper)
        elif r.motion == "vertical":
            controller = VerticalController(self.limits, r.speed_rpm, finger, r.timeout_s, keeper)
        else:
            controller = HoldController(self.limits, r.speed_rpm, finger, r.timeout_s, force_keeper=keeper)
        self.monitor.set_k(r.k)
        return self._start(MANIPULATE, controller, ("thumb",) if r.use_force else (), now_ns)

    def _start(self, kind: str, controller: Controller, force_fingers: tuple[str, ...], now_ns: int) -> list:
        self.controller, self.kind, self._force_fingers = controller, kind, force_fingers
        self._required = frozenset({("taxels", f) for f in controller.fingers} |
                                   {("wrench", f) for f in force_fingers})
        self.aligner.reset()
        self.watchdog.arm(now_ns)
        return self._actions(controller.start(self.joints))

    def _end(self) -> None:
        self.controller, self.kind = None, None
        self.watchdog.disarm()
        self.monitor.set_k(self.k_parameter)

    # ---- inputs ----------------------------------------------------------------------------
    def on_taxels(self, finger: str, stamp_ns: int, voltages: np.ndarray, receipt_ns: int) -> tuple[ContactEvaluation, list]:
        evaluation = self.monitor.evaluate(finger, stamp_ns, voltages)
        self.watchdog.sample(f"taxels/{finger}", stamp_ns, receipt_ns)
        if self.controller is None:
            return evaluation, []
        self.aligner.add(("taxels", finger), stamp_ns, evaluation)
        return evaluation, self._try_step()

    def on_wrench(self, finger: str, stamp_ns: int, normal_force_n: float, receipt_ns: int) -> list:
        self.forces[finger] = normal_force_n
        self.watchdog.sample(f"wrench/{finger}", stamp_ns, receipt_ns)
        if self.controller is None:
            return []
        self.aligner.add(("wrench", finger), stamp_ns, normal_force_n)
        return self._try_step()

    def on_joints(self, sample: JointSample, receipt_ns: int) -> list:
        self.joints = sample
        self.watchdog.reference(sample.stamp_ns, receipt_ns)
        return self.check(receipt_ns)

    def check(self, now_ns: int) -> list:
        """Watchdog tick: stale data aborts the goal with sensor_stale and stops the motors."""
        if self.controller is None:
            return []
        streams = [f"taxels/{f}" for f in self.controller.fingers] + [f"wrench/{f}" for f in self._force_fingers]
        stale = self.watchdog.check(streams, now_ns)
        if stale is None:
            return []
        self.stale_reason = stale
        return self._abort(now_ns, SENSOR_STALE, stale)

    def cancel(self, now_ns: int) -> list:
        if self.controller is None:
            return []
        return self._abort(now_ns, CANCELED)

    def on_move_result(self, reason: str, now_ns: int) -> list:
        """Result of our current MoveMotors goal: a motor fault ends the goal."""
        if self.controller is not None and reason.startswith(MOTOR_FAULT):
            return self._abort(now_ns, MOTOR_FAULT, reason)
        return []

    # ---- internals -------------------------------------------------------------------------
    def _abort(self, stamp_ns: int, reason: str, detail: str = "") -> list:
        return self._actions(self.controller.abort(stamp_ns, reason), detail)

    def _try_step(self) -> list:
        ready = self.aligner.ready(self._required)
        if ready is None or self.joints is None:
            return []
        stamp, entries = ready
        contacts = {f: entries[("taxels", f)] for f in self.controller.fingers}
        forces = dict(self.forces)
        forces.update({f: entries[("wrench", f)] for f in self._force_fingers})
        return self._actions(self.controller.step(ControlInput(stamp, contacts, forces, self.joints)))

    def _forces(self) -> tuple[float, float]:
        c = self.controller
        if isinstance(c, GraspController):
            return c.finger_force, c.thumb_force
        return self.forces.get("index", 0.0), self.forces.get("thumb", 0.0)

    def _actions(self, out: ControlOutput, detail: str = "") -> list:
        c = self.controller
        actions: list = []
        if out.command is not None:
            if out.command.is_stop:
                actions.append(StopMotors())
            else:
                elapsed = (out.stamp_ns - c.start_ns) * 1e-9 if c.start_ns is not None else 0.0
                # the motor driver stops on its own if we vanish: a little after our own timeout
                timeout = max(0.0, c.timeout_ns * 1e-9 - elapsed) + 1.0 if c.timeout_ns else 0.0
                actions.append(SendMove(dict(out.command.velocities_rpm), timeout))
        finger_force, thumb_force = self._forces()
        feasible = getattr(c, "feasible", False)
        threshold = getattr(c, "threshold", 0.0)
        actions.append(Feedback(self.kind, out.phase, finger_force, thumb_force, feasible, threshold))
        if out.done:
            stop_time = (c.stop_ns - c.start_ns) * 1e-9 if c.stop_ns is not None else 0.0
            actions.append(Finished(self.kind, out.success, out.reason, stop_time, finger_force, thumb_force, detail))
            self._end()
        return actions
