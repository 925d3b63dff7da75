"""A stamped wrench estimate, the core data the converters turn into WrenchStamped."""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

WRENCH_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")


@dataclass
class WrenchSample:
    stamp_ns: int
    wrench: np.ndarray  # float64 [6]: fx, fy, fz (N), tx, ty, tz (N*m); NaN = not estimated
    frame_id: str = ""


def full_wrench(values: Iterable[float], axes: Sequence[str]) -> np.ndarray:
    """Place a model's outputs (named by `axes`) into a 6-vector; axes it lacks are NaN.

    NaN rather than 0: a force-only model knows nothing about torque, and a zero would read as
    a measurement.
    """
    wrench = np.full(len(WRENCH_AXES), np.nan)
    for value, axis in zip(values, axes):
        wrench[WRENCH_AXES.index(axis)] = float(value)
    return wrench
