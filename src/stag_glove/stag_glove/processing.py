"""Frame processing core (docs/glove.md): normalisation, shorted-frame rejection, empty-hand
calibration and the contact flag.

Raw frames are 10-bit counts [rows, cols] (0..1023 = 0..5 V). The useful signal of the STAG
sensors lies in 500..650 counts, which maps to pressure 0..1 (clipped). A reading above 950 means
two electrodes are shorted, which makes the whole frame untrustworthy, so it is dropped. A frame has
contact when any sensor exceeds that sensor's maximum over an empty-hand recording (plus a margin,
so quantisation noise at the maximum does not flicker the flag).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

ADC_MAX = 1023


@dataclass(frozen=True)
class NormalisationConfig:
    low: float = 500.0     # counts mapped to pressure 0
    high: float = 650.0    # counts mapped to pressure 1
    short_threshold: int = 950  # any reading above this marks a shorted frame
    contact_margin: float = 0.05  # pressure above the empty-hand maximum needed for contact (~2.5 noise sd)

    def __post_init__(self) -> None:
        if not self.high > self.low:
            raise ValueError(f"normalisation high ({self.high}) must exceed low ({self.low})")
        if not 0 < self.short_threshold <= ADC_MAX:
            raise ValueError(f"short_threshold must be in 1..{ADC_MAX}, got {self.short_threshold}")
        if self.contact_margin < 0:
            raise ValueError(f"contact_margin must be >= 0, got {self.contact_margin}")


def normalise(raw: np.ndarray, low: float = NormalisationConfig.low,
              high: float = NormalisationConfig.high) -> np.ndarray:
    """Counts -> pressure 0..1 (float32), clipped; works on one frame or a stack."""
    scale = np.float32(1.0 / (high - low))
    out = (np.asarray(raw, dtype=np.float32) - np.float32(low)) * scale
    return np.clip(out, 0.0, 1.0, out=out)


def is_shorted(raw: np.ndarray, threshold: int = 950, mask: np.ndarray | None = None) -> bool:
    """True when any reading (inside `mask` if given) exceeds `threshold`."""
    raw = np.asarray(raw)
    values = raw[mask] if mask is not None else raw
    return bool((values > threshold).any())


def shorted_frames(raw: np.ndarray, threshold: int = 950) -> np.ndarray:
    """Per-frame shorted flag for a stack [N, rows, cols]."""
    raw = np.asarray(raw)
    return np.asarray((raw.reshape(raw.shape[0], -1) > threshold).any(axis=1))


@dataclass
class EmptyHandCalibration:
    """Per-sensor maximum pressure over an empty-hand recording (no object touched)."""

    maximum: np.ndarray  # float32 [rows, cols], normalised pressure
    frames_used: int

    @classmethod
    def from_frames(cls, raw_frames: np.ndarray, config: NormalisationConfig = NormalisationConfig()
                    ) -> EmptyHandCalibration:
        """Calibrate from raw counts [N, rows, cols]; shorted frames are left out."""
        raw_frames = np.asarray(raw_frames)
        if raw_frames.ndim != 3 or raw_frames.shape[0] == 0:
            raise ValueError(f"empty-hand recording must be [N>=1, rows, cols], got {raw_frames.shape}")
        good = ~shorted_frames(raw_frames, config.short_threshold)
        if not good.any():
            raise ValueError(f"all {raw_frames.shape[0]} empty-hand frames are shorted")
        pressure = normalise(raw_frames[good], config.low, config.high)
        return cls(pressure.max(axis=0), int(good.sum()))


@dataclass
class ProcessedFrame:
    stamp_ns: int
    raw: np.ndarray        # uint16 [rows, cols]
    pressure: np.ndarray   # float32 [rows, cols], 0..1
    shorted: bool
    contact: bool
    sequence: int = -1     # readout sequence number when known


@dataclass
class FrameProcessor:
    """Normalise, flag shorted frames, and flag contact against the empty-hand calibration.

    Without a calibration the empty-hand maximum is taken as zero pressure, so any sensor above
    `contact_margin` counts as contact."""

    config: NormalisationConfig = field(default_factory=NormalisationConfig)
    calibration: EmptyHandCalibration | None = None
    mask: np.ndarray | None = None  # sensor cells for the contact flag; None = every cell

    def process(self, raw: np.ndarray, stamp_ns: int, sequence: int = -1) -> ProcessedFrame:
        raw = np.asarray(raw)
        if raw.ndim != 2:
            raise ValueError(f"a glove frame is [rows, cols], got shape {raw.shape}")
        cfg = self.config
        pressure = normalise(raw, cfg.low, cfg.high)
        # every cell counts: a high reading where no sensor sits still means a row/column short
        shorted = is_shorted(raw, cfg.short_threshold)
        contact = False if shorted else self.has_contact(pressure)
        return ProcessedFrame(int(stamp_ns), raw.astype(np.uint16, copy=False), pressure, shorted,
                              contact, sequence)

    def has_contact(self, pressure: np.ndarray) -> bool:
        baseline = 0.0 if self.calibration is None else self.calibration.maximum
        if self.calibration is not None and self.calibration.maximum.shape != pressure.shape:
            raise ValueError(f"calibration shape {self.calibration.maximum.shape} does not match "
                             f"frame shape {pressure.shape}")
        above = pressure > baseline + self.config.contact_margin
        if self.mask is not None:
            above &= self.mask
        return bool(above.any())

    def calibrate(self, raw_frames: np.ndarray) -> EmptyHandCalibration:
        self.calibration = EmptyHandCalibration.from_frames(raw_frames, self.config)
        return self.calibration
