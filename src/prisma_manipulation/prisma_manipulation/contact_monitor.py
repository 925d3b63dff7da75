"""Algorithm 1 contact monitor: is the contact on a fingertip still safe to manipulate with?

Per sample of one finger: v_a = mean of the 9 voltages, v_t = K * v_a, taxel i is safe when
v_i >= v_t, an edge (bottom 0-1-2, top 6-7-8, right 0-3-6, left 2-5-8) is lost when all three of its
taxels are below v_t, and the contact is feasible when no edge is lost and v_a reaches
`min_mean_voltage` (0 disables that check; with it, an untouched pad, whose taxels all sit near
their rest voltage, is not reported as a feasible contact).

K can change at run time (`set_k`, the manipulation node's parameter callback): the next
evaluated sample uses it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prisma_common.hand import N_TAXELS
from prisma_tactile_driver.taxels import EDGES

EDGE_NAMES = ("bottom", "top", "right", "left")  # ContactState order
_EDGE_INDEX = np.array([EDGES[name] for name in EDGE_NAMES])  # (4, 3)
K_RANGE = (0.0, 1.5)  # exclusive low, inclusive high: K > 1 is legal but flags most taxels unsafe


def check_k(k: float) -> float:
    k = float(k)
    if not math.isfinite(k) or not K_RANGE[0] < k <= K_RANGE[1]:
        raise ValueError(f"k {k} outside ({K_RANGE[0]}, {K_RANGE[1]}]")
    return k


@dataclass(frozen=True)
class ContactEvaluation:
    finger: str
    stamp_ns: int
    voltages: np.ndarray  # float32[9]
    mean_voltage: float  # v_a
    k: float
    threshold: float  # v_t = k * v_a
    safe: np.ndarray  # bool[9]
    lost_edges: tuple[str, ...]  # subset of EDGE_NAMES, in that order
    feasible: bool

    def safe_count(self, edge: str) -> int:
        """How many of an edge's three taxels are at or above the threshold."""
        return int(self.safe[list(EDGES[edge])].sum())


DEFAULT_K = 0.8  # the manipulation node's k and every paper scenario's (the hold needs K > 0.6)


class ContactMonitor:
    def __init__(self, k: float = DEFAULT_K, min_mean_voltage: float = 0.0) -> None:
        self.k = check_k(k)
        if not math.isfinite(min_mean_voltage) or min_mean_voltage < 0:
            raise ValueError(f"min_mean_voltage {min_mean_voltage} must be >= 0")
        self.min_mean_voltage = float(min_mean_voltage)

    def set_k(self, k: float) -> None:
        self.k = check_k(k)

    def evaluate(self, finger: str, stamp_ns: int, voltages: np.ndarray) -> ContactEvaluation:
        v = np.asarray(voltages, dtype=np.float32).reshape(N_TAXELS)
        mean = float(v.mean(dtype=np.float64))
        threshold = self.k * mean
        safe = v >= threshold
        lost_mask = ~safe[_EDGE_INDEX].any(axis=1)
        lost = tuple(name for name, is_lost in zip(EDGE_NAMES, lost_mask) if is_lost)
        feasible = not lost and mean >= self.min_mean_voltage and math.isfinite(mean)
        return ContactEvaluation(finger, int(stamp_ns), v, mean, self.k, threshold, safe, lost, feasible)

    def evaluate_many(self, stamp_ns: int, voltages: dict[str, np.ndarray]) -> dict[str, ContactEvaluation]:
        return {finger: self.evaluate(finger, stamp_ns, v) for finger, v in voltages.items()}


def first_lost_index(voltages: np.ndarray, k: float, edge: str, start: int = 0) -> int | None:
    """Index of the first sample (>= start) of a [T, 9] voltage record whose `edge` taxels are all
    below k * mean: the reference the closed-loop tests compare stop times against."""
    v = np.asarray(voltages, dtype=np.float64)
    threshold = k * v.mean(axis=1, keepdims=True)
    lost = (v[:, list(EDGES[edge])] < threshold).all(axis=1)
    hits = np.flatnonzero(lost[start:])
    return int(hits[0]) + start if hits.size else None
