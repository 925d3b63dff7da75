"""Bags of demonstrations -> LeRobot episodes: which topics feed which feature, how each message is
decoded (the owning packages' converters), and the frames sampled on the fps grid (`sampling`).

One episode per bag (`whole_bag`): the episode markers the teleop node is to publish do not exist
yet, and a bag without them is refused with the line that says to use `--whole-bag`.

Features (docs/datasets.md, "Features"):
- observation.state [6] float32: the three motors' positions (rad) then velocities (rad/s), /joint_states
- observation.tactile [5, 3, 3] float32: each finger's taxel voltages (V), row-major as the pad's
  numbering (row 0 = bottom, column 0 = right side), /prisma/<finger>/taxels or /prisma/hand/taxels
- observation.wrench [5, 6] float32: fx fy fz (N), tx ty tz (N m), /prisma/<finger>/wrench or /prisma/hand/wrench
- observation.contact [5] float32: 1 where the ContactState is `feasible` (Algorithm 1: no edge
  lost, the pad's mean voltage at or above the monitor's minimum), else 0
- observation.glove_pose [joints] float32: the operator's joint angles (rad), /glove/joint_states, when recorded
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
from prisma_teleop.ros_conversions import hand_pose_from_msg, motor_targets_from_msg

from .lerobot_format import Dataset, Episode, Feature
from .sampling import NS, Stream, sample_and_hold

TARGETS_TOPIC = "/prisma/teleop/motor_targets"  # the teleop node's prisma/teleop/motor_targets
GLOVE_TOPIC = "/glove/joint_states"  # a hand-pose glove's (the synthetic_glove node's) glove/joint_states
DEFAULT_FPS = 50
DEFAULT_TASK = "teleoperate the PRISMA hand"
ACTIONS = ("targets", "positions")

STATE, TACTILE, WRENCH, CONTACT, GLOVE_POSE, ACTION = (
    "observation.state", "observation.tactile", "observation.wrench", "observation.contact",
    "observation.glove_pose", "action")

# Max age of each kind of stream (s): a frame whose newest sample of the stream is older ends the
# episode. The 100 Hz hand streams: 5 periods; the 60 Hz glove and its targets: 6 periods, below
# the Teleoperate goal's default input_timeout (0.15 s), after which the hand stops anyway.
MAX_AGE_S = {"joint_states": 0.05, "taxels": 0.05, "wrench": 0.05, "contact": 0.05, "motor_targets": 0.1,
             "glove": 0.1}


class ExportError(ValueError):
    """A bag that cannot be exported as asked; the message names the bag, the topic and the fix."""


@dataclass
class ExportOptions:
    fps: int = DEFAULT_FPS
    task: str = DEFAULT_TASK
    action: str = "targets"
    whole_bag: bool = False
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

    def topics(self) -> list[str]:
        return [topics.JOINT_STATES, *self.taxels, *self.wrench, *self.contact,
                *([TARGETS_TOPIC] if self.targets else []), *([GLOVE_TOPIC] if self.glove else [])]


def _per_finger_or_hand(present: dict[str, str], pattern: str, hand: str) -> list[str] | None:
    per_finger = [pattern.format(finger=f) for f in FINGERS]
    if all(t in present for t in per_finger):
        return per_finger
    return [hand] if hand in present else None


def plan_bag(bag: Path, options: ExportOptions) -> BagPlan:
    """The topics to read from `bag`; ExportError naming every missing one and what the bag has."""
    present = bag_topics(bag)
    if not options.whole_bag:
        raise ExportError(f"bag {bag} has no episode markers (the teleop node does not mark episodes yet): "
                          f"export it with --whole-bag, one episode per bag")
    missing = []
    if topics.JOINT_STATES not in present:
        missing.append(f"'{topics.JOINT_STATES}' (observation.state)")
    found = {}
    for kind, pattern, hand in (("taxels", topics.TAXELS, topics.HAND_TAXELS),
                                ("wrench", topics.WRENCH, topics.HAND_WRENCH),
                                ("contact", topics.CONTACT, topics.HAND_CONTACT)):
        chosen = _per_finger_or_hand(present, pattern, hand)
        if chosen is None:
            absent = [pattern.format(finger=f) for f in FINGERS if pattern.format(finger=f) not in present]
            missing.append(f"{', '.join(map(repr, absent))} (or '{hand}')")
        found[kind] = chosen or []
    targets = TARGETS_TOPIC in present
    if options.action == "targets" and not targets:
        missing.append(f"'{TARGETS_TOPIC}' (the action: the teleop node's motor targets; for a bag without "
                       f"teleoperation use --action positions)")
    if missing:
        has = ", ".join(sorted(present)) or "no topics at all"
        raise ExportError(f"bag {bag} has no topic {'; no topic '.join(missing)}; it has: {has}")
    return BagPlan(bag, found["taxels"], found["wrench"], found["contact"], GLOVE_TOPIC in present,
                   options.action == "targets")


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


def read_streams(plan: BagPlan) -> tuple[dict[str, _Samples], list[str]]:
    """Stream key -> its samples, and the glove's joint names (empty without a glove). Keys:
    'joint_states', 'taxels/<finger>', 'wrench/<finger>', 'contact/<finger>', 'motor_targets', 'glove'."""
    samples: dict[str, _Samples] = defaultdict(_Samples)
    glove_names: list[str] = []
    for record in read_bag(plan.bag, plan.topics()):
        topic, msg = record.topic, record.message
        if topic == topics.JOINT_STATES:
            joint = joint_sample_from_msg(msg)
            positions, velocities = _motor_vector(joint.positions), _motor_vector(joint.velocities)
            if positions is not None and velocities is not None:  # another publisher's JointState: not the motors
                samples["joint_states"].add(joint.stamp_ns, np.concatenate(
                    [positions, [rpm_to_rad_s(v) for v in velocities]]))
        elif topic == TARGETS_TOPIC:
            stamp, targets = motor_targets_from_msg(msg)
            vector = _motor_vector(targets)
            if vector is not None:
                samples["motor_targets"].add(stamp, vector)
        elif topic == GLOVE_TOPIC:
            stamp, angles = hand_pose_from_msg(msg)
            if not glove_names:
                glove_names = list(angles)
            if sorted(angles) != sorted(glove_names):
                raise ExportError(f"bag {plan.bag}: {GLOVE_TOPIC} changes its joints from {glove_names} to "
                                  f"{list(angles)} at {stamp / NS:.3f} s; export the parts apart")
            samples["glove"].add(stamp, np.array([angles[n] for n in glove_names]))
        elif topic == topics.HAND_TAXELS:
            for sample in msg.samples:
                frame = taxel_frame_from_msg(sample)
                samples[f"taxels/{frame.finger}"].add(frame.stamp_ns, frame.voltages.reshape(3, 3))
        elif topic == topics.HAND_WRENCH:
            for finger, wrench in zip(msg.fingers, msg.wrenches):
                sample = wrench_from_msg(wrench)
                samples[f"wrench/{finger}"].add(sample.stamp_ns, sample.wrench)
        elif topic == topics.HAND_CONTACT:
            for contact in msg.contacts:
                evaluation = contact_state_from_msg(contact)
                samples[f"contact/{evaluation.finger}"].add(evaluation.stamp_ns, float(evaluation.feasible))
        elif (finger := _finger_of(topic, topics.TAXELS)) is not None:
            frame = taxel_frame_from_msg(msg)
            samples[f"taxels/{finger}"].add(frame.stamp_ns, frame.voltages.reshape(3, 3))
        elif (finger := _finger_of(topic, topics.WRENCH)) is not None:
            sample = wrench_from_msg(msg)
            samples[f"wrench/{finger}"].add(sample.stamp_ns, sample.wrench)
        elif (finger := _finger_of(topic, topics.CONTACT)) is not None:
            evaluation = contact_state_from_msg(msg)
            samples[f"contact/{finger}"].add(evaluation.stamp_ns, float(evaluation.feasible))
    return samples, glove_names


def stream_topic(plan: BagPlan, key: str) -> str:
    """The topic a stream key came from, as the summary names it."""
    kind, _, finger = key.partition("/")
    if kind == "joint_states":
        return topics.JOINT_STATES
    if kind == "motor_targets":
        return TARGETS_TOPIC
    if kind == "glove":
        return GLOVE_TOPIC
    chosen = {"taxels": plan.taxels, "wrench": plan.wrench, "contact": plan.contact}[kind]
    return chosen[FINGERS.index(finger)] if len(chosen) == len(FINGERS) else f"{chosen[0]} ({finger})"


def needed_streams(plan: BagPlan) -> list[str]:
    keys = ["joint_states", *(f"{kind}/{f}" for kind in ("taxels", "wrench", "contact") for f in FINGERS)]
    return keys + (["motor_targets"] if plan.targets else []) + (["glove"] if plan.glove else [])


def features_for(glove_names: Sequence[str]) -> list[Feature]:
    motor = list(MOTOR_NAMES)
    features = [
        Feature(STATE, "float32", (6,), [f"{m}.pos" for m in motor] + [f"{m}.vel" for m in motor]),
        Feature(TACTILE, "float32", (len(FINGERS), 3, 3), ["finger", "row", "col"]),
        Feature(WRENCH, "float32", (len(FINGERS), 6), ["finger", "axis"]),
        Feature(CONTACT, "float32", (len(FINGERS),), list(FINGERS)),
    ]
    if glove_names:
        features.append(Feature(GLOVE_POSE, "float32", (len(glove_names),), list(glove_names)))
    features.append(Feature(ACTION, "float32", (len(motor),), motor))
    return features


def export_notes(options: ExportOptions) -> dict[str, Any]:
    """What meta/prisma_export.json says about the dataset as a whole."""
    action = (f"{TARGETS_TOPIC} sampled like the observations" if options.action == "targets"
              else "the next frame's motor positions (observation.state[0:3] of frame k+1)")
    return {
        "tool": "prisma-dataset export",
        "sampling": "sample-and-hold: per stream, the newest sample whose header stamp is <= the frame's instant; "
                    "a frame where a stream's newest sample is older than its max age ends the episode",
        "max_age_s": dict(options.max_age_s),
        "action": action,
        "axes": {TACTILE: {"finger": list(FINGERS), "row": "0 = bottom (taxels 0-1-2)",
                           "col": "0 = right lateral side (taxels 0-3-6)"},
                 WRENCH: {"finger": list(FINGERS), "axis": ["fx", "fy", "fz", "tx", "ty", "tz"]}},
        "units": {STATE: "rad, rad/s", TACTILE: "V", WRENCH: "N, N m", CONTACT: "1 = feasible contact",
                  GLOVE_POSE: "rad", ACTION: "rad"},
    }


def export_bag(plan: BagPlan, options: ExportOptions) -> tuple[Episode, list[str]]:
    """One bag as one episode; (the episode, the glove's joint names)."""
    samples, glove_names = read_streams(plan)
    streams = []
    for key in needed_streams(plan):
        got = samples.get(key)
        topic = stream_topic(plan, key)
        if got is None or not got.stamps:
            raise ExportError(f"bag {plan.bag}: {topic} has no usable message (a JointState needs positions and "
                              f"velocities of {', '.join(MOTOR_NAMES)}; motor targets all three motors)")
        kind = key.partition("/")[0]
        streams.append(Stream.from_samples(topic, got.stamps, np.asarray(got.values),
                                           round(options.max_age_s[kind] * NS)))
    sampled = sample_and_hold(streams, options.fps)
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
    if options.action == "targets":
        values[ACTION] = by_key["motor_targets"]
        keep = frames
    else:  # the next frame's positions: the last frame has none
        keep = frames - 1
        values[ACTION] = state[1:, :len(MOTOR_NAMES)]
    values = {name: np.asarray(v[:keep], dtype=np.float32) for name, v in values.items()}
    if keep <= 0:
        why = f": {sampled.gap.describe()}" if sampled.gap else ""
        raise ExportError(f"bag {plan.bag}: no frame has every stream within its max age{why}")
    origin = int(min(s.stamps_ns[0] for s in streams))
    ended = ("the end of the bag" if sampled.gap is None
             else f"a gap: {sampled.gap.describe(origin)}")
    notes = {
        "source": str(plan.bag), "start_s": (int(sampled.instants_ns[0]) - origin) / NS,
        "frames": keep, "ended": ended, "dropped_s": round(sampled.dropped_ns / NS, 6),
        "gap": None if sampled.gap is None else {
            "stream": sampled.gap.stream, "at_s": (sampled.gap.at_ns - origin) / NS,
            "age_s": sampled.gap.age_ns / NS, "max_age_s": sampled.gap.max_age_ns / NS},
    }
    return Episode(options.task, values, notes), glove_names


def export_bags(bags: Iterable[Path], options: ExportOptions,
                progress: Callable[[str], None] | None = None) -> Dataset:
    """Every bag as an episode of one dataset (nothing is written here). ExportError for a bag
    that lacks a needed topic, has no fresh frame, or records other features than the first bag."""
    if options.action not in ACTIONS:
        raise ExportError(f"--action {options.action!r}: choose one of {', '.join(ACTIONS)}")
    plans = [plan_bag(Path(bag), options) for bag in bags]  # every bag's topics checked before any is read
    episodes: list[Episode] = []
    features: list[Feature] | None = None
    for plan in plans:
        episode, glove_names = export_bag(plan, options)
        bag_features = features_for(glove_names)
        if features is None:
            features = bag_features
        elif bag_features != features:
            raise ExportError(f"bag {plan.bag} records other features than {plans[0].bag} "
                              f"({'with' if plan.glove else 'without'} {GLOVE_TOPIC}); export them apart")
        episodes.append(episode)
        if progress:
            progress(f"{plan.bag}: {episode.length} frames, ended by {episode.notes['ended']}")
    if features is None:
        raise ExportError("no bag given")
    return Dataset(options.fps, features, episodes, export_notes=export_notes(options))
