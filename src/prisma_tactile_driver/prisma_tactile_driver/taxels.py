"""Core taxel data: one fingertip sample of 3x3 optoelectronic taxels.

Taxel numbering (docs/architecture.md, Interfaces): index i = 3*row + col; row 0 = bottom (0-1-2),
row 2 = top (6-7-8); column 0 = right lateral side (0-3-6), column 2 = left lateral side (2-5-8).
Counts are 12-bit MAX11617 readings; V = vref * counts / 4096.
"""
from __future__ import annotations

from dataclasses import dataclass

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
    """One fingertip sample: raw counts and V = vref*counts/4096 (nothing subtracted: Algorithm 1
    compares raw voltages; the force estimator's ~/bias zeroes the wrenches instead)."""

    finger: str
    stamp_ns: int
    counts: np.ndarray  # uint16[9]
    voltages: np.ndarray  # float32[9]

    def __post_init__(self) -> None:
        self.counts = np.asarray(self.counts, dtype=np.uint16).reshape(-1)
        self.voltages = np.asarray(self.voltages, dtype=np.float32).reshape(-1)
        if self.counts.shape != (N_TAXELS,) or self.voltages.shape != (N_TAXELS,):
            raise ValueError(
                f"TaxelFrame needs 9 counts and 9 voltages, got {self.counts.shape} and {self.voltages.shape}"
            )
        self.stamp_ns = int(self.stamp_ns)

    @classmethod
    def from_counts(cls, finger: str, stamp_ns: int, counts: np.ndarray, vref: float = DEFAULT_VREF) -> TaxelFrame:
        counts = np.asarray(counts, dtype=np.uint16)
        return cls(finger, stamp_ns, counts, counts_to_voltages(counts, vref))
