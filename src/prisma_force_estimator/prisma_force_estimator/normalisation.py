"""Per-channel z-score normalisation of taxel inputs and wrench outputs.

The statistics come from the training split only and travel in the bundle metadata, so the
inference core applies exactly what training used.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# A channel that never varies (a dead taxel, a torque axis of a pure-push set) would divide by
# zero; such channels are only centred.
_MIN_STD = 1e-8


@dataclass(frozen=True)
class Normaliser:
    mean: np.ndarray  # float64 [C]
    std: np.ndarray  # float64 [C], strictly positive

    @classmethod
    def fit(cls, values: np.ndarray) -> Normaliser:
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 2 or values.shape[0] < 2:
            raise ValueError(f"need at least two samples of shape [N, C] to fit, got {values.shape}")
        std = values.std(axis=0)
        return cls(values.mean(axis=0), np.where(std > _MIN_STD, std, 1.0))

    @classmethod
    def identity(cls, channels: int) -> Normaliser:
        return cls(np.zeros(channels), np.ones(channels))

    @property
    def channels(self) -> int:
        return int(self.mean.shape[0])

    def apply(self, values: np.ndarray) -> np.ndarray:
        return ((np.asarray(values, dtype=np.float64) - self.mean) / self.std).astype(np.float32)

    def invert(self, values: np.ndarray) -> np.ndarray:
        return np.asarray(values, dtype=np.float64) * self.std + self.mean

    def to_dict(self) -> dict:
        return {"mean": [float(v) for v in self.mean], "std": [float(v) for v in self.std]}

    @classmethod
    def from_dict(cls, data: dict) -> Normaliser:
        mean = np.asarray(data["mean"], dtype=np.float64)
        std = np.asarray(data["std"], dtype=np.float64)
        if mean.ndim != 1 or mean.shape != std.shape:
            raise ValueError(f"mean and std must be equal-length lists, got {mean.shape} and {std.shape}")
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std > 0)):
            raise ValueError("mean must be finite and std finite and positive")
        return cls(mean, std)
