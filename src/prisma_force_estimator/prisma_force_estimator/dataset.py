"""Training data for the force estimator and its contiguous-block train/validation split.

A `ForceDataset` is the plain-array view every source is reduced to: synthetic calibration
sets from the tactile driver's pad model, saved .npz calibration sets, or real calibration bags
(calibration_bag.py). `block` groups samples that must land on the same side of the split
(one synthetic trajectory, or one recording).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prisma_hand_sim.calibration import CalibrationSet, generate_calibration_set

from .wrench import WRENCH_AXES


@dataclass
class ForceDataset:
    voltages: np.ndarray  # float32 [N, 9], taxel i = 3*row + col
    wrench: np.ndarray  # float32 [N, 6]: fx, fy, fz (N), tx, ty, tz (N*m about the pad centre)
    stamp_ns: np.ndarray  # int64 [N]
    block: np.ndarray  # int64 [N], id of the contiguous group (trajectory / recording)
    source: str = ""

    def __post_init__(self) -> None:
        self.voltages = np.asarray(self.voltages, dtype=np.float32)
        self.wrench = np.asarray(self.wrench, dtype=np.float32)
        self.stamp_ns = np.asarray(self.stamp_ns, dtype=np.int64)
        self.block = np.asarray(self.block, dtype=np.int64)
        n = self.voltages.shape[0]
        if self.voltages.shape != (n, 9):
            raise ValueError(f"voltages must have shape [N, 9], got {self.voltages.shape}")
        if self.wrench.shape != (n, len(WRENCH_AXES)):
            raise ValueError(f"wrench must have shape [{n}, 6], got {self.wrench.shape}")
        if self.stamp_ns.shape != (n,) or self.block.shape != (n,):
            raise ValueError(f"stamp_ns and block must have shape [{n}], got "
                             f"{self.stamp_ns.shape} and {self.block.shape}")

    def __len__(self) -> int:
        return int(self.voltages.shape[0])

    def subset(self, index: np.ndarray) -> ForceDataset:
        return ForceDataset(self.voltages[index], self.wrench[index], self.stamp_ns[index],
                            self.block[index], self.source)

    def targets(self, axes: tuple[str, ...] | list[str]) -> np.ndarray:
        """The wrench columns named by `axes`, in that order."""
        return self.wrench[:, [WRENCH_AXES.index(a) for a in axes]]

    @classmethod
    def from_calibration_set(cls, calibration, source: str = "synthetic") -> ForceDataset:
        """From a prisma_hand_sim.calibration.CalibrationSet (trajectory ids become blocks)."""
        return cls(calibration.voltages, calibration.wrench, calibration.stamp_ns,
                   calibration.trajectory, source)


def synthetic_dataset(n_samples: int = 140_000, seed: int = 0) -> ForceDataset:
    """The tactile driver's default synthetic calibration set (push, slide and roll trajectories)."""
    calibration = generate_calibration_set(n_samples=n_samples, seed=seed)
    return ForceDataset.from_calibration_set(calibration, f"synthetic(n={n_samples}, seed={seed})")


def load_calibration_npz(path: str | Path) -> ForceDataset:
    """A CalibrationSet saved with CalibrationSet.save()."""
    return ForceDataset.from_calibration_set(CalibrationSet.load(path), str(path))


def _runs(block: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of equal consecutive block ids."""
    if len(block) == 0:
        return []
    edges = np.flatnonzero(np.diff(block)) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [len(block)]])
    return list(zip(starts.tolist(), stops.tolist()))


@dataclass(frozen=True)
class Split:
    train: np.ndarray  # int64 indices
    validation: np.ndarray  # int64 indices
    dropped: int  # guard samples that belong to neither side


def contiguous_block_split(block: np.ndarray, val_fraction: float = 0.2, seed: int = 0,
                           min_chunks: int = 20, guard: int = 10) -> Split:
    """Split sample indices into train/validation by whole contiguous chunks.

    Chunks are the runs of equal `block` id (trajectories). When there are fewer than
    `min_chunks` of them (a single recording), each run is cut into equal contiguous pieces so
    there are about `min_chunks`; `guard` samples either side of such an artificial cut are
    dropped, because neighbouring samples of one trajectory are nearly identical and would leak
    validation data into training. Chunks are drawn for validation in a seeded random order
    until `val_fraction` of the samples are taken.
    """
    if not 0.0 < val_fraction < 1.0:
        raise ValueError(f"val_fraction must be in (0, 1), got {val_fraction}")
    block = np.asarray(block)
    runs = _runs(block)
    if len(runs) < 2 and len(block) < 2:
        raise ValueError(f"need at least 2 samples to split, got {len(block)}")
    chunks: list[tuple[int, int, bool]] = []  # start, stop, cut_inside_a_run
    pieces_per_run = max(1, int(np.ceil(min_chunks / max(len(runs), 1)))) if len(runs) < min_chunks else 1
    for start, stop in runs:
        bounds = np.linspace(start, stop, pieces_per_run + 1).round().astype(int)
        for a, b in zip(bounds[:-1], bounds[1:]):
            if b > a:
                chunks.append((int(a), int(b), pieces_per_run > 1))
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(chunks))
    target = val_fraction * len(block)
    is_val = np.zeros(len(chunks), dtype=bool)
    taken = 0
    for c in order:
        if taken >= target:
            break
        if len(chunks) - is_val.sum() <= 1:
            break  # always keep at least one training chunk
        is_val[c] = True
        taken += chunks[c][1] - chunks[c][0]
    side = np.empty(len(block), dtype=np.int8)  # 1 = validation, 0 = train, -1 = guard
    for (a, b, _), val in zip(chunks, is_val):
        side[a:b] = 1 if val else 0
    if guard > 0:
        for (a, b, cut), (a2, _, cut2) in zip(chunks[:-1], chunks[1:]):
            # Only cuts inside one run need a guard; trajectories are independent of each other.
            same_run = cut and cut2 and block[b - 1] == block[a2]
            if same_run and side[b - 1] != side[a2] and side[b - 1] >= 0 and side[a2] >= 0:
                side[max(a, b - guard):b] = -1
                side[a2:a2 + guard] = -1
    return Split(np.flatnonzero(side == 0), np.flatnonzero(side == 1), int((side == -1).sum()))
