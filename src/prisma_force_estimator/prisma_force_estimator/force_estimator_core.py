"""Per-finger taxel samples -> wrenches, estimated for all fingers in one batch.

The tactile driver publishes the five fingertips of one scan with (nearly) the same stamp, one
message each. The pipeline holds samples until every configured finger has one, or until a
sample shows the scan is over (a finger repeats, or a stamp lies more than `batch_window_ns` from
the pending scan), then runs one network call per bundle for the whole scan. A finger that stops
publishing therefore delays the others by at most one scan. Used by the node and by
prisma-estimate-bag, so both produce identical wrenches. With a `WrenchBias` (the node's ~/bias)
every wrench has its finger's no-load offset subtracted once one was taken (bias.py).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .bias import WrenchBias
from .bundle import DEFAULT_PRECISION, resolve_bundle_path
from .wrench import WrenchSample, full_wrench

if TYPE_CHECKING:
    from .inference import ForceEstimator


@dataclass
class TaxelSample:
    finger: str
    stamp_ns: int
    voltages: np.ndarray  # [9]
    frame_id: str = ""


@dataclass
class FingerCounts:
    received: int = 0
    estimated: int = 0
    rejected: int = 0  # non-finite voltages: no wrench is produced


@dataclass
class WrenchPipeline:
    estimators: Mapping[str, ForceEstimator]  # finger -> estimator (fingers may share one)
    frame_id_template: str = ""  # "" keeps the input's frame id; else e.g. "{finger}_pad"
    batch_window_ns: int = 5_000_000
    counts: dict[str, FingerCounts] = field(default_factory=dict)
    ignored: int = 0  # samples of fingers this pipeline does not serve
    bias: WrenchBias | None = None  # no-load offsets measured and subtracted (None: raw estimates)
    _pending: dict[str, TaxelSample] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.estimators:
            raise ValueError("the pipeline needs at least one finger")
        if self.batch_window_ns < 0:
            raise ValueError(f"batch_window_ns must be >= 0, got {self.batch_window_ns}")
        self.counts = {finger: FingerCounts() for finger in self.estimators}

    @property
    def fingers(self) -> list[str]:
        return list(self.estimators)

    def add(self, sample: TaxelSample) -> list[tuple[str, WrenchSample]]:
        """Queue one finger's sample; returns the wrenches of any scan this completes."""
        if sample.finger not in self.estimators:
            self.ignored += 1
            return []
        self.counts[sample.finger].received += 1
        out: list[tuple[str, WrenchSample]] = []
        if self._pending:
            first = next(iter(self._pending.values()))
            if sample.finger in self._pending or abs(sample.stamp_ns - first.stamp_ns) > self.batch_window_ns:
                out += self.flush()
        self._pending[sample.finger] = sample
        if len(self._pending) == len(self.estimators):
            out += self.flush()
        return out

    def flush(self) -> list[tuple[str, WrenchSample]]:
        """Estimate every pending sample now (one batch per distinct estimator)."""
        pending = list(self._pending.values())
        self._pending.clear()
        if not pending:
            return []
        results: dict[str, np.ndarray] = {}
        groups: dict[int, list[TaxelSample]] = {}
        for sample in pending:
            groups.setdefault(id(self.estimators[sample.finger]), []).append(sample)
        for members in groups.values():
            estimator = self.estimators[members[0].finger]
            batch = np.stack([np.asarray(s.voltages, dtype=np.float32).reshape(9) for s in members])
            for sample, row in zip(members, estimator.estimate(batch)):
                results[sample.finger] = row
        out = []
        for sample in pending:
            row = results[sample.finger]
            counts = self.counts[sample.finger]
            if not np.all(np.isfinite(row)):
                counts.rejected += 1
                continue
            counts.estimated += 1
            wrench = full_wrench(row, self.estimators[sample.finger].axes)
            if self.bias is not None:
                self.bias.observe(sample.finger, sample.voltages, wrench)
                wrench = self.bias.apply(sample.finger, wrench)
            frame_id = (self.frame_id_template.format(finger=sample.finger)
                        if self.frame_id_template else sample.frame_id)
            out.append((sample.finger, WrenchSample(sample.stamp_ns, wrench, frame_id)))
        return out


def build_estimators(bundles: Mapping[str, str], threads: int | None = None,
                     precision: str = DEFAULT_PRECISION) -> dict[str, ForceEstimator]:
    """finger -> ForceEstimator, loading each distinct bundle path once."""
    from .inference import ForceEstimator

    loaded: dict[str, ForceEstimator] = {}
    estimators = {}
    for finger, path in bundles.items():
        if path not in loaded:
            loaded[path] = ForceEstimator.from_bundle(path, threads=threads, precision=precision)
        estimators[finger] = loaded[path]
    return estimators


def load_estimator(bundle: str | Path, threads: int | None = None,
                   precision: str = DEFAULT_PRECISION) -> ForceEstimator:
    """The ForceEstimator of a bundle path as the node resolves it (BundleError if it is not one).
    torch is imported here, when an estimator is loaded, not with this module."""
    from .inference import ForceEstimator

    return ForceEstimator.from_bundle(resolve_bundle_path(bundle), threads=threads, precision=precision)
