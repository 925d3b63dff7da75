"""One hand scenario of the paper (docs/manipulation.md), run in the ROS-free closed loop and recorded as the ROS
graph would publish it.

The closed loop (`prisma_manipulation.closed_loop.ClosedLoop`) composes the sim motors, the
hand/world model, one optical pad model per finger, Algorithm 1 and a controller. `HandRecorder`
attaches to it without changing what it computes and, on every sample, turns what the nodes would
see into the messages the nodes would publish, with the nodes' own cores and converters:

- taxels: `TactileHub` (the tactile_driver's core) reading the pads' counts -> `taxel_frame_to_msg`;
- wrench: `WrenchPipeline` (the force_estimator's core) with the default bundle -> `wrench_to_msg`.
  Its Fz is also the normal force the controller uses, as on the robot;
- contact: `ContactMonitor` with the manipulation node's parameters -> `contact_state_to_msg`;
- /joint_states from the motor states -> `joint_state_to_msg`;
- Grasp / Manipulate feedback after every controller step (`<action>/_action/feedback`), MoveMotors
  feedback on every sample while a velocity goal runs, and every goal's status changes
  (`<action>/_action/status`), as an action server publishes them. The MoveMotors goals are the
  manipulation node's own decisions (`manipulation_core.MoveLease`): one per new velocity command,
  re-sent every 0.1 s while the command holds (each preempting the last), a cancel for a stop;
- the goal starts only where the manipulation node would accept it: every stream it needs fresh
  (`SensorWatchdog.fresh`, as `ManipulationCore.readiness` asks), else the recording fails;
- /diagnostics once per second from each driver's core (tactile hub, estimator pipeline, motor
  driver).
Stamps are the loop's sample stamps (sim time from 0), so every topic is ordered in time.
"""
from __future__ import annotations

import uuid
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from prisma_force_estimator.diagnostics import pipeline_diagnostics
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.node_config import EstimatorConfig
from prisma_force_estimator.pipeline import TaxelSample, WrenchPipeline
from prisma_force_estimator.ros_conversions import wrench_to_msg
from prisma_manipulation.contact_monitor import ContactMonitor
from prisma_manipulation.controllers import ControlInput, ControlOutput, JointSample
from prisma_manipulation.grasp_controller import GraspController
from prisma_manipulation.manipulation_core import Feedback, MoveLease, SendMove
from prisma_manipulation.motor_bus import MOTOR_NAMES, MotorState
from prisma_manipulation.motor_driver_core import MotorDriverCore
from prisma_manipulation.motor_goals import MoveFeedback
from prisma_manipulation.node_config import ManipulationConfig, MotorDriverConfig
from prisma_manipulation.watchdog import SensorWatchdog
from prisma_manipulation.ros_conversions import (
    contact_state_to_msg,
    grasp_feedback_to_msg,
    joint_state_to_msg,
    manipulate_feedback_to_msg,
    move_feedback_to_msg,
)
from prisma_manipulation.scenarios import DEFAULT_K, Scenario, build
from prisma_tactile_driver.backend import HubReading
from prisma_tactile_driver.driver_config import DriverConfig
from prisma_tactile_driver.hub import TactileHub
from prisma_tactile_driver.ros_conversions import diagnostics_to_msg, stamp_from_ns, taxel_frame_to_msg
from prisma_tactile_driver.taxels import FINGERS

from .bag import BagWriter
from .typestore import types as typestore_types

NS = 1_000_000_000
DIAGNOSTICS_PERIOD_NS = NS  # every driver's diagnostics_period default (1 s)

# action_msgs/msg/GoalStatus
STATUS_EXECUTING, STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 2, 4, 5, 6

# default topic names (docs/architecture.md, Topic table)
TAXELS, WRENCH, CONTACT = "/prisma/{finger}/taxels", "/prisma/{finger}/wrench", "/prisma/{finger}/contact"
JOINT_STATES, DIAGNOSTICS = "/joint_states", "/diagnostics"
ACTIONS = {"grasp": "/prisma/grasp", "manipulate": "/prisma/manipulate", "move": "/prisma/motors/move"}
ACTION_TYPES = {"grasp": "prisma_msgs/action/Grasp", "manipulate": "prisma_msgs/action/Manipulate",
                "move": "prisma_msgs/action/MoveMotors"}


def feedback_topic(action: str) -> str:
    return f"{ACTIONS[action]}/_action/feedback"


def status_topic(action: str) -> str:
    return f"{ACTIONS[action]}/_action/status"


# ------------------------------------------------------------------------------------------------
# The scenarios prisma-sim runs


@dataclass(frozen=True)
class HandScenarioSpec:
    name: str
    action: str  # "grasp" | "manipulate": the goal the scenario stands for
    goal: dict  # that goal's fields (the controller runs exactly these settings)
    world: str  # the prisma_manipulation scenario it runs: its world (scenario_world) and controller
    description: str

    def make(self) -> Scenario:
        return replace(build(self.world), name=self.name)


HAND_SCENARIOS: dict[str, HandScenarioSpec] = {
    spec.name: spec for spec in (
        HandScenarioSpec(
            "pinch_grasp", "grasp",
            {"grasp": "pinch", "finger_force": 0.8, "thumb_force": 1.0, "speed_rpm": 60.0, "timeout": 10.0},
            "grasp",
            "foam ball on a stand; fingers close at 60 rpm to 0.8 N on the index pad, then the thumb "
            "flexes at 60 rpm to 1 N (estimated Fz)"),
        HandScenarioSpec(
            "lateral_grasp", "grasp",
            {"grasp": "lateral", "finger_force": 0.8, "thumb_force": 1.0, "speed_rpm": 60.0, "timeout": 10.0},
            "lateral",
            "card against the side of the index: fingers close to the lateral fist, thumb flexes at "
            "60 rpm to 1 N (estimated Fz)"),
        HandScenarioSpec(
            "horizontal", "manipulate",
            {"motion": "horizontal", "speed_rpm": 20.0, "k": DEFAULT_K, "use_force": False, "timeout": 10.0},
            "horizontal",
            "ball pinched at 1 N; thumb rotates clockwise at 20 rpm until the right taxels 6-3-0 are "
            "lost, then back to the start angle"),
        HandScenarioSpec(
            "vertical", "manipulate",
            {"motion": "vertical", "speed_rpm": 10.0, "k": DEFAULT_K, "use_force": False, "timeout": 15.0},
            "vertical",
            "ball pinched at 1 N; fingers close + thumb extends at 10 rpm until the top row 6-7-8 is "
            "lost, then the reverse until the bottom row 0-1-2 is lost"),
        HandScenarioSpec(
            "disturbance", "manipulate",
            {"motion": "hold", "speed_rpm": 20.0, "k": DEFAULT_K, "use_force": False, "timeout": 3.0},
            "disturbance",
            "ball pinched; at 0.5 s a push slips it 4 mm toward the thumb pad's right side; the thumb "
            "rotates at 20 rpm until two left taxels are back above v_t"),
        HandScenarioSpec(
            "combined", "manipulate",
            {"motion": "hold", "speed_rpm": 20.0, "k": DEFAULT_K, "use_force": True, "timeout": 3.0},
            "combined",
            "as disturbance, and the object slips to a narrower section: the estimated thumb force "
            "is restored to 1 N while the voltages steer the rotation"),
    )
}


# ------------------------------------------------------------------------------------------------
# Recording


class _RecordingPad:
    """Delegates to a PadModel and keeps the counts of its latest sample."""

    def __init__(self, pad) -> None:
        self.pad = pad
        self.counts: np.ndarray | None = None

    def sample(self, contact):
        self.counts = self.pad.sample(contact)
        return self.counts


class _ScanBackend:
    """HubBackend serving the pads' latest counts: the tactile hub core reads the closed loop's pads
    as the sim backend reads its own."""

    def __init__(self, pads: dict[str, _RecordingPad]) -> None:
        self.pads = pads
        self.scans = 0

    def read(self, stamp_ns: int) -> list[HubReading]:
        self.scans += 1
        return [HubReading(self.scans - 1, {f: p.counts for f, p in self.pads.items() if p.counts is not None})]

    def counters(self) -> dict[str, int]:
        return {"scans": self.scans}

    def close(self) -> None:
        pass


def _goal_uuid(*parts: object) -> np.ndarray:
    """Deterministic goal id (same run -> same bag)."""
    name = "/".join(str(p) for p in parts)
    return np.frombuffer(uuid.uuid5(uuid.NAMESPACE_URL, f"prisma-sim:{name}").bytes, dtype=np.uint8).copy()


@dataclass
class _Goal:
    action: str
    goal_id: np.ndarray
    accepted_ns: int


@dataclass
class GoalRecord:
    """One action goal as recorded: for summaries and tests."""

    action: str
    accepted_ns: int
    ended_ns: int | None = None
    status: int = STATUS_EXECUTING
    feedback: int = 0


@dataclass
class HandRecording:
    samples: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    counts: dict[str, int] = field(default_factory=dict)
    goals: list[GoalRecord] = field(default_factory=list)
    wrench_fz: list[np.ndarray] = field(default_factory=list)  # [5] per sample (what the controller used)


class HandRecorder:
    """Attach to a Scenario before `run()`; writes every message to `writer` as the loop runs."""

    def __init__(self, scenario: Scenario, writer: BagWriter, estimator: ForceEstimator, action: str,
                 types: Callable[[str], Any] = typestore_types) -> None:
        if action not in ("grasp", "manipulate"):
            raise ValueError(f"action must be grasp or manipulate, got {action!r}")
        self.scenario, self.writer, self.types, self.action = scenario, writer, types, action
        self.recording = HandRecording()
        loop, controller = scenario.loop, scenario.controller
        self.tactile_config = DriverConfig(backend="sim", contact_source="hand_world")
        self.manipulation_config = ManipulationConfig()
        estimator_config = EstimatorConfig()
        self.bundle_paths = {f: estimator.path for f in FINGERS}

        # tactile_driver core on the loop's pads
        self.pads = {f: _RecordingPad(pad) for f, pad in loop.pads.items()}
        loop.pads = self.pads
        self.hub = TactileHub(_ScanBackend(self.pads), FINGERS, vref=self.tactile_config.vref,
                              tare_samples=self.tactile_config.tare_samples,
                              stale_timeout_ns=int(self.tactile_config.stale_timeout * NS),
                              name="tactile_driver", hardware_id="sim/hand_world")
        # force_estimator core: its Fz is the controller's normal force
        self.pipeline = WrenchPipeline({f: estimator for f in FINGERS}, estimator_config.frame_id_format,
                                       int(round(estimator_config.batch_window * NS)))
        loop.force_fn = self._forces
        # the manipulation node's monitor (its min_mean_voltage decides `feasible`)
        self.monitor = ContactMonitor(loop.monitor.k, self.manipulation_config.min_mean_voltage)
        # motor_driver core on the loop's bus, for its diagnostics
        self.motor_core = MotorDriverCore(MotorDriverConfig(), bus=loop.bus)
        self.motor_core.connect(0)

        self._stamp_ns = 0
        self._next_diagnostics_ns: int | None = None
        self._wrenches: dict[str, Any] = {}
        self._goal: _Goal | None = None  # the Grasp/Manipulate goal
        self._move: _Goal | None = None  # the MoveMotors goal it is running
        self._moves = 0
        self._goal_record: GoalRecord | None = None
        self._move_record: GoalRecord | None = None
        self.lease = MoveLease()  # the manipulation node's MoveMotors decisions
        self.watchdog = SensorWatchdog(int(round(self.manipulation_config.stale_timeout * NS)))

        self._sample = loop.sample
        loop.sample = self._on_sample
        self._start, self._step = controller.start, controller.step
        controller.start = self._on_start
        controller.step = self._on_step

    # ---- loop hooks --------------------------------------------------------------------------
    def _forces(self, voltages: np.ndarray) -> np.ndarray:
        fz = np.full(len(FINGERS), np.nan)
        self._wrenches = {}
        for i, finger in enumerate(FINGERS):
            frame_id = self.tactile_config.frame_id(finger)
            for f, sample in self.pipeline.add(TaxelSample(finger, self._stamp_ns, voltages[i], frame_id)):
                self._wrenches[f] = sample
        for f, sample in self._wrenches.items():
            fz[FINGERS.index(f)] = sample.wrench[2]
        self.recording.wrench_fz.append(fz)
        return fz

    def _on_sample(self, stamp_ns: int):
        self._stamp_ns = stamp_ns
        joints, volts, evaluations, truth, used = self._sample(stamp_ns)
        self._record_sample(stamp_ns, joints)
        return joints, volts, evaluations, truth, used

    def _on_start(self, joints: JointSample) -> ControlOutput:
        c = self.scenario.controller
        force_fingers = c.fingers if isinstance(c, GraspController) else \
            ("thumb",) if getattr(c, "force_keeper", None) is not None else ()
        streams = [f"taxels/{f}" for f in c.fingers] + [f"wrench/{f}" for f in force_fingers]
        not_ready = self.watchdog.fresh(streams, joints.stamp_ns)
        if not_ready is not None:
            raise RuntimeError(f"the manipulation node would reject the {self.action} goal at "
                               f"{joints.stamp_ns * 1e-9:.2f} s: {not_ready}")
        out = self._start(joints)
        self._goal = _Goal(self.action, _goal_uuid(self.scenario.name, self.action), joints.stamp_ns)
        self._goal_record = GoalRecord(self.action, joints.stamp_ns)
        self.recording.goals.append(self._goal_record)
        self._write_status(self._goal, STATUS_EXECUTING, joints.stamp_ns)
        self._record_output(out, {})
        return out

    def _on_step(self, inp: ControlInput) -> ControlOutput:
        out = self._step(inp)
        self._record_output(out, inp.forces)
        return out

    # ---- messages ----------------------------------------------------------------------------
    def _write(self, topic: str, msg: Any, stamp_ns: int | None = None) -> None:
        self.writer.write(topic, msg, stamp_ns)
        self.recording.counts[topic] = self.recording.counts.get(topic, 0) + 1

    def _record_sample(self, t: int, joints: JointSample) -> None:
        rec = self.recording
        rec.samples += 1
        rec.first_ns = t if rec.first_ns is None else rec.first_ns
        rec.last_ns = t
        types = self.types
        states = {m: MotorState(m, joints.positions[m], joints.velocities.get(m, 0.0), joints.currents.get(m, 0.0))
                  for m in MOTOR_NAMES}
        self._write(JOINT_STATES, joint_state_to_msg(types, t, states))
        self.watchdog.reference(t, t)
        frames = {frame.finger: frame for frame in self.hub.poll(t)}
        for finger, frame in frames.items():
            self._write(TAXELS.format(finger=finger),
                        taxel_frame_to_msg(frame, types, self.tactile_config.frame_id(finger)))
            self.watchdog.sample(f"taxels/{finger}", frame.stamp_ns, t)
        for finger in FINGERS:
            sample = self._wrenches.get(finger)
            if sample is not None:
                self._write(WRENCH.format(finger=finger), wrench_to_msg(types, sample))
                self.watchdog.sample(f"wrench/{finger}", sample.stamp_ns, t)
        # the manipulation node evaluates Algorithm 1 on every taxel message, also when idle
        for finger, frame in frames.items():
            evaluation = self.monitor.evaluate(finger, frame.stamp_ns, frame.voltages)
            frame_id = self.manipulation_config.frame_id_format.format(finger=finger)
            self._write(CONTACT.format(finger=finger), contact_state_to_msg(types, evaluation, frame_id))
        if self._move is not None:  # the motor driver's feedback on every tick of a running goal
            feedback = MoveFeedback([states[m].position_rad for m in MOTOR_NAMES],
                                    [states[m].velocity_rpm for m in MOTOR_NAMES],
                                    [states[m].current_ma for m in MOTOR_NAMES])
            self._write_feedback(self._move, move_feedback_to_msg(types, feedback), t)
            self._move_record.feedback += 1
        # the node re-sends the running command on the /joint_states of this sample when it is due
        # (before the controller steps on the sample's taxels); the new goal preempts the last
        refresh = self.lease.refresh(t)
        if refresh is not None:
            self._send_move(t)
        if self._next_diagnostics_ns is None or t >= self._next_diagnostics_ns:
            self._next_diagnostics_ns = t + DIAGNOSTICS_PERIOD_NS
            self._write_diagnostics(t)

    def _write_diagnostics(self, t: int) -> None:
        types = self.types
        self._write(DIAGNOSTICS, diagnostics_to_msg(types, t, self.hub.diagnostics(t)))
        self._write(DIAGNOSTICS, diagnostics_to_msg(
            types, t, pipeline_diagnostics(self.pipeline, "force_estimator", self.bundle_paths)))
        self._write(DIAGNOSTICS, diagnostics_to_msg(types, t, self.motor_core.diagnostics()))

    def _record_output(self, out: ControlOutput, forces) -> None:
        """What the manipulation node does with a controller output: MoveMotors goals for velocity
        commands (a stop cancels the running one), feedback, and the end of the goal."""
        t = out.stamp_ns
        if out.command is not None:
            if isinstance(self.lease.command(out.command.velocities_rpm, t), SendMove):
                self._send_move(t)
            elif self._move is not None:
                self._end_move(STATUS_CANCELED, t)  # a stop cancels the running goal
        if self._goal is None:
            return
        c = self.scenario.controller
        if isinstance(c, GraspController):
            finger_force, thumb_force = c.finger_force, c.thumb_force
        else:
            finger_force, thumb_force = float(forces.get("index", 0.0)), float(forces.get("thumb", 0.0))
        feedback = Feedback(self.action, out.phase, finger_force, thumb_force,
                            bool(getattr(c, "feasible", False)), float(getattr(c, "threshold", 0.0)))
        convert = grasp_feedback_to_msg if self.action == "grasp" else manipulate_feedback_to_msg
        self._write_feedback(self._goal, convert(self.types, feedback), t)
        self._goal_record.feedback += 1
        if out.done:
            self.lease.release()
            status = STATUS_SUCCEEDED if out.success else STATUS_CANCELED if out.reason == "canceled" else STATUS_ABORTED
            self._write_status(self._goal, status, t)
            self._goal_record.ended_ns, self._goal_record.status = t, status
            self._goal = None

    def _send_move(self, t: int) -> None:
        """A MoveMotors goal (a new command or its refresh): it preempts the running one."""
        if self._move is not None:
            self._end_move(STATUS_ABORTED, t)  # preempted
        self._moves += 1
        self._move = _Goal("move", _goal_uuid(self.scenario.name, "move", self._moves), t)
        self._move_record = GoalRecord("move", t)
        self.recording.goals.append(self._move_record)
        self._write_status(self._move, STATUS_EXECUTING, t)

    def _end_move(self, status: int, t: int) -> None:
        self._write_status(self._move, status, t)
        self._move_record.ended_ns, self._move_record.status = t, status
        self._move = None

    def _write_feedback(self, goal: _Goal, feedback: Any, t: int) -> None:
        types = self.types
        msg = types(f"{ACTION_TYPES[goal.action]}_FeedbackMessage")(
            goal_id=types("unique_identifier_msgs/msg/UUID")(uuid=goal.goal_id), feedback=feedback)
        self._write(feedback_topic(goal.action), msg, t)

    def _write_status(self, goal: _Goal, status: int, t: int) -> None:
        types = self.types
        info = types("action_msgs/msg/GoalInfo")(goal_id=types("unique_identifier_msgs/msg/UUID")(uuid=goal.goal_id),
                                                 stamp=stamp_from_ns(types, goal.accepted_ns))
        msg = types("action_msgs/msg/GoalStatusArray")(
            status_list=[types("action_msgs/msg/GoalStatus")(goal_info=info, status=status)])
        self._write(status_topic(goal.action), msg, t)

    def finish(self) -> HandRecording:
        """Close open goals at the last sample (a run cut by its duration ends them aborted)."""
        t = self.recording.last_ns or 0
        if self._move is not None:
            self._end_move(STATUS_ABORTED, t)
        if self._goal is not None:
            self._write_status(self._goal, STATUS_ABORTED, t)
            self._goal_record.ended_ns, self._goal_record.status = t, STATUS_ABORTED
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
    for a in (action, "move"):
        topics[feedback_topic(a)] = f"{ACTION_TYPES[a]}_FeedbackMessage"
        topics[status_topic(a)] = "action_msgs/msg/GoalStatusArray"
    return topics

