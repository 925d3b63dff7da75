"""Bags of demonstrations -> LeRobot episodes: which topics feed which feature, how each message is
decoded (the owning packages' converters), and the frames sampled on the fps grid (`sampling`).

One episode per marked span (episode_spans.py: the teleop node's markers on prisma/teleop/episode,
start..end, the task and outcome theirs), or one per bag with `whole_bag`; a bag without markers
(and no `whole_bag`) is refused with the line that says how to mark one or to use `--whole-bag`.
recorded_topics.py names the topics; record.launch.py records them, `prisma-dataset topics` prints them.

Features (docs/datasets.md, "Features"):
- observation.state [6] float32: the three motors' positions (rad) then velocities (rad/s), /joint_states
- observation.tactile [5, 3, 3] float32: each finger's taxel voltages (V), row-major as the pad's
  numbering (row 0 = bottom, column 0 = right side), /prisma/<finger>/taxels or /prisma/hand/taxels
- observation.wrench [5, 6] float32: fx fy fz (N), tx ty tz (N m), /prisma/<finger>/wrench or /prisma/hand/wrench
- observation.contact [5] float32: 1 where the ContactState is `feasible` (Algorithm 1: no edge
  lost, the pad's mean voltage at or above the monitor's minimum), else 0
- observation.glove_pose [joints] float32: the operator's joint angles (rad), /glove/joint_states, when recorded
- observation.glove_pressure [32, 32] float32: the STAG glove's normalised pressure (0..1) per sensor,
  row-major as its readout, /stag/frame (GloveFrame; a shorted frame is skipped), when recorded
- action [3] float32: the motor targets the hand followed, /prisma/teleop/motor_targets (`targets`);
  or, with `positions`, the next frame's motor positions (the episode's last frame, which has no
  next one, is dropped)
"""
from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from prisma_common import topics
from prisma_common.bag import bag_topics, read_bag
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_force_estimator.ros_conversions import wrench_from_msg
from prisma_manipulation.ros_conversions import contact_state_from_msg, joint_sample_from_msg
from prisma_motor_driver.control_table import rpm_to_rad_s
from prisma_tactile_driver.ros_conversions import taxel_frame_from_msg
from prisma_teleop.episodes import DEFAULT_TASK, EpisodeMarker
from prisma_teleop.ros_conversions import episode_marker_from_msg, hand_pose_from_msg, motor_targets_from_msg
from stag_glove.ros_conversions import glove_frame_from_msg

from .episode_spans import Span, episode_spans
from .lerobot_format import Dataset, Episode, Feature
from .recorded_topics import EPISODE_TOPIC, GLOVE_TOPIC, STAG_FRAME_TOPIC, TARGETS_TOPIC, in_namespace
from .recorded_topics import record_topics as record_topics  # the list a recording needs (re-exported)
from .sampling import NS, Stream, sample_and_hold

DEFAULT_FPS = 50
ACTIONS = ("targets", "positions")
# how an operator marks an episode without engaging again (the teleop node's service)
MARK_EPISODE_COMMAND = ("ros2 service call /teleop/mark_episode prisma_msgs/srv/MarkEpisode "
                        "\"{event: start, task: 'pinch the ball'}\"")

STATE, TACTILE, WRENCH, CONTACT, GLOVE_POSE, GLOVE_PRESSURE, ACTION = (
    "observation.state", "observation.tactile", "observation.wrench", "observation.contact",
    "observation.glove_pose", "observation.glove_pressure", "action")

# Max age of each kind of stream (s): a frame whose newest sample of the stream is older ends the
# episode. The 100 Hz hand streams: 5 periods; the 60 Hz glove and its targets: 6 periods, below
# the Teleoperate goal's default input_timeout (0.15 s), after which the hand stops anyway. The STAG
# glove's frames (~7.3 fps, 137 ms apart): 0.3 s holds a frame across one lost or shorted frame (274
# ms) and its jitter, not across two (411 ms): an older pressure would describe another grasp.
MAX_AGE_S = {"joint_states": 0.05, "taxels": 0.05, "wrench": 0.05, "contact": 0.05, "motor_targets": 0.1,
             "glove": 0.1, "glove_pressure": 0.3}


class ExportError(ValueError):
    """A bag that cannot be exported as asked; the message names the bag, the topic and the fix."""


@dataclass
class ExportOptions:
    fps: int = DEFAULT_FPS
    task: str | None = None  # None: the markers' task (--whole-bag: DEFAULT_TASK); else every episode's
    action: str = "targets"
    whole_bag: bool = False
    namespace: str = ""  # the hand's namespace the bag was recorded in
    max_age_s: dict[str, float] = field(default_factory=lambda: dict(MAX_AGE_S))


@dataclass
class BagPlan:
    """Which topics of one bag feed the features: per-finger topics when all five are there, else the
    per-hand ones."""

    bag: Path
    taxels: list[str]
    wrench: list[str]
    contact: list[str]
    glove: bool
    targets: bool
    glove_pressure: bool = False
    markers: bool = False  # read the episode markers (not with --whole-bag)
    namespace: str = ""

    def name(self, topic: str) -> str:
        """A default topic as this bag holds it (in the plan's namespace)."""
        return in_namespace(topic, self.namespace)

    def topics(self) -> list[str]:
        optional = ((TARGETS_TOPIC, self.targets), (GLOVE_TOPIC, self.glove), (STAG_FRAME_TOPIC, self.glove_pressure),
                    (EPISODE_TOPIC, self.markers))
        return [self.name(topics.JOINT_STATES), *self.taxels, *self.wrench, *self.contact,
                *(self.name(t) for t, wanted in optional if wanted)]


def _per_finger_or_hand(present: dict[str, str], pattern: str, hand: str) -> list[str] | None:
    per_finger = [pattern.format(finger=f) for f in FINGERS]
    if all(t in present for t in per_finger):
        return per_finger
    return [hand] if hand in present else None


def no_markers(bag: Path | str) -> str:
    """The refusal of a bag without episode markers: how to mark one, or --whole-bag."""
    return (f"bag {bag} has no episode markers ({EPISODE_TOPIC}): record the teleop node's markers (engaging starts "
            f"an episode, letting go ends it; or mark one: {MARK_EPISODE_COMMAND}, then event: end), or export "
            f"the bag as one episode with --whole-bag")


def plan_bag(bag: Path, options: ExportOptions) -> BagPlan:
    """The topics to read from `bag`; ExportError naming every missing one and what the bag has."""
    present = bag_topics(bag)
    ns = options.namespace

    def name(topic: str) -> str:
        return in_namespace(topic, ns)

    if not options.whole_bag and name(EPISODE_TOPIC) not in present:  # the first thing to fix
        raise ExportError(no_markers(bag))
    missing = []
    if name(topics.JOINT_STATES) not in present:
        missing.append(f"'{name(topics.JOINT_STATES)}' (observation.state)")
    found = {}
    for kind, pattern, hand in (("taxels", topics.TAXELS, topics.HAND_TAXELS),
                                ("wrench", topics.WRENCH, topics.HAND_WRENCH),
                                ("contact", topics.CONTACT, topics.HAND_CONTACT)):
        chosen = _per_finger_or_hand(present, name(pattern), name(hand))
        if chosen is None:
            absent = [name(pattern).format(finger=f) for f in FINGERS
                      if name(pattern).format(finger=f) not in present]
            missing.append(f"{', '.join(map(repr, absent))} (or '{name(hand)}')")
        found[kind] = chosen or []
    targets = name(TARGETS_TOPIC) in present
    if options.action == "targets" and not targets:
        missing.append(f"'{name(TARGETS_TOPIC)}' (the action: the teleop node's motor targets; for a bag without "
                       f"teleoperation use --action positions)")
    if missing:
        has = ", ".join(sorted(present)) or "no topics at all"
        where = f" (namespace '{ns.strip('/')}')" if ns.strip("/") else ""
        raise ExportError(f"bag {bag}{where} has no topic {'; no topic '.join(missing)}; it has: {has}")
    return BagPlan(bag, found["taxels"], found["wrench"], found["contact"], name(GLOVE_TOPIC) in present,
                   options.action == "targets", name(STAG_FRAME_TOPIC) in present, not options.whole_bag, ns)


@dataclass
class _Samples:
    stamps: list[int] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)

    def add(self, stamp_ns: int, value: Any) -> None:
        self.stamps.append(stamp_ns)
        self.values.append(value)


def _finger_of(topic: str, pattern: str) -> str | None:
    for finger in FINGERS:
        if topic == pattern.format(finger=finger):
            return finger
    return None


def _motor_vector(values: Mapping[str, float]) -> np.ndarray | None:
    if not all(m in values for m in MOTOR_NAMES):
        return None
    return np.array([values[m] for m in MOTOR_NAMES], dtype=np.float64)


@dataclass
class BagStreams:
    """What one bag holds for the export: stream key -> samples, the glove's joint names (empty
    without a glove), the glove pressure's (rows, cols) (None without it), the episode markers."""

    samples: dict[str, _Samples]
    glove_names: list[str]
    pressure_shape: tuple[int, int] | None
    markers: list[EpisodeMarker]


def read_streams(plan: BagPlan) -> BagStreams:
    """Every sample the plan's topics hold. Keys: 'joint_states', 'taxels/<finger>', 'wrench/<finger>',
    'contact/<finger>', 'motor_targets', 'glove', 'glove_pressure'."""
    samples: dict[str, _Samples] = defaultdict(_Samples)
    glove_names: list[str] = []
    pressure_shape: tuple[int, int] | None = None
    markers: list[EpisodeMarker] = []
    joint_states, targets_topic, glove_topic, frame_topic, episode_topic = (plan.name(t) for t in (
        topics.JOINT_STATES, TARGETS_TOPIC, GLOVE_TOPIC, STAG_FRAME_TOPIC, EPISODE_TOPIC))
    hand_taxels, hand_wrench, hand_contact = (plan.name(t) for t in (
        topics.HAND_TAXELS, topics.HAND_WRENCH, topics.HAND_CONTACT))
    per_finger = {pattern: plan.name(pattern) for pattern in (topics.TAXELS, topics.WRENCH, topics.CONTACT)}
    for record in read_bag(plan.bag, plan.topics()):
        topic, msg = record.topic, record.message
        if topic == joint_states:
            joint = joint_sample_from_msg(msg)
            positions, velocities = _motor_vector(joint.positions), _motor_vector(joint.velocities)
            if positions is not None and velocities is not None:  # another publisher's JointState: not the motors
                samples["joint_states"].add(joint.stamp_ns, np.concatenate(
                    [positions, [rpm_to_rad_s(v) for v in velocities]]))
        elif topic == targets_topic:
            stamp, targets = motor_targets_from_msg(msg)
            vector = _motor_vector(targets)
            if vector is not None:
                samples["motor_targets"].add(stamp, vector)
        elif topic == glove_topic:
            stamp, angles = hand_pose_from_msg(msg)
            if not glove_names:
                glove_names = list(angles)
            if sorted(angles) != sorted(glove_names):
                raise ExportError(f"bag {plan.bag}: {glove_topic} changes its joints from {glove_names} to "
                                  f"{list(angles)} at {stamp / NS:.3f} s; export the parts apart")
            samples["glove"].add(stamp, np.array([angles[n] for n in glove_names]))
        elif topic == frame_topic:
            try:
                frame = glove_frame_from_msg(msg)
            except ValueError as exc:
                raise ExportError(f"bag {plan.bag}: {frame_topic}: {exc}") from None
            if frame.shorted:  # its pressure is the short's, not the hand's
                continue
            shape = (int(frame.pressure.shape[0]), int(frame.pressure.shape[1]))
            if pressure_shape is None:
                pressure_shape = shape
            if shape != pressure_shape:
                raise ExportError(f"bag {plan.bag}: {frame_topic} changes from {pressure_shape} to {shape} sensors "
                                  f"at {frame.stamp_ns / NS:.3f} s; export the parts apart")
            samples["glove_pressure"].add(frame.stamp_ns, frame.pressure)
        elif topic == episode_topic:
            try:
                markers.append(episode_marker_from_msg(msg))
            except ValueError as exc:
                raise ExportError(f"bag {plan.bag}: {episode_topic}: {exc}") from None
        elif topic == hand_taxels:
            for sample in msg.samples:
                frame_t = taxel_frame_from_msg(sample)
                samples[f"taxels/{frame_t.finger}"].add(frame_t.stamp_ns, frame_t.voltages.reshape(3, 3))
        elif topic == hand_wrench:
            for finger, wrench in zip(msg.fingers, msg.wrenches):
                sample = wrench_from_msg(wrench)
                samples[f"wrench/{finger}"].add(sample.stamp_ns, sample.wrench)
        elif topic == hand_contact:
            for contact in msg.contacts:
                evaluation = contact_state_from_msg(contact)
                samples[f"contact/{evaluation.finger}"].add(evaluation.stamp_ns, float(evaluation.feasible))
        elif (finger := _finger_of(topic, per_finger[topics.TAXELS])) is not None:
            frame_t = taxel_frame_from_msg(msg)
            samples[f"taxels/{finger}"].add(frame_t.stamp_ns, frame_t.voltages.reshape(3, 3))
        elif (finger := _finger_of(topic, per_finger[topics.WRENCH])) is not None:
            sample = wrench_from_msg(msg)
            samples[f"wrench/{finger}"].add(sample.stamp_ns, sample.wrench)
        elif (finger := _finger_of(topic, per_finger[topics.CONTACT])) is not None:
            evaluation = contact_state_from_msg(msg)
            samples[f"contact/{finger}"].add(evaluation.stamp_ns, float(evaluation.feasible))
    return BagStreams(samples, glove_names, pressure_shape, markers)


def stream_topic(plan: BagPlan, key: str) -> str:
    """The topic a stream key came from, as the summary names it."""
    kind, _, finger = key.partition("/")
    single = {"joint_states": topics.JOINT_STATES, "motor_targets": TARGETS_TOPIC, "glove": GLOVE_TOPIC,
              "glove_pressure": STAG_FRAME_TOPIC}
    if kind in single:
        return plan.name(single[kind])
    chosen = {"taxels": plan.taxels, "wrench": plan.wrench, "contact": plan.contact}[kind]
    return chosen[FINGERS.index(finger)] if len(chosen) == len(FINGERS) else f"{chosen[0]} ({finger})"


def needed_streams(plan: BagPlan) -> list[str]:
    keys = ["joint_states", *(f"{kind}/{f}" for kind in ("taxels", "wrench", "contact") for f in FINGERS)]
    optional = (("motor_targets", plan.targets), ("glove", plan.glove), ("glove_pressure", plan.glove_pressure))
    return keys + [key for key, wanted in optional if wanted]


def features_for(glove_names: Sequence[str], pressure_shape: tuple[int, int] | None = None) -> list[Feature]:
    motor = list(MOTOR_NAMES)
    features = [
        Feature(STATE, "float32", (6,), [f"{m}.pos" for m in motor] + [f"{m}.vel" for m in motor]),
        Feature(TACTILE, "float32", (len(FINGERS), 3, 3), ["finger", "row", "col"]),
        Feature(WRENCH, "float32", (len(FINGERS), 6), ["finger", "axis"]),
        Feature(CONTACT, "float32", (len(FINGERS),), list(FINGERS)),
    ]
    if glove_names:
        features.append(Feature(GLOVE_POSE, "float32", (len(glove_names),), list(glove_names)))
    if pressure_shape is not None:
        features.append(Feature(GLOVE_PRESSURE, "float32", pressure_shape, ["row", "col"]))
    features.append(Feature(ACTION, "float32", (len(motor),), motor))
    return features


def export_notes(options: ExportOptions) -> dict[str, Any]:
    """What meta/prisma_export.json says about the dataset as a whole."""
    action = (f"{TARGETS_TOPIC} sampled like the observations" if options.action == "targets"
              else "the next frame's motor positions (observation.state[0:3] of frame k+1)")
    return {
        "tool": "prisma-dataset export",
        "episodes_by": "one per bag (--whole-bag)" if options.whole_bag else
                       f"one per marked span ({EPISODE_TOPIC}: start .. end)",
        "sampling": "sample-and-hold: per stream, the newest sample whose header stamp is <= the frame's instant; "
                    "a frame where a stream's newest sample is older than its max age ends the episode",
        "max_age_s": dict(options.max_age_s),
        "action": action,
        "axes": {TACTILE: {"finger": list(FINGERS), "row": "0 = bottom (taxels 0-1-2)",
                           "col": "0 = right lateral side (taxels 0-3-6)"},
                 WRENCH: {"finger": list(FINGERS), "axis": ["fx", "fy", "fz", "tx", "ty", "tz"]},
                 GLOVE_PRESSURE: {"row": "the STAG readout's rows", "col": "its columns"}},
        "units": {STATE: "rad, rad/s", TACTILE: "V", WRENCH: "N, N m", CONTACT: "1 = feasible contact",
                  GLOVE_POSE: "rad", GLOVE_PRESSURE: "normalised 0..1 (shorted frames skipped)", ACTION: "rad"},
    }


def _episode(plan: BagPlan, options: ExportOptions, streams: list[Stream], task: str, outcome: str,
             span: tuple[int, int] | None, where: str) -> Episode | str:
    """One episode of the bag's streams within `span` (None: the whole bag), or why it has no frame."""
    sampled = sample_and_hold(streams, options.fps, span)
    by_key = {key: sampled.values[stream_topic(plan, key)] for key in needed_streams(plan)}
    frames = len(sampled.instants_ns)
    state = by_key["joint_states"]
    values = {
        STATE: state,
        TACTILE: np.stack([by_key[f"taxels/{f}"] for f in FINGERS], axis=1),
        WRENCH: np.stack([by_key[f"wrench/{f}"] for f in FINGERS], axis=1),
        CONTACT: np.stack([by_key[f"contact/{f}"] for f in FINGERS], axis=1),
    }
    if plan.glove:
        values[GLOVE_POSE] = by_key["glove"]
    if plan.glove_pressure:
        values[GLOVE_PRESSURE] = by_key["glove_pressure"]
    if options.action == "targets":
        values[ACTION] = by_key["motor_targets"]
        keep = frames
    else:  # the next frame's positions: the last frame has none
        keep = frames - 1
        values[ACTION] = state[1:, :len(MOTOR_NAMES)]
    values = {name: np.asarray(v[:keep], dtype=np.float32) for name, v in values.items()}
    origin = int(min(s.stamps_ns[0] for s in streams))
    if keep <= 0:
        why = f": {sampled.gap.describe(origin)}" if sampled.gap else ""
        return f"{where}: no frame has every stream within its max age{why}"
    ended = (("the end of the bag" if span is None else "its end marker") if sampled.gap is None
             else f"a gap: {sampled.gap.describe(origin)}")
    notes = {
        "source": str(plan.bag), "start_s": (int(sampled.instants_ns[0]) - origin) / NS,
        "frames": keep, "ended": ended, "dropped_s": round(sampled.dropped_ns / NS, 6),
        "skipped_start_frames": sampled.skipped,
        "gap": None if sampled.gap is None else {
            "stream": sampled.gap.stream, "at_s": (sampled.gap.at_ns - origin) / NS,
            "age_s": sampled.gap.age_ns / NS, "max_age_s": sampled.gap.max_age_ns / NS},
    }
    return Episode(task, values, notes, outcome)


def export_bag(plan: BagPlan, options: ExportOptions,
               progress: Callable[[str], None] | None = None) -> tuple[list[Episode], list[Feature]]:
    """One bag's episodes (one per marked span, or the whole bag) and their features. A marked span
    without a fresh frame is left out and said through `progress`; ExportError when none is left."""
    got = read_streams(plan)
    streams = []
    for key in needed_streams(plan):
        samples = got.samples.get(key)
        topic = stream_topic(plan, key)
        if samples is None or not samples.stamps:
            raise ExportError(f"bag {plan.bag}: {topic} has no usable message (a JointState needs positions and "
                              f"velocities of {', '.join(MOTOR_NAMES)}; motor targets all three motors; a glove "
                              f"frame must not be shorted)")
        kind = key.partition("/")[0]
        streams.append(Stream.from_samples(topic, samples.stamps, np.asarray(samples.values),
                                           round(options.max_age_s[kind] * NS)))
    features = features_for(got.glove_names, got.pressure_shape)
    if options.whole_bag:
        episode = _episode(plan, options, streams, options.task or DEFAULT_TASK, "", None, f"bag {plan.bag}")
        if isinstance(episode, str):
            raise ExportError(episode)
        return [episode], features
    bag_end = max(int(s.stamps_ns[-1]) for s in streams)
    spans: list[Span] = episode_spans(got.markers, bag_end)
    if not spans:
        raise ExportError(no_markers(plan.bag) if not got.markers else
                          f"bag {plan.bag} has episode markers but no start among them (the recording began "
                          f"after the episodes started): mark one while recording, or use --whole-bag")
    episodes = []
    for span in spans:
        episode = _episode(plan, options, streams, options.task or span.task, span.outcome,
                           (span.start_ns, span.end_ns), f"bag {plan.bag} episode {span.episode}")
        if isinstance(episode, str):
            if progress:
                progress(f"{episode}: left out")
            continue
        episode.notes.update(marked_episode=span.episode, outcome_reason=span.reason)
        episodes.append(episode)
    if not episodes:
        raise ExportError(f"bag {plan.bag}: none of its {len(spans)} marked episodes has a frame with every stream "
                          f"within its max age")
    return episodes, features


def export_bags(bags: Iterable[Path], options: ExportOptions,
                progress: Callable[[str], None] | None = None) -> Dataset:
    """Every bag's episodes in one dataset (nothing is written here). ExportError for a bag that
    lacks a needed topic or episode markers, has no fresh frame, or records other features than the
    first bag."""
    if options.action not in ACTIONS:
        raise ExportError(f"--action {options.action!r}: choose one of {', '.join(ACTIONS)}")
    plans = [plan_bag(Path(bag), options) for bag in bags]  # every bag's topics checked before any is read
    episodes: list[Episode] = []
    features: list[Feature] | None = None
    for plan in plans:
        bag_episodes, bag_features = export_bag(plan, options, progress)
        if features is None:
            features = bag_features
        elif bag_features != features:
            first, this = {f.name: f for f in features}, {f.name: f for f in bag_features}
            differ = [f"without {n}" for n in first if n not in this] + [f"with {n}" for n in this if n not in first]
            differ += [f"{n} of shape {this[n].shape}, not {first[n].shape}" for n in this
                       if n in first and this[n] != first[n]]
            raise ExportError(f"bag {plan.bag} records other features than {plans[0].bag} ({', '.join(differ)}); "
                              f"export them apart")
        episodes += bag_episodes
        if progress:
            for episode in bag_episodes:
                outcome = f", {episode.outcome}" if episode.outcome else ""
                progress(f"{plan.bag}: {episode.task!r}{outcome}: {episode.length} frames, ended by "
                         f"{episode.notes['ended']}")
    if features is None:
        raise ExportError("no bag given")
    return Dataset(options.fps, features, episodes, export_notes=export_notes(options))
