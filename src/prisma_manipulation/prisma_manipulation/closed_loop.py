"""ROS-free closed loop: the hand's node cores on simulated hardware, one scan per period.

The same decision code as the launched graph, in the order the graph delivers its messages, with
explicit stamps. Per scan at t_k:
1. the motor driver's core (`MotorDriverCore` on the sim motors) ticks: the joint sample, the running
   MoveMotors goal's feedback, and its result when it ended (timeout, joint limit, fault), which goes
   to the manipulation core as the node's MoveMotors client hands it over;
2. the world moves to the motor positions and loads the motors;
3. the manipulation core (`ManipulationCore`, the manipulation node's) takes the joint sample;
4. the tactile driver's core (`TactileHub`) reads its sim backend (`SimHubBackend`, the world as its
   contact source: one `PadModel` per finger) into taxel frames, and the manipulation core takes
   each (Algorithm 1, a controller step when due);
5. the force estimator's core (`WrenchPipeline`) turns the frames into wrenches when an estimator is
   given, and the manipulation core takes each normal force; without one it takes the world's
   force on each pad (ground truth).
The manipulation core's decisions are carried out as the node does: SendMove starts a MoveMotors
velocity goal on the motor driver's core (preempting the last), StopMotors cancels it; Feedback and
Finished end up in the `Scan` each period hands to `observer` (the bag recorder) and in the `Trace`.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_force_estimator.force_estimator_core import TaxelSample, WrenchPipeline
from prisma_force_estimator.node_config import ForceEstimatorConfig
from prisma_hand_sim.contact_source import HandWorldContactSource
from prisma_hand_sim.hand_world import HandWorld
from prisma_hand_sim.pad_model import PadParams
from prisma_motor_driver.backend import MotorState
from prisma_motor_driver.motor_driver_core import MotorDriverCore
from prisma_motor_driver.motor_goals import MoveFeedback, MoveResult
from prisma_motor_driver.node_config import MotorDriverConfig
from prisma_motor_driver.ros_conversions import velocity_goal
from prisma_motor_driver.sim_backend import SimMotorBus
from prisma_tactile_driver.sim_backend import SimHubBackend
from prisma_tactile_driver.tactile_driver_core import TactileHub
from prisma_tactile_driver.taxels import TaxelFrame

from .contact_monitor import ContactEvaluation
from .controllers import Controller, JointSample
from .goal_kind import GoalKind
from .goal_kinds import GOAL_KINDS
from .manipulation_core import ActionHandlers, Finished, ManipulationCore, SendMove, StopMotors
from .node_config import ManipulationConfig

if TYPE_CHECKING:
    from prisma_force_estimator.force_estimator_core import WrenchSample
    from prisma_force_estimator.inference import ForceEstimator

NS = 1_000_000_000
FRAME_ID_FORMAT = "prisma_{finger}_pad"  # tactile_driver's and force_estimator's default frame ids


@dataclass
class Trace:
    period_ns: int
    stamps_ns: list[int] = field(default_factory=list)
    voltages: list[np.ndarray] = field(default_factory=list)  # [5, 9] per sample
    thresholds: list[np.ndarray] = field(default_factory=list)  # [5]
    lost_edges: list[dict[str, tuple[str, ...]]] = field(default_factory=list)
    forces_true: list[np.ndarray] = field(default_factory=list)  # [5] on each pad
    forces_used: list[np.ndarray] = field(default_factory=list)  # [5] what the manipulation core got
    positions: list[np.ndarray] = field(default_factory=list)  # [3] MOTOR_NAMES order
    commands: list[np.ndarray] = field(default_factory=list)  # [3] rpm in force after this sample
    contact_xy: list[np.ndarray] = field(default_factory=list)  # [5, 2] (nan = no contact)
    phases: list[str] = field(default_factory=list)
    done_index: int | None = None

    def array(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name))

    def finger_voltages(self, finger: str) -> np.ndarray:
        return self.array("voltages")[:, FINGERS.index(finger), :]

    def force(self, finger: str, which: str = "true") -> np.ndarray:
        return self.array(f"forces_{which}")[:, FINGERS.index(finger)]

    def position(self, motor: str) -> np.ndarray:
        return self.array("positions")[:, MOTOR_NAMES.index(motor)]

    def index_of(self, stamp_ns: int) -> int:
        return self.stamps_ns.index(stamp_ns)


@dataclass
class Scan:
    """Everything the graph's nodes received and decided in one period (for the bag recorder)."""

    stamp_ns: int
    states: dict[str, MotorState]
    frames: list[TaxelFrame]
    evaluations: dict[str, ContactEvaluation]
    wrenches: dict[str, WrenchSample]
    forces: dict[str, float] = field(default_factory=dict)  # the normal force handed to the core per finger
    move_feedback: MoveFeedback | None = None  # the running MoveMotors goal's, this tick
    move_result: MoveResult | None = None  # the MoveMotors goal that ended by itself this tick
    goal_started: bool = False  # the goal was sent (and accepted) at this scan, before `actions`
    actions: list = field(default_factory=list)  # the manipulation core's decisions, in order
    inputs: list = field(default_factory=list)  # goal kinds' extra inputs received: (stream, stamp_ns, value)


class ClosedLoop:
    def __init__(
        self,
        world: HandWorld,
        estimator: ForceEstimator | None = None,
        config: ManipulationConfig | None = None,
        rate_hz: float = 100.0,
        pad_params: PadParams | None = None,
        seed: int = 0,
        observer: Callable[[Scan], Any] | None = None,
        kinds: tuple[GoalKind, ...] = GOAL_KINDS,
    ) -> None:
        """`kinds`: the goal kinds its manipulation core serves (a test adds one to GOAL_KINDS)."""
        self.world = world
        self.period_ns = int(round(1e9 / rate_hz))
        self.observer = observer
        self.core = ManipulationCore(config or ManipulationConfig(), kinds)
        motor_config = MotorDriverConfig(backend="sim")
        # the motors' clock starts at the first scan, whatever its stamp
        self.bus = SimMotorBus(motor_config.motors(), initial_positions=world.positions, start_ns=None)
        self.motor = MotorDriverCore(motor_config, self.bus)
        self.motor.connect(0)
        # the tactile driver's sim backend (contact_source hand_world) on this loop's world
        self.contacts = HandWorldContactSource(world)
        self.hub = TactileHub(SimHubBackend(self.contacts, FINGERS, pad_params, seed), FINGERS,
                              name="tactile_driver", hardware_id="sim/hand_world")
        self.estimator = estimator
        self.pipeline = None
        if estimator is not None:
            batch_window_ns = int(round(ForceEstimatorConfig().batch_window * NS))
            self.pipeline = WrenchPipeline({f: estimator for f in FINGERS}, FRAME_ID_FORMAT, batch_window_ns)
        self.controller: Controller | None = None  # the goal's controller, kept after it ends
        self.finished: Finished | None = None
        self._stamp_ns = 0  # the scan whose decisions are being carried out
        # as the node carries them out, on the sim motor driver's core (the rest is only recorded)
        self._handlers = ActionHandlers(send_move=self._send_move, stop_motors=self._stop_motors,
                                        finished=self._finished)

    # ---- one scan --------------------------------------------------------------------------
    def scan(self, stamp_ns: int, inputs: Iterable[tuple[str, int, Any]] = ()) -> tuple[Scan, np.ndarray, np.ndarray]:
        """One period at stamp_ns: (the scan, the pads' voltages [5, 9], the normal forces the
        manipulation core got [5]). `inputs`: a goal kind's extra input samples (stream, stamp_ns,
        value) received since the last scan (a glove's targets), handed to the core first, as the
        node's subscription would. The decisions are carried out before it returns."""
        tick = self.motor.tick(stamp_ns)
        states = tick.states or {}
        joints = JointSample(stamp_ns, {n: s.position_rad for n, s in states.items()},
                             {n: s.velocity_rpm for n, s in states.items()},
                             {n: s.current_ma for n, s in states.items()})
        scan = Scan(stamp_ns, states, [], {}, {}, move_feedback=tick.feedback, move_result=tick.result,
                    inputs=list(inputs))
        for stream, sample_ns, value in scan.inputs:
            self._carry_out(self.core.on_input(stream, sample_ns, value, stamp_ns), scan)
        if tick.result is not None:
            self._carry_out(self.core.on_move_result(tick.result.reason, stamp_ns), scan)
        self.contacts.update_joints(list(joints.positions), list(joints.positions.values()), stamp_ns)
        self.bus.set_loads(self.world.motor_loads())
        self._carry_out(self.core.on_joints(joints, stamp_ns), scan)

        scan.frames = self.hub.poll(stamp_ns)
        for frame in scan.frames:
            evaluation, actions = self.core.on_taxels(frame.finger, frame.stamp_ns, frame.voltages, stamp_ns)
            scan.evaluations[frame.finger] = evaluation
            self._carry_out(actions, scan)
        by_finger = {frame.finger: frame for frame in scan.frames}
        volts = np.stack([np.asarray(by_finger[f].voltages, dtype=np.float64) for f in FINGERS])

        used = np.full(len(FINGERS), np.nan)
        if self.pipeline is None:
            truth = self.world.forces()
            forces = {(f.finger, f.stamp_ns): truth[f.finger] for f in scan.frames}
        else:
            forces = {}
            for frame in scan.frames:
                frame_id = FRAME_ID_FORMAT.format(finger=frame.finger)
                sample = TaxelSample(frame.finger, frame.stamp_ns, frame.voltages, frame_id)
                for finger, wrench in self.pipeline.add(sample):
                    scan.wrenches[finger] = wrench
                    forces[(finger, wrench.stamp_ns)] = float(wrench.wrench[2])  # +Fz presses the pad
        for (finger, sample_ns), force in forces.items():
            used[FINGERS.index(finger)] = force
            scan.forces[finger] = force
            self._carry_out(self.core.on_wrench(finger, sample_ns, force, stamp_ns), scan)
        return scan, volts, used

    def _carry_out(self, actions: list, scan: Scan) -> None:
        self._stamp_ns = scan.stamp_ns
        self._handlers.carry_out(actions)
        scan.actions.extend(actions)

    def _send_move(self, action: SendMove) -> None:
        self.motor.start(velocity_goal(action.velocities_rpm, action.timeout_s, self._stamp_ns), self._stamp_ns)

    def _stop_motors(self, action: StopMotors) -> None:
        self.motor.cancel()  # as on the node, the canceled goal's result changes no decision

    def _finished(self, action: Finished) -> None:
        self.finished = action

    # ---- a goal ----------------------------------------------------------------------------
    def start(self, request: Any, scan: Scan) -> None:
        """Send the goal at the scan's stamp as a client would: refused (RuntimeError naming why)
        where the manipulation node would refuse it."""
        core, t = self.core, scan.stamp_ns
        refusal = core.accept(request, True, t)
        if refusal is not None:
            raise RuntimeError(f"the manipulation node would refuse the goal at {t * 1e-9:.2f} s: {refusal}")
        scan.goal_started = True
        actions = core.start(request, t)
        self.controller = core.controller
        self._carry_out(actions, scan)

    def run(self, request: Any, duration_s: float, start_ns: int = 0,
            settle_s: float = 0.0, progress: Callable[[str], None] | None = None) -> Trace:
        """Scan once, send the goal, and scan on until it has finished (then `settle_s` more) or
        `duration_s` has passed."""
        trace = Trace(self.period_ns)
        n_max = int(round(duration_s * 1e9 / self.period_ns))
        settle_left = int(round(settle_s * 1e9 / self.period_ns))
        self.finished = None
        scan, _, _ = self.scan(start_ns)
        self.start(request, scan)
        self._observe(scan)
        controller = self.controller
        assert controller is not None  # start() raised for a goal that did not start
        phase = controller.phase
        for k in range(1, n_max + 1):
            t = start_ns + k * self.period_ns
            was_done = self.finished is not None
            scan, volts, used = self.scan(t)
            self._observe(scan)
            if was_done:
                settle_left -= 1
            elif self.finished is not None:
                trace.done_index = len(trace.stamps_ns)
            if progress and controller.phase != phase:
                progress(f"t={t * 1e-9:.2f}s phase {phase} -> {controller.phase}")
            phase = controller.phase
            self._record(trace, scan, volts, used, controller)
            if self.finished is not None and settle_left <= 0:
                break
        return trace

    def _observe(self, scan: Scan) -> None:
        if self.observer is not None:
            self.observer(scan)

    def _record(self, trace: Trace, scan: Scan, volts: np.ndarray, used: np.ndarray, controller: Controller) -> None:
        trace.stamps_ns.append(scan.stamp_ns)
        trace.voltages.append(volts)
        trace.thresholds.append(np.array([scan.evaluations[f].threshold for f in FINGERS]))
        trace.lost_edges.append({f: scan.evaluations[f].lost_edges for f in FINGERS})
        truth = self.world.forces()
        trace.forces_true.append(np.array([truth[f] for f in FINGERS]))
        trace.forces_used.append(used)
        trace.positions.append(np.array([scan.states[m].position_rad for m in MOTOR_NAMES]))
        trace.commands.append(np.array([controller.command.velocities_rpm[m] for m in MOTOR_NAMES]))
        xy = np.full((len(FINGERS), 2), np.nan)
        for i, f in enumerate(FINGERS):
            c = self.world.contact(f)
            if c is not None:
                xy[i] = (c.x_mm, c.y_mm)
        trace.contact_xy.append(xy)
        trace.phases.append(controller.phase)
