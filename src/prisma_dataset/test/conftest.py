"""A small demonstration bag, written with the suite's BagWriter and the owning packages' converters,
and what it holds (stream key -> [(stamp_ns, value)]) for the tests to compute each frame by hand.

Streams, as the graph publishes them: /joint_states and each finger's taxels, wrench and contact at
100 Hz (each finger 1 ms after the previous one, jittered by up to 2 ms), the teleop node's motor
targets and the glove at 60 Hz, the STAG glove's 32 x 32 frames at 7.3 fps (`stag`), and the teleop
node's episode markers (`markers`). Values are distinct per sample, so a frame that took the wrong
sample shows it.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from prisma_common import topics
from prisma_common.bag import BagWriter
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_common.typestore import types
from prisma_force_estimator.ros_conversions import hand_wrench_to_msg, wrench_to_msg
from prisma_force_estimator.wrench import WrenchSample
from prisma_manipulation.contact_monitor import ContactMonitor
from prisma_manipulation.ros_conversions import contact_state_to_msg, hand_contact_to_msg
from prisma_motor_driver.backend import MotorState
from prisma_motor_driver.ros_conversions import joint_state_to_msg
from prisma_tactile_driver.ros_conversions import hand_taxels_to_msg, taxel_frame_to_msg
from prisma_tactile_driver.taxels import TaxelFrame
from prisma_teleop.episodes import EpisodeMarker
from prisma_teleop.ros_conversions import episode_marker_to_msg, hand_pose_to_msg, motor_targets_to_msg
from stag_glove.processing import ProcessedFrame
from stag_glove.ros_conversions import glove_frame_to_msg

MS = 1_000_000
START_NS = 1_000 * MS  # the bag's first stamp
GLOVE_JOINTS = ("index_mcp", "thumb_cmc_flexion")
STAG_FPS = 7.3
STAG_SIZE = 32
EPISODE_TOPIC = "/prisma/teleop/episode"


@dataclass
class RecordedBag:
    path: Path
    streams: dict[str, list[tuple[int, Any]]] = field(default_factory=dict)  # key -> [(stamp_ns, value)]

    def add(self, key: str, stamp_ns: int, value: Any) -> None:
        self.streams.setdefault(key, []).append((stamp_ns, value))

    def at(self, key: str, instant_ns: int) -> Any:
        """The newest value of `key` stamped at or before `instant_ns` (by hand, for the tests)."""
        held = [(stamp, value) for stamp, value in self.streams[key] if stamp <= instant_ns]
        return max(held, key=lambda item: item[0])[1]


def stamp_of(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def marker(event: str, at_s: float, episode: int, task: str = "pinch the ball", outcome: str = "") -> EpisodeMarker:
    """An episode marker `at_s` seconds into the bag."""
    return EpisodeMarker(START_NS + round(at_s * 1e9), episode, event, task, outcome,
                         "engaged" if event == "start" else "let go")


def write_bag(path: Path, seconds: float = 1.0, seed: int = 0, targets: bool = True, glove: bool = False,
              gap: tuple[str, float, float] | None = None, per_hand: bool = False, stag: bool = False,
              shorted: tuple[int, ...] = (), markers: tuple[EpisodeMarker, ...] = (),
              namespace: str = "") -> RecordedBag:
    """`gap`: (stream key, from s, to s) of the bag during which that stream publishes nothing;
    `per_hand`: the fingertip samples of each scan in one HandTaxels, HandWrench and HandContact
    (each sample keeps its own stamp) instead of the per-finger topics; `stag`: the STAG glove's frames
    on /stag/frame, those numbered in `shorted` flagged shorted (and not recorded as values);
    `markers`: on /prisma/teleop/episode; `namespace`: every topic in it."""
    rng = np.random.default_rng(seed)
    recorded = RecordedBag(path)
    monitor = ContactMonitor(min_mean_voltage=1.0)

    def silent(key: str, stamp_ns: int) -> bool:
        return gap is not None and gap[0] == key and gap[1] <= (stamp_ns - START_NS) / 1e9 < gap[2]

    with BagWriter(path) as bag:
        messages: list[tuple[int, str, Any]] = []
        for k in range(int(seconds * 100)):
            base = START_NS + k * 10 * MS
            stamp = base + int(rng.integers(0, 2 * MS))
            positions = rng.uniform(-1, 9, 3)
            rpm = rng.uniform(-60, 60, 3)
            states = {m: MotorState(m, float(p), float(v), 100.0) for m, p, v in zip(MOTOR_NAMES, positions, rpm)}
            if not silent("joint_states", stamp):
                msg = joint_state_to_msg(types, stamp, states)
                messages.append((stamp, topics.JOINT_STATES, msg))
                recorded.add("joint_states", stamp, np.concatenate([msg.position, msg.velocity]))
            scan: dict[str, list[tuple[str, Any]]] = {"taxels": [], "wrench": [], "contact": []}  # (finger, msg)
            for f, finger in enumerate(FINGERS):
                stamp = base + (f + 1) * MS + int(rng.integers(0, 2 * MS))
                counts = rng.integers(0, 4096, 9).astype(np.uint16)
                voltages = (counts * 3.3 / 4096).astype(np.float32)
                if not silent(f"taxels/{finger}", stamp):
                    scan["taxels"].append((finger, taxel_frame_to_msg(
                        types, TaxelFrame(finger, stamp, counts, voltages), f"{finger}_pad")))
                    recorded.add(f"taxels/{finger}", stamp, voltages.reshape(3, 3))
                wrench = rng.normal(0, 1, 6)
                if not silent(f"wrench/{finger}", stamp):
                    scan["wrench"].append((finger, wrench_to_msg(types, WrenchSample(stamp, wrench, f"{finger}_pad"))))
                    recorded.add(f"wrench/{finger}", stamp, wrench)
                evaluation = monitor.evaluate(finger, stamp, voltages)
                if not silent(f"contact/{finger}", stamp):
                    scan["contact"].append((finger, contact_state_to_msg(types, evaluation, f"{finger}_pad")))
                    recorded.add(f"contact/{finger}", stamp, float(evaluation.feasible))
            if per_hand:
                newest = max(stamp_of(m) for _, m in scan["taxels"])
                messages.append((newest, topics.HAND_TAXELS, hand_taxels_to_msg(types, [m for _, m in scan["taxels"]])))
                messages.append((newest, topics.HAND_WRENCH, hand_wrench_to_msg(
                    types, [f for f, _ in scan["wrench"]], [m for _, m in scan["wrench"]])))
                messages.append((newest, topics.HAND_CONTACT,
                                 hand_contact_to_msg(types, [m for _, m in scan["contact"]])))
            else:
                for pattern, kind in ((topics.TAXELS, "taxels"), (topics.WRENCH, "wrench"),
                                      (topics.CONTACT, "contact")):
                    for finger, msg in scan[kind]:
                        messages.append((stamp_of(msg), pattern.format(finger=finger), msg))
        for k in range(int(seconds * 60)):
            stamp = START_NS + k * 1_000_000_000 // 60 + int(rng.integers(0, 2 * MS))
            if targets and not silent("motor_targets", stamp):
                values = dict(zip(MOTOR_NAMES, rng.uniform(0, 7, 3)))
                messages.append((stamp, "/prisma/teleop/motor_targets", motor_targets_to_msg(types, stamp, values)))
                recorded.add("motor_targets", stamp, np.array(list(values.values())))
            if glove and not silent("glove", stamp):
                angles = dict(zip(GLOVE_JOINTS, rng.uniform(0, 1.5, len(GLOVE_JOINTS))))
                messages.append((stamp, "/glove/joint_states", hand_pose_to_msg(types, stamp, angles)))
                recorded.add("glove", stamp, np.array(list(angles.values())))
        if stag:
            for k in range(int(seconds * STAG_FPS) + 1):
                stamp = START_NS + round(k * 1e9 / STAG_FPS) + int(rng.integers(0, 5 * MS))
                pressure = rng.uniform(0, 1, (STAG_SIZE, STAG_SIZE)).astype(np.float32)
                raw = (pressure * 1023).astype(np.uint16)
                frame = ProcessedFrame(stamp, raw, pressure, k in shorted, True)
                if not silent("glove_pressure", stamp):
                    messages.append((stamp, "/stag/frame", glove_frame_to_msg(types, frame, "stag_glove")))
                    if k not in shorted:
                        recorded.add("glove_pressure", stamp, pressure)
        for m in markers:
            messages.append((m.stamp_ns, EPISODE_TOPIC, episode_marker_to_msg(types, m)))
        prefix = f"/{namespace.strip('/')}" if namespace.strip("/") else ""
        for stamp, topic, msg in sorted(messages, key=lambda item: item[0]):
            bag.write(prefix + topic, msg, stamp)
    return recorded


@pytest.fixture(scope="session")
def make_bag(tmp_path_factory) -> Callable[..., RecordedBag]:
    """write_bag into a fresh directory: make_bag(name, **write_bag's options)."""
    root = tmp_path_factory.mktemp("bags")

    def make(name: str, **options: Any) -> RecordedBag:
        return write_bag(root / name, **options)

    return make


@pytest.fixture(scope="session")
def mark() -> Callable[..., EpisodeMarker]:
    """`marker`: mark(event, at_s, episode, task, outcome), at_s seconds into a bag write_bag makes."""
    return marker


@pytest.fixture(scope="session")
def bag_start_ns() -> int:
    return START_NS
