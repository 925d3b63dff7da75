"""Core taxel data: one fingertip sample of 3x3 optoelectronic taxels.

Taxel numbering (docs/architecture.md, Interfaces): index i = 3*row + col; row 0 = bottom (0-1-2),
row 2 = top (6-7-8); column 0 = right lateral side (0-3-6), column 2 = left lateral side (2-5-8).
Counts are 12-bit MAX11617 readings; V = vref * counts / 4096.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from prisma_common.hand import DEFAULT_VREF, N_TAXELS, counts_to_voltages

# Taxel indices of each pad edge, as Algorithm 1 and the ContactState message name them.
EDGES: dict[str, tuple[int, int, int]] = {
    "bottom": (0, 1, 2),
    "top": (6, 7, 8),
    "right": (0, 3, 6),
    "left": (2, 5, 8),
}


@dataclass
class TaxelFrame:
    """One fingertip sample. `baseline` (volts, from a tare) is kept beside the raw values, never
    subtracted in place, so published counts and voltages always satisfy V = vref*counts/4096."""

    finger: str
    stamp_ns: int
    counts: np.ndarray  # uint16[9]
    voltages: np.ndarray  # float32[9]
    baseline: np.ndarray | None = None  # float32[9] volts, None until tared

    def __post_init__(self) -> None:
        self.counts = np.asarray(self.counts, dtype=np.uint16).reshape(-1)
        self.voltages = np.asarray(self.voltages, dtype=np.float32).reshape(-1)
        if self.counts.shape != (N_TAXELS,) or self.voltages.shape != (N_TAXELS,):
            raise ValueError(
                f"TaxelFrame needs 9 counts and 9 voltages, got {self.counts.shape} and {self.voltages.shape}"
            )
        if self.baseline is not None:
            self.baseline = np.asarray(self.baseline, dtype=np.float32).reshape(N_TAXELS)
        self.stamp_ns = int(self.stamp_ns)

    @classmethod
    def from_counts(cls, finger: str, stamp_ns: int, counts: np.ndarray, vref: float = DEFAULT_VREF,
                    baseline: np.ndarray | None = None) -> TaxelFrame:
        counts = np.asarray(counts, dtype=np.uint16)
        return cls(finger, stamp_ns, counts, counts_to_voltages(counts, vref), baseline)

    def tared_voltages(self) -> np.ndarray:
        """Voltages minus the tare baseline (raw voltages when not tared)."""
        if self.baseline is None:
            return self.voltages.copy()
        return (self.voltages - self.baseline).astype(np.float32)


@dataclass
class TareBuffer:
    """Keeps the last `n_samples` voltage vectors of one finger; tare = their mean."""

    n_samples: int = 100
    _recent: deque = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.n_samples < 1:
            raise ValueError(f"tare n_samples must be >= 1, got {self.n_samples}")
        self._recent = deque(maxlen=self.n_samples)

    def add(self, voltages: np.ndarray) -> None:
        self._recent.append(np.asarray(voltages, dtype=np.float64).reshape(N_TAXELS))

    def __len__(self) -> int:
        return len(self._recent)

    @property
    def ready(self) -> bool:
        return len(self._recent) == self.n_samples

    def baseline(self) -> np.ndarray:
        """Mean of the buffered samples; ValueError while fewer than n_samples are held."""
        if not self.ready:
            raise ValueError(f"tare needs {self.n_samples} samples, have {len(self._recent)}")
        return np.mean(np.stack(self._recent), axis=0).astype(np.float32)
