"""Real calibration data: a taxel topic and a reference F/T sensor topic recorded in one bag.

Taxel samples (prisma_msgs/TaxelArray) are paired with the reference wrench
(geometry_msgs/WrenchStamped) whose header stamp is nearest, if it lies within `tolerance_ns`.
Samples without a partner are counted, never silently dropped. The reference wrench must already
be expressed about the pad centre in the pad frame (see docs/force_estimation.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prisma_common.bag import read_bag, require_topics
from prisma_tactile_driver.ros_conversions import taxel_frame_from_msg

from .dataset import ForceDataset
from .ros_conversions import wrench_from_msg


@dataclass
class PairingReport:
    taxel_messages: int
    wrench_messages: int
    matched: int
    unmatched_taxels: int  # no reference wrench within the tolerance
    unused_wrenches: int  # reference wrenches no taxel sample was paired with
    tolerance_ns: int
    max_offset_ns: int  # largest |taxel stamp - wrench stamp| among the pairs

    def summary(self) -> str:
        return (f"{self.matched} pairs from {self.taxel_messages} taxel and {self.wrench_messages} wrench "
                f"messages (tolerance {self.tolerance_ns / 1e6:g} ms); {self.unmatched_taxels} taxel "
                f"samples unmatched, {self.unused_wrenches} wrenches unused, largest offset "
                f"{self.max_offset_ns / 1e6:.3f} ms")


def pair_by_stamp(taxel_ns: np.ndarray, wrench_ns: np.ndarray, tolerance_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """For each taxel stamp, the index of the nearest wrench stamp or -1; also |offset|.

    `wrench_ns` must be sorted ascending.
    """
    taxel_ns = np.asarray(taxel_ns, dtype=np.int64)
    wrench_ns = np.asarray(wrench_ns, dtype=np.int64)
    partner = np.full(len(taxel_ns), -1, dtype=np.int64)
    offset = np.zeros(len(taxel_ns), dtype=np.int64)
    if len(wrench_ns) == 0 or len(taxel_ns) == 0:
        return partner, offset
    right = np.clip(np.searchsorted(wrench_ns, taxel_ns), 0, len(wrench_ns) - 1)
    left = np.clip(right - 1, 0, len(wrench_ns) - 1)
    d_right = np.abs(wrench_ns[right] - taxel_ns)
    d_left = np.abs(wrench_ns[left] - taxel_ns)
    nearest = np.where(d_left <= d_right, left, right)
    offset = np.minimum(d_left, d_right)
    ok = offset <= tolerance_ns
    partner[ok] = nearest[ok]
    return partner, offset


def load_calibration_bag(path: str | Path, taxel_topic: str = "/prisma/thumb/taxels",
                         wrench_topic: str = "/ft_sensor/wrench",
                         tolerance_ns: int = 5_000_000) -> tuple[ForceDataset, PairingReport]:
    """Pair one finger's taxel samples with the reference wrench by header stamp.

    A bag lacking either topic raises MissingTopicsError (a ValueError) naming it and the topics
    the bag has; a topic without messages raises ValueError naming it."""
    if tolerance_ns < 0:
        raise ValueError(f"tolerance_ns must be >= 0, got {tolerance_ns}")
    taxel_stamps, voltages, wrench_stamps, wrenches = [], [], [], []
    # prisma_bringup depends on this package; importing its bag layer here, not at module level,
    # keeps the ROS package graph acyclic (colcon refuses cycles).
    require_topics(path, [taxel_topic, wrench_topic])
    for record in read_bag(path, topics=[taxel_topic, wrench_topic]):
        if record.topic == taxel_topic:
            frame = taxel_frame_from_msg(record.message)
            taxel_stamps.append(frame.stamp_ns)
            voltages.append(np.asarray(frame.voltages, dtype=np.float32))
        else:
            sample = wrench_from_msg(record.message)
            wrench_stamps.append(sample.stamp_ns)
            wrenches.append(sample.wrench)
    if not taxel_stamps:
        raise ValueError(f"bag {path} has no messages on the taxel topic {taxel_topic!r}")
    if not wrench_stamps:
        raise ValueError(f"bag {path} has no messages on the reference topic {wrench_topic!r}")
    taxel_ns = np.asarray(taxel_stamps, dtype=np.int64)
    order = np.argsort(taxel_ns, kind="stable")
    taxel_ns = taxel_ns[order]
    v = np.stack(voltages)[order]
    w_ns = np.asarray(wrench_stamps, dtype=np.int64)
    w_order = np.argsort(w_ns, kind="stable")
    w_ns, w = w_ns[w_order], np.stack(wrenches)[w_order]
    partner, offset = pair_by_stamp(taxel_ns, w_ns, tolerance_ns)
    matched = partner >= 0
    report = PairingReport(
        taxel_messages=len(taxel_ns),
        wrench_messages=len(w_ns),
        matched=int(matched.sum()),
        unmatched_taxels=int((~matched).sum()),
        unused_wrenches=int(len(w_ns) - len(np.unique(partner[matched]))),
        tolerance_ns=int(tolerance_ns),
        max_offset_ns=int(offset[matched].max()) if matched.any() else 0,
    )
    # Non-finite samples cannot be trained on; they count as unmatched.
    finite = matched.copy()
    finite[matched] = np.isfinite(v[matched]).all(1) & np.isfinite(w[partner[matched]]).all(1)
    report.unmatched_taxels += int(matched.sum() - finite.sum())
    report.matched = int(finite.sum())
    dataset = ForceDataset(v[finite], w[partner[finite]], taxel_ns[finite],
                           np.zeros(int(finite.sum()), dtype=np.int64), f"bag {path} ({taxel_topic} vs {wrench_topic})")
    return dataset, report
