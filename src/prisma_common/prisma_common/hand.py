"""The hand's names and its fingertip pads: the five fingers, the three motors (also the
/joint_states names), taxel numbering and the pads' 12-bit ADC counts <-> volts.

Taxel numbering (docs/architecture.md, Interfaces): index i = 3*row + col; row 0 = bottom (0-1-2),
row 2 = top (6-7-8); column 0 = right lateral side (0-3-6), column 2 = left lateral side (2-5-8).
Counts are 12-bit MAX11617 readings; V = vref * counts / 4096.
"""
from __future__ import annotations

import numpy as np

FINGERS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "little")
N_TAXELS = 9
# centre-to-centre spacing of the 3x3 taxels on a pad: the description's taxel_pitch (dimensions.xacro,
# tied by prisma_description's test_urdf), the pad model's and the tactile markers' default
TAXEL_PITCH_M = 0.004
ADC_BITS = 12
ADC_LEVELS = 1 << ADC_BITS  # 4096: V = vref * counts / ADC_LEVELS
ADC_MAX = ADC_LEVELS - 1
DEFAULT_VREF = 3.3
MOTOR_NAMES = ("fingers", "thumb_flexion", "thumb_rotation")


def check_finger(finger: str) -> str:
    if finger not in FINGERS:
        raise ValueError(f"unknown finger {finger!r}; expected one of {FINGERS}")
    return finger


def counts_to_voltages(counts: np.ndarray, vref: float = DEFAULT_VREF) -> np.ndarray:
    """12-bit counts -> volts (float32), any shape."""
    if vref <= 0:
        raise ValueError(f"vref must be > 0, got {vref}")
    return (np.asarray(counts, dtype=np.float32) * np.float32(vref / ADC_LEVELS)).astype(np.float32)


def voltages_to_counts(voltages: np.ndarray, vref: float = DEFAULT_VREF) -> np.ndarray:
    """Volts -> the 12-bit count an ideal ADC would report (rounded, clipped to 0..4095)."""
    if vref <= 0:
        raise ValueError(f"vref must be > 0, got {vref}")
    counts = np.rint(np.asarray(voltages, dtype=np.float64) * (ADC_LEVELS / vref))
    return np.clip(counts, 0, ADC_MAX).astype(np.uint16)
