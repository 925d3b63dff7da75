"""Bias: each fingertip's no-load wrench measured and subtracted, as an F/T sensor's bias service
zeroes its wrench.

A network's estimate for an untouched pad is not exactly zero (the pad's rest voltages drift with
temperature and LED ageing; a bundle trained on another pad sees them slightly off). `WrenchBias`
keeps each finger's last `samples` raw estimates with the mean voltage of their taxels. `take()`
makes the mean of every finger's window its offset, subtracted from each of its wrenches from then
on (all six axes; axes the model lacks stay NaN), all fingers or none. It is refused, leaving the
offsets as they were, while a finger has fewer than `samples` estimates, or while a finger is in
contact: the rule is the mean of its nine taxel voltages at or above `contact_voltage` (0.55 V, the
manipulation node's min_mean_voltage; an untouched pad sits at its ~0.43 V rest voltages) in any
sample of the window. The taxel voltages decide, not the estimated force, because the force is the
thing being corrected.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

DEFAULT_SAMPLES = 100
DEFAULT_CONTACT_VOLTAGE = 0.55


@dataclass(frozen=True)
class BiasResult:
    success: bool
    message: str
    warning: bool = False  # taken, but something the operator must know (not saved to the hand directory)


class WrenchBias:
    def __init__(self, fingers: Iterable[str], samples: int = DEFAULT_SAMPLES,
                 contact_voltage: float = DEFAULT_CONTACT_VOLTAGE) -> None:
        if samples < 1:
            raise ValueError(f"bias samples {samples} must be >= 1")
        self.samples = samples
        self.contact_voltage = contact_voltage
        self._mean_volts: dict[str, deque] = {f: deque(maxlen=samples) for f in fingers}
        self._wrenches: dict[str, deque] = {f: deque(maxlen=samples) for f in self._mean_volts}
        self.offsets: dict[str, np.ndarray] = {}  # finger -> [6] subtracted from its wrenches

    def observe(self, finger: str, voltages: np.ndarray, raw_wrench: np.ndarray) -> None:
        """One raw estimate of `finger` and the voltages it was estimated from."""
        if finger in self._wrenches:
            self._mean_volts[finger].append(float(np.mean(voltages)))
            self._wrenches[finger].append(np.asarray(raw_wrench, dtype=np.float64))

    def apply(self, finger: str, raw_wrench: np.ndarray) -> np.ndarray:
        offset = self.offsets.get(finger)
        return raw_wrench if offset is None else raw_wrench - offset

    def take(self) -> BiasResult:
        short = {f: len(w) for f, w in self._wrenches.items() if len(w) < self.samples}
        if short:
            detail = ", ".join(f"{f} {n}/{self.samples}" for f, n in short.items())
            return BiasResult(False, f"refused: not enough samples yet: {detail}")
        touched = {f: max(v) for f, v in self._mean_volts.items() if max(v) >= self.contact_voltage}
        if touched:
            detail = ", ".join(f"{f} (taxel mean {v:.2f} V)" for f, v in touched.items())
            return BiasResult(False, f"refused: in contact: {detail}, at or above {self.contact_voltage} V; "
                                     "take the bias with nothing touching the pads")
        self.offsets = {f: np.mean(np.stack(w), axis=0) for f, w in self._wrenches.items()}
        detail = "; ".join(f"{f} Fz {o[2]:+.4f} N" for f, o in self.offsets.items())
        return BiasResult(True, f"biased over {self.samples} samples: {detail}")

    def restore(self, offsets: Mapping[str, np.ndarray]) -> None:
        """Offsets saved by an earlier take() (the hand directory's force_bias.yaml), for the
        fingers this bias serves; the others keep none."""
        self.offsets = {f: np.asarray(o, dtype=np.float64) for f, o in offsets.items() if f in self._wrenches}

    def describe(self, finger: str) -> str:
        """The finger's offset for /diagnostics: fx fy fz (N) tx ty tz (N*m), or none."""
        offset = self.offsets.get(finger)
        return "none" if offset is None else " ".join(f"{v:.4f}" for v in offset)
