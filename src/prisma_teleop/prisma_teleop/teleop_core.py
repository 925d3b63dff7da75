"""The teleop node's decisions, ROS-free: glove input -> motor targets and the goals it keeps on the
manipulation node.

`GoalKeeper`: the one goal this node holds on the manipulation node (Teleoperate, Grasp or
GripperCommand; the manipulation node runs one goal at a time across all of them). Given the goal
the glove wants now, it sends it when none runs, cancels the running one when another is wanted
(and sends that one once the cancel has ended it), and after a refusal for now (`not_ready`,
`busy`) sends it again after `retry_period`. A goal that ended for good is not sent again until
something else is wanted. Whatever happens it sends at most one goal per `MIN_SEND_INTERVAL_NS`
(four a second): a goal that ends as soon as it starts must not become a storm of goals.

Every input sample's stamp is judged first (prisma_common.sample_stamps: stamped 0, ahead of the
node's clock, older than `max_input_age` on arrival): a refused sample is not used at all (no
target, no goal, no capture); the refusal is logged once per episode and on /diagnostics while it
lasts (`diagnostics`).

`HandPoseTeleop` (input joint_states): every accepted glove sample -> retargeting.retarget ->
TargetFilter -> the targets published on prisma/teleop/motor_targets; while engaged it keeps a
Teleoperate goal running: sent once `RESUME_SAMPLES` accepted samples arrived since the last goal
ended (the manipulation node refuses it not_ready until the targets flow), sent again after one
ended input_stale once the glove is back; any other end (sensor_stale, motor_fault, canceled by
another client, invalid) disengages with the reason logged. Captures of the operator's poses build
the calibration (calibration.py): in use, and saved, once the operator has captured all four
poses (a calibration loaded from the operator's file counts as captured).

`StagTeleop` (input stag): each accepted pose estimate with its frame's total pressure ->
stag_poses.PoseMapper -> the Grasp or the open GripperCommand to keep, while engaged. A grasp pose
already held when the node began to see the glove (engaged mid-pose, a replay already running), and
one the hand was not ready for (`not_ready`), is not started from its end: the operator forms it
anew (sent from its end, it was cancelled by the next pose a moment later).

Both mark episodes (episodes.py: engaging starts one, letting go or the goal ending for good ends it,
the operator's ~/mark_episode starts or ends one with a task and an outcome).

Every method returns decisions as data (`SendGoal`, `CancelGoal`, `Note` for the log, `EpisodeMarker`
to publish); the node carries them out. Time is explicit (`now_ns`, the node clock).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace

from prisma_common.diagnostics import OK, WARN, DiagnosticStatusData
from prisma_common.goal_refusal import NOT_READY, RETRY_LATER, refusal_code
from prisma_common.sample_stamps import StampGate, StampNews

from .calibration import POSES, CalibrationError, OperatorCalibration
from .episodes import EpisodeMarks, EpisodeRefused
from .node_config import TeleopConfig
from .retargeting import MissingJoints, retarget
from .stag_poses import GraspCommand, OpenCommand, PoseMapper

NS = 1_000_000_000
RESUME_SAMPLES = 3  # glove samples since a goal ended before a new Teleoperate goal is sent
FLOWING_NS = NS // 5  # the glove counts as flowing while its last sample is younger than this
MIN_SEND_INTERVAL_NS = NS // 4  # at most four goals a second, whatever ends them
INPUT_STALE = "input_stale"
JOINT_LIMIT = "joint_limit"  # a grasp closed to the motors' limits: nothing between the fingers
CANCELED = "canceled"


@dataclass(frozen=True)
class TeleopGoal:
    """A Teleoperate goal (0 = the manipulation node's parameter)."""

    max_pad_force: float = 0.0
    max_speed_rpm: float = 0.0
    input_timeout: float = 0.0

    @classmethod
    def of(cls, config: TeleopConfig) -> TeleopGoal:
        """The goal the teleop node sends with `config`'s fields; `TeleopGoal.of(TeleopConfig())` is its
        default goal, which whatever drives the hand in an operator's place sends too."""
        return cls(config.max_pad_force, config.max_speed_rpm, config.input_timeout)


Command = TeleopGoal | GraspCommand | OpenCommand


@dataclass(frozen=True)
class SendGoal:
    command: Command


@dataclass(frozen=True)
class CancelGoal:
    why: str


@dataclass(frozen=True)
class Note:
    """A line for the node's log: level info, warning or error; `throttled`: a warning the node may
    hold back when it repeats within seconds (a stamp's refusal is said once per episode: never)."""

    level: str
    text: str
    throttled: bool = True


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

    def __init__(self, retry_period_ns: int, min_send_interval_ns: int = MIN_SEND_INTERVAL_NS) -> None:
        self.retry_period_ns = retry_period_ns
        self.min_send_interval_ns = min_send_interval_ns
        self.state = self.IDLE
        self.sent: Command | None = None  # the goal running (or on its way)
        self.settled: Command | None = None  # the last goal that ended for good
        self.retry_at_ns = 0
        self.sent_at_ns: int | None = None  # when the last goal was sent
        self.sent_count = 0
        self.last_end: tuple[str, str] | None = None  # the last goal that ended: (what it was, its reason)

    def want(self, wanted: Command | None, now_ns: int) -> list:
        if self.state == self.SENT and command_key(wanted) != command_key(self.sent):
            self.state = self.CANCELLING
            return [CancelGoal(f"{describe(wanted)} wanted" if wanted is not None else "nothing wanted")]
        due = now_ns >= self.retry_at_ns and (self.sent_at_ns is None
                                              or now_ns - self.sent_at_ns >= self.min_send_interval_ns)
        if self.state == self.IDLE and wanted is not None and command_key(wanted) != command_key(self.settled) and due:
            self.state, self.sent = self.SENT, wanted
            self.sent_at_ns, self.sent_count = now_ns, self.sent_count + 1
            return [SendGoal(wanted)]
        return []

    def ended(self, reason: str, success: bool, now_ns: int) -> tuple[Command | None, bool]:
        """The goal's end: (the command that ended, whether it ended for good). A goal refused for
        now is sent again after retry_period, as is an open GripperCommand that did not succeed
        (its result has no text to say why: opening is always worth another try)."""
        command, cancelled_by_us = self.sent, self.state == self.CANCELLING
        self.state, self.sent = self.IDLE, None
        if command is not None:
            self.last_end = (describe(command), reason or ("succeeded" if success else "aborted"))
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
    """What both inputs share: engaged or not, the goal keeper, the judgement of the input's stamps
    and the node's status on /diagnostics."""

    def __init__(self, config: TeleopConfig, input_topic: str) -> None:
        self.config = config
        self.engaged = config.engage_at_start
        self.keeper = GoalKeeper(int(round(config.retry_period * NS)))
        self.gate = StampGate(input_topic, config.stamp_limits())
        self.episodes = EpisodeMarks(config.episode_task)
        self._arrivals = 0  # input samples (accepted or not) since the last status
        self._status_ns: int | None = None  # when the last status was made
        self._last_arrival: tuple[int, int] | None = None  # the latest input sample: (its stamp, its arrival)

    def wanted(self, now_ns: int) -> Command | None:
        raise NotImplementedError

    def _admit(self, stamp_ns: int, now_ns: int) -> tuple[bool, list]:
        """Whether to use an input sample (its stamp judged), and the log line when the judgement changed."""
        self._arrivals += 1
        self._last_arrival = (stamp_ns, now_ns)
        accepted, news = self.gate.judge(stamp_ns, now_ns)
        return accepted, [_note(news)] if news is not None else []

    def tick(self, now_ns: int) -> list:
        """On every input sample and goal end: the goal the glove wants now, a retry when due."""
        actions = self.keeper.want(self.wanted(now_ns), now_ns)
        if any(isinstance(a, SendGoal) for a in actions):
            self.episodes.goal_started()
        return actions

    def begin(self, now_ns: int) -> list:
        """At the node's start: the first episode's start when engaged at start."""
        return list(self.episodes.engaged(now_ns)) if self.engaged else []

    def engage(self, on: bool, now_ns: int) -> tuple[str, list]:
        """~/engage: engaging starts an episode unless one is open, letting go ends the open one."""
        was, self.engaged = self.engaged, on
        if on:
            self.keeper.forget()
        state = "engaged" if on else "disengaged"
        message = f"already {state}" if was == on else state
        markers = self.episodes.engaged(now_ns) if on else self.episodes.let_go(now_ns)
        return message, [Note("info", f"teleoperation {message}"), *markers] + self.tick(now_ns)

    def mark_episode(self, event: str, now_ns: int, task: str = "", outcome: str = "") -> tuple[bool, str, int, list]:
        """~/mark_episode: (done, the reply, the episode's index, decisions); engagement is left as it is."""
        try:
            marker = self.episodes.mark(event, now_ns, task, outcome)
        except EpisodeRefused as exc:
            index = self.episodes.open.episode if self.episodes.open is not None else self.episodes.next_index
            return False, str(exc), index, []
        return True, marker.describe(), marker.episode, [marker]

    def _goal_ended(self, reason: str, success: bool) -> None:
        """A goal's end, for the episode's outcome (in GoalKeeper.last_end's words)."""
        self.episodes.goal_ended(reason or ("succeeded" if success else "aborted"), success)

    def reconfigure(self, config: TeleopConfig) -> None:
        self.config = config
        self.keeper.retry_period_ns = int(round(config.retry_period * NS))
        self.gate.limits = config.stamp_limits()
        self.episodes.task = config.episode_task

    def diagnostics(self, now_ns: int) -> DiagnosticStatusData:
        """The node's status (name `teleop`): engaged or not, the input's rate and age, whether it is
        refused and why, the last goal and its end, and what the input's own part adds."""
        elapsed = None if self._status_ns is None else now_ns - self._status_ns
        rate = self._arrivals / (elapsed / NS) if elapsed else None
        self._arrivals, self._status_ns = 0, now_ns
        values = {"engaged": str(self.engaged).lower(), "input": self.gate.stream,
                  "input_rate_hz": f"{rate:.1f}" if rate is not None else "not measured yet"}
        if self._last_arrival is None:
            values["input_age_ms"] = values["input_silent_ms"] = "no sample yet"
        else:
            stamp, arrival = self._last_arrival
            values["input_age_ms"] = "stamped 0" if stamp == 0 else f"{(arrival - stamp) / 1e6:.0f}"
            values["input_silent_ms"] = f"{(now_ns - arrival) / 1e6:.0f}"
        refused = self.gate.refused
        values["input_refused"] = refused or "no"
        values["input_refused_samples"] = str(self.gate.refused_total)
        values["goals_sent"] = str(self.keeper.sent_count)
        values["goal_running"] = describe(self.keeper.sent) if self.keeper.sent is not None else "none"
        what, reason = self.keeper.last_end or ("none", "")
        values["last_goal"] = what
        values["last_goal_end"] = reason or "none"
        values.update(self.episodes.status(now_ns))
        values.update(self._status_values())
        silent = self._last_arrival is None or now_ns - self._last_arrival[1] > NS
        if refused is not None:
            level, message = WARN, f"input refused: {refused}"
        elif not self.engaged:
            level, message = OK, "disengaged (~/engage)"
        elif silent:
            level, message = WARN, f"engaged, no input on {self.gate.stream}"
        else:
            level, message = OK, f"engaged: {values['goal_running']} running" if self.keeper.sent else "engaged"
        return DiagnosticStatusData("teleop", level, message, "", values)

    def _status_values(self) -> dict[str, str]:
        return {}


def _note(news: StampNews) -> Note:
    return Note(news.level, news.text, throttled=False)


class HandPoseTeleop(_Engaging):
    """Input joint_states (the module docstring says what it does)."""

    def __init__(self, config: TeleopConfig, calibration: OperatorCalibration, captured: bool = False,
                 input_topic: str = "glove/joint_states") -> None:
        """`captured`: `calibration` is the operator's own (loaded from their file), not the nominal hand's."""
        super().__init__(config, input_topic)
        self.joints, self.ranges = config.joint_groups(), config.motor_ranges()
        calibration.check(self.joints.flexion(), self.joints.thumb_opposition)  # CalibrationError at start
        self.calibration = self.candidate = calibration
        self.captured: set[str] = set(POSES) if captured else set()  # the candidate's poses the operator captured
        self.filter = config.target_filter()
        self._recent: deque[Mapping[str, float]] = deque(maxlen=config.capture_samples)
        self._last_rx_ns: int | None = None
        self._since_end = 0  # samples since the last goal ended

    def on_sample(self, stamp_ns: int, angles: Mapping[str, float], now_ns: int) -> tuple[dict[str, float] | None,
                                                                                           list]:
        """A glove sample: (the motor targets to publish, or None for a sample it cannot use; decisions)."""
        accepted, notes = self._admit(stamp_ns, now_ns)
        if not accepted:
            return None, notes + self.tick(now_ns)
        try:
            targets = retarget(angles, self.calibration, self.joints, self.ranges)
        except MissingJoints as exc:
            return None, notes + [Note("warning", f"glove sample ignored: {exc}")]
        self._recent.append(dict(angles))
        self._last_rx_ns = now_ns
        self._since_end += 1
        return self.filter.step(stamp_ns, targets), notes + self.tick(now_ns)

    def wanted(self, now_ns: int) -> Command | None:
        if not self.engaged:
            return None
        flowing = (self._last_rx_ns is not None and now_ns - self._last_rx_ns < FLOWING_NS
                   and self._since_end >= RESUME_SAMPLES)
        if self.keeper.state == GoalKeeper.IDLE and not flowing:
            return None
        return TeleopGoal.of(self.config)

    def on_goal_ended(self, reason: str, success: bool, now_ns: int) -> list:
        command, for_good = self.keeper.ended(reason, success, now_ns)
        self._since_end = 0
        self._goal_ended(reason, success)
        notes: list = []
        if isinstance(command, TeleopGoal) and for_good:  # not cancelled by this node: by another client, or failed
            self.engaged = False
            notes.append(Note("warning" if reason == CANCELED else "error",
                              f"Teleoperate ended {reason}: disengaged; call ~/engage to resume"))
            notes += self.episodes.failed(now_ns, reason)
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
        if self.gate.refused is not None:
            return False, f"nothing to capture: {self.gate.refused}", None
        if not self._recent:
            return False, f"no glove sample yet on {self.gate.stream}: nothing to capture", None
        samples = list(self._recent)
        joints = [j for j in self.joints.all() if all(j in s for s in samples)]
        angles = {j: sum(s[j] for s in samples) / len(samples) for j in joints}
        operator = self.candidate.operator if self.captured == set(POSES) else "captured"
        self.candidate = replace(self.candidate.with_pose(pose, angles), operator=operator or "captured")
        self.captured.add(pose)
        captured = f"captured {pose.replace('_', ' ')} ({len(samples)} samples)"
        unchanged = f"the calibration in use ({self.calibration.operator or 'unnamed'}) is unchanged"
        missing = self.poses_to_capture()
        if missing:
            return True, f"{captured}; {unchanged} until {', '.join(missing)} {'is' if len(missing) == 1 else 'are'} " \
                         "captured too", None
        try:
            self.candidate.check(self.joints.flexion(), self.joints.thumb_opposition)
        except CalibrationError as exc:
            return True, f"{captured}; {unchanged}: {exc}", None
        self.calibration = self.candidate
        self.filter.reset()
        return True, f"{captured}; calibration in use", self.calibration

    def poses_to_capture(self) -> list[str]:
        """The poses the operator has not captured yet (their words: `thumb adducted`)."""
        return [p.replace("_", " ") for p in POSES if p not in self.captured]

    def _status_values(self) -> dict[str, str]:
        missing = self.poses_to_capture()
        complete = "yes" if not missing else f"no: {', '.join(missing)} to capture"
        return {"calibration_operator": self.calibration.operator or "unnamed", "calibration_complete": complete}


class StagTeleop(_Engaging):
    """Input stag: the pose estimates and the glove's pressure -> Grasp and open goals."""

    PRESSURES_KEPT = 32  # frames whose total pressure waits for its pose estimate

    def __init__(self, config: TeleopConfig, input_topic: str = "stag/hand_pose",
                 replace_service: str = "/tactile_driver/replace_object") -> None:
        """`replace_service`: the hand's service that puts the object back (named in the log)."""
        super().__init__(config, input_topic)
        self.replace_service = replace_service
        self.mapper = PoseMapper(config.pose_mapping())
        self._pressures: dict[int, float] = {}
        self._latest_pressure: float | None = None
        # the pose already held when this node began to see the glove (engaged): its start was not
        # seen (a replay or an operator mid-pose), so its grasp is not started; "" until the first estimate
        self._start_unseen: str | None = ""

    def on_frame(self, stamp_ns: int, pressure: float, shorted: bool) -> None:
        """A glove frame's total pressure (a shorted frame gets no pose estimate: not kept)."""
        if shorted:
            return
        self._pressures[stamp_ns] = self._latest_pressure = pressure
        while len(self._pressures) > self.PRESSURES_KEPT:
            del self._pressures[next(iter(self._pressures))]

    def on_pose(self, stamp_ns: int, label: str, confidence: float, now_ns: int) -> list:
        accepted, notes = self._admit(stamp_ns, now_ns)
        if not accepted:
            return notes + self.tick(now_ns)
        pressure = self._pressures.get(stamp_ns, self._latest_pressure)
        if pressure is None:
            return notes + [Note("warning", "pose estimate ignored: no glove frame (stag/frame) for its pressure yet")]
        if self._start_unseen == "":
            self._start_unseen = label
        command = self.mapper.update(label, confidence, pressure)
        current = self.mapper.current
        if label != self._start_unseen and (current is None or current.pose != self._start_unseen):
            self._start_unseen = None  # the pose held at the start is over: the next one's start is seen
        if command is not None:
            held = (f"pose {label} held {self.mapper.mapping.frames} frames (pressure {pressure:.1f}): "
                    f"{describe(command)}")
            if self._unseen_start(command):
                held += ("; not started: the pose was already held when teleoperation began (a grasp from its end "
                         "would be cancelled by the next pose at once): form it anew")
            notes.append(Note("info", held))
        return notes + self.tick(now_ns)

    def _unseen_start(self, command: Command | None) -> bool:
        return isinstance(command, GraspCommand) and self._start_unseen is not None and \
            command.pose == self._start_unseen

    def wanted(self, now_ns: int) -> Command | None:
        current = self.mapper.current
        return current if self.engaged and not self._unseen_start(current) else None

    def engage(self, on: bool, now_ns: int) -> tuple[str, list]:
        if on and not self.engaged:
            self._start_unseen = ""  # a pose held now was formed before: its grasp waits for it formed anew
        return super().engage(on, now_ns)

    def on_goal_ended(self, reason: str, success: bool, now_ns: int) -> list:
        command, for_good = self.keeper.ended(reason, success, now_ns)
        self._goal_ended(reason, success)
        notes = []
        if isinstance(command, GraspCommand) and refusal_code(reason) == NOT_READY:
            # the hand was not ready for the pose: sent again later it would start at the end of the
            # pose and be cancelled by the next one moments after; the operator forms it again
            self.keeper.settled, self.keeper.retry_at_ns = command, 0
            notes.append(Note("warning", f"{describe(command)} ended {reason}: not sent again; form the pose anew "
                                         "once the hand is ready"))
        elif isinstance(command, GraspCommand) and stop_code(reason) == JOINT_LIMIT:
            notes.append(Note("warning", f"{describe(command)} ended {reason}: the fingers closed to their limit "
                                         "without touching anything, the object is not between them (an open hand "
                                         "lets it fall). Put it back (the sim and emulated hand: ros2 service call "
                                         f"{self.replace_service} std_srvs/srv/Trigger), then form the pose again"))
        elif command is not None and not success and reason != CANCELED:
            again = "" if for_good else f": sent again in {self.config.retry_period:g} s"
            notes.append(Note("warning", f"{describe(command)} ended {reason or 'aborted'}{again}"))
        return notes + self.tick(now_ns)

    def reconfigure(self, config: TeleopConfig) -> None:
        super().reconfigure(config)
        self.mapper.mapping = config.pose_mapping()
