"""The teleop node's decisions, ROS-free: glove input -> motor targets and the goals it keeps on the
manipulation node.

`GoalKeeper`: the one goal this node holds on the manipulation node (Teleoperate, Grasp or
GripperCommand; the manipulation node runs one goal at a time across all of them). Given the goal
the glove wants now, it sends it when none runs, cancels the running one when another is wanted
(and sends that one once the cancel has ended it), and after a refusal for now (`not_ready`,
`busy`) sends it again after `retry_period`. A goal that ended for good is not sent again until
something else is wanted.

`HandPoseTeleop` (input joint_states): every glove sample -> retargeting.retarget ->
TargetFilter -> the targets published on prisma/teleop/motor_targets; while engaged it keeps a
Teleoperate goal running: sent once `RESUME_SAMPLES` samples arrived since the last goal ended
(the manipulation node refuses it not_ready until the targets flow), sent again after one ended
input_stale once the glove is back; any other end (sensor_stale, motor_fault, canceled by another
client, invalid) disengages with the reason logged. Captures of the operator's poses build the
calibration (calibration.py): in use, and saved, once it is complete.

`StagTeleop` (input stag): each pose estimate with its frame's total pressure ->
stag_poses.PoseMapper -> the Grasp or the open GripperCommand to keep, while engaged.

Every method returns decisions as data (`SendGoal`, `CancelGoal`, `Note` for the log); the node
carries them out. Time is explicit (`now_ns`, the node clock).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace

from prisma_common.goal_refusal import RETRY_LATER, refusal_code

from .calibration import POSES, CalibrationError, OperatorCalibration
from .node_config import TeleopConfig
from .retargeting import MissingJoints, retarget
from .stag_poses import GraspCommand, OpenCommand, PoseMapper

NS = 1_000_000_000
RESUME_SAMPLES = 3  # glove samples since a goal ended before a new Teleoperate goal is sent
FLOWING_NS = NS // 5  # the glove counts as flowing while its last sample is younger than this
INPUT_STALE = "input_stale"
CANCELED = "canceled"


@dataclass(frozen=True)
class TeleopGoal:
    """A Teleoperate goal (0 = the manipulation node's parameter)."""

    max_pad_force: float = 0.0
    max_speed_rpm: float = 0.0
    input_timeout: float = 0.0


Command = TeleopGoal | GraspCommand | OpenCommand


@dataclass(frozen=True)
class SendGoal:
    command: Command


@dataclass(frozen=True)
class CancelGoal:
    why: str


@dataclass(frozen=True)
class Note:
    """A line for the node's log: level info, warning or error."""

    level: str
    text: str


def stop_code(reason: str) -> str:
    """The code a goal's end reason starts with: `input_stale` of `input_stale: ... silent for 160 ms`."""
    return reason.partition(":")[0].strip()


def command_key(command: Command | None) -> str | None:
    """What makes two commands the same goal: the kind, and a grasp's preset (not its forces)."""
    if command is None:
        return None
    if isinstance(command, GraspCommand):
        return f"grasp {command.grasp}"
    return "teleoperate" if isinstance(command, TeleopGoal) else "open"


def describe(command: Command) -> str:
    if isinstance(command, GraspCommand):
        return (f"Grasp {command.grasp} (finger {command.finger_force:.2f} N, thumb {command.thumb_force:.2f} N; "
                f"pose {command.pose})")
    if isinstance(command, OpenCommand):
        return f"GripperCommand position 0 (open; pose {command.pose})"
    return "Teleoperate"


class GoalKeeper:
    """The goal this node holds on the manipulation node (the module docstring says how)."""

    IDLE, SENT, CANCELLING = "idle", "sent", "cancelling"

    def __init__(self, retry_period_ns: int) -> None:
        self.retry_period_ns = retry_period_ns
        self.state = self.IDLE
        self.sent: Command | None = None  # the goal running (or on its way)
        self.settled: Command | None = None  # the last goal that ended for good
        self.retry_at_ns = 0

    def want(self, wanted: Command | None, now_ns: int) -> list:
        if self.state == self.SENT and command_key(wanted) != command_key(self.sent):
            self.state = self.CANCELLING
            return [CancelGoal(f"{describe(wanted)} wanted" if wanted is not None else "nothing wanted")]
        if (self.state == self.IDLE and wanted is not None and command_key(wanted) != command_key(self.settled)
                and now_ns >= self.retry_at_ns):
            self.state, self.sent = self.SENT, wanted
            return [SendGoal(wanted)]
        return []

    def ended(self, reason: str, success: bool, now_ns: int) -> tuple[Command | None, bool]:
        """The goal's end: (the command that ended, whether it ended for good). A goal refused for
        now is sent again after retry_period, as is an open GripperCommand that did not succeed
        (its result has no text to say why: opening is always worth another try)."""
        command, cancelled_by_us = self.sent, self.state == self.CANCELLING
        self.state, self.sent = self.IDLE, None
        if cancelled_by_us:
            return command, False
        retry = refusal_code(reason) in RETRY_LATER or (isinstance(command, OpenCommand) and not success)
        if retry:
            self.retry_at_ns = now_ns + self.retry_period_ns
        elif stop_code(reason) != INPUT_STALE:
            self.settled = command
        return command, not retry and stop_code(reason) != INPUT_STALE

    def forget(self) -> None:
        """Whatever ended before may be sent again (engaging again)."""
        self.settled, self.retry_at_ns = None, 0


class _Engaging:
    """What both inputs share: engaged or not, and the goal keeper."""

    def __init__(self, config: TeleopConfig) -> None:
        self.config = config
        self.engaged = config.engage_at_start
        self.keeper = GoalKeeper(int(round(config.retry_period * NS)))

    def wanted(self, now_ns: int) -> Command | None:
        raise NotImplementedError

    def tick(self, now_ns: int) -> list:
        """On every input sample and goal end: the goal the glove wants now, a retry when due."""
        return self.keeper.want(self.wanted(now_ns), now_ns)

    def engage(self, on: bool, now_ns: int) -> tuple[str, list]:
        was, self.engaged = self.engaged, on
        if on:
            self.keeper.forget()
        state = "engaged" if on else "disengaged"
        message = f"already {state}" if was == on else state
        return message, [Note("info", f"teleoperation {message}")] + self.tick(now_ns)

    def reconfigure(self, config: TeleopConfig) -> None:
        self.config = config
        self.keeper.retry_period_ns = int(round(config.retry_period * NS))


class HandPoseTeleop(_Engaging):
    """Input joint_states (the module docstring says what it does)."""

    def __init__(self, config: TeleopConfig, calibration: OperatorCalibration) -> None:
        super().__init__(config)
        self.joints, self.ranges = config.joint_groups(), config.motor_ranges()
        calibration.check(self.joints.flexion(), self.joints.thumb_opposition)  # CalibrationError at start
        self.calibration = self.candidate = calibration
        self.filter = config.target_filter()
        self._recent: deque[Mapping[str, float]] = deque(maxlen=config.capture_samples)
        self._last_rx_ns: int | None = None
        self._since_end = 0  # samples since the last goal ended

    def on_sample(self, stamp_ns: int, angles: Mapping[str, float], now_ns: int) -> tuple[dict[str, float] | None,
                                                                                           list]:
        """A glove sample: (the motor targets to publish, or None for a sample it cannot use; decisions)."""
        try:
            targets = retarget(angles, self.calibration, self.joints, self.ranges)
        except MissingJoints as exc:
            return None, [Note("warning", f"glove sample ignored: {exc}")]
        self._recent.append(dict(angles))
        self._last_rx_ns = now_ns
        self._since_end += 1
        return self.filter.step(stamp_ns, targets), self.tick(now_ns)

    def wanted(self, now_ns: int) -> Command | None:
        if not self.engaged:
            return None
        flowing = (self._last_rx_ns is not None and now_ns - self._last_rx_ns < FLOWING_NS
                   and self._since_end >= RESUME_SAMPLES)
        if self.keeper.state == GoalKeeper.IDLE and not flowing:
            return None
        c = self.config
        return TeleopGoal(c.max_pad_force, c.max_speed_rpm, c.input_timeout)

    def on_goal_ended(self, reason: str, success: bool, now_ns: int) -> list:
        command, for_good = self.keeper.ended(reason, success, now_ns)
        self._since_end = 0
        notes = []
        if isinstance(command, TeleopGoal) and for_good:  # not cancelled by this node: by another client, or failed
            self.engaged = False
            notes.append(Note("warning" if reason == CANCELED else "error",
                              f"Teleoperate ended {reason}: disengaged; call ~/engage to resume"))
        elif stop_code(reason) == INPUT_STALE:
            notes.append(Note("warning", "Teleoperate ended input_stale (the glove fell silent): resumes once the "
                                         "glove is back"))
        elif not for_good and reason not in (CANCELED, ""):
            notes.append(Note("warning", f"Teleoperate {reason}: sent again in {self.config.retry_period:g} s"))
        return notes + self.tick(now_ns)

    def reconfigure(self, config: TeleopConfig) -> None:
        super().reconfigure(config)
        self.filter.deadband_rad = config.deadband

    def capture(self, pose: str) -> tuple[bool, str, OperatorCalibration | None]:
        """Capture the glove's pose now (the mean of the recent samples) as calibration pose `pose`:
        (success, the reply, the calibration to save when it became complete and is now in use)."""
        if pose not in POSES:
            raise ValueError(f"unknown calibration pose {pose!r}")
        if not self._recent:
            return False, "no glove sample yet on glove/joint_states: nothing to capture", None
        samples = list(self._recent)
        joints = [j for j in self.joints.all() if all(j in s for s in samples)]
        angles = {j: sum(s[j] for s in samples) / len(samples) for j in joints}
        self.candidate = self.candidate.with_pose(pose, angles)
        captured = f"captured {pose.replace('_', ' ')} ({len(samples)} samples)"
        try:
            self.candidate.check(self.joints.flexion(), self.joints.thumb_opposition)
        except CalibrationError as exc:
            return True, f"{captured}; the calibration in use is unchanged until the rest is captured: {exc}", None
        self.calibration = replace(self.candidate, operator=self.candidate.operator or "captured")
        self.filter.reset()
        return True, f"{captured}; calibration in use", self.calibration


class StagTeleop(_Engaging):
    """Input stag: the pose estimates and the glove's pressure -> Grasp and open goals."""

    PRESSURES_KEPT = 32  # frames whose total pressure waits for its pose estimate

    def __init__(self, config: TeleopConfig) -> None:
        super().__init__(config)
        self.mapper = PoseMapper(config.pose_mapping())
        self._pressures: dict[int, float] = {}
        self._latest_pressure: float | None = None

    def on_frame(self, stamp_ns: int, pressure: float, shorted: bool) -> None:
        """A glove frame's total pressure (a shorted frame gets no pose estimate: not kept)."""
        if shorted:
            return
        self._pressures[stamp_ns] = self._latest_pressure = pressure
        while len(self._pressures) > self.PRESSURES_KEPT:
            del self._pressures[next(iter(self._pressures))]

    def on_pose(self, stamp_ns: int, label: str, confidence: float, now_ns: int) -> list:
        pressure = self._pressures.get(stamp_ns, self._latest_pressure)
        if pressure is None:
            return [Note("warning", "pose estimate ignored: no glove frame (stag/frame) for its pressure yet")]
        command = self.mapper.update(label, confidence, pressure)
        notes = [] if command is None else [Note("info", f"pose {label} held {self.mapper.mapping.frames} frames "
                                                         f"(pressure {pressure:.1f}): {describe(command)}")]
        return notes + self.tick(now_ns)

    def wanted(self, now_ns: int) -> Command | None:
        return self.mapper.current if self.engaged else None

    def on_goal_ended(self, reason: str, success: bool, now_ns: int) -> list:
        command, for_good = self.keeper.ended(reason, success, now_ns)
        notes = []
        if command is not None and not success and reason != CANCELED:
            again = "" if for_good else f": sent again in {self.config.retry_period:g} s"
            notes.append(Note("warning", f"{describe(command)} ended {reason or 'aborted'}{again}"))
        return notes + self.tick(now_ns)

    def reconfigure(self, config: TeleopConfig) -> None:
        super().reconfigure(config)
        self.mapper.mapping = config.pose_mapping()
