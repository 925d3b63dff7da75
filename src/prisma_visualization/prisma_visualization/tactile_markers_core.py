"""What RViz draws on each fingertip pad: the nine taxels coloured by Algorithm 1's decision, the
contact's position and the normal force.

Input is what the graph already computes, never a second evaluation: the manipulation node's
ContactState of a sample (voltages, v_t = K v_a with the K it runs with, and the per-taxel `safe`
decision) and the force estimator's wrench. A taxel's colour carries that decision: red where the
ContactState says safe (v_i >= v_t), blue where not, deeper the further the voltage is from v_t.

The contact's position is the centroid of the taxels above v_t weighted by how far above they are
(the pad model raises the taxels under a contact), drawn only while the estimated normal force Fz
reaches `contact_force_n`; the force is an arrow along the pad's normal, pointing into the pad,
`arrow_m_per_n` long per newton. Positions are in the pad frame (metres): taxel i = 3 row + col at
((col - 1) pitch, (row - 1) pitch, 0), z out of the pad; frames are the ContactState's header frame,
so a namespaced or prefixed hand draws on its own pads.

The display takes the newest of each; `take_drawings` returns the pads whose input changed since the
last call, so a display timer publishes at its own rate (not per sample) and nothing when the graph
is quiet.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prisma_common.hand import N_TAXELS
from prisma_force_estimator.wrench import WrenchSample
from prisma_manipulation.contact_monitor import ContactEvaluation

from .node_config import TactileMarkersConfig

Rgba = tuple[float, float, float, float]
Point = tuple[float, float, float]

SAFE_PALE: Rgba = (1.0, 0.80, 0.25, 1.0)  # just above v_t
SAFE_DEEP: Rgba = (0.85, 0.05, 0.05, 1.0)  # far above
LOST_PALE: Rgba = (0.55, 0.75, 1.0, 1.0)  # just below v_t
LOST_DEEP: Rgba = (0.05, 0.15, 0.80, 1.0)  # far below
FULL_MARGIN = 0.5  # relative distance from v_t at which the colour is deepest


def taxel_positions(pitch_m: float) -> np.ndarray:
    """[9, 3] taxel centres in the pad frame, taxel i = 3 row + col."""
    rows, cols = np.divmod(np.arange(N_TAXELS), 3)
    return np.stack([(cols - 1) * pitch_m, (rows - 1) * pitch_m, np.zeros(N_TAXELS)], axis=1)


def taxel_colour(voltage: float, threshold: float, safe: bool) -> Rgba:
    """Red shades for a safe taxel, blue for one below v_t; the depth is |v - v_t| / v_t up to
    FULL_MARGIN. `safe` is the ContactState's decision, not recomputed here."""
    margin = abs(voltage - threshold) / threshold if threshold > 0 and math.isfinite(voltage) else 1.0
    depth = min(margin / FULL_MARGIN, 1.0)
    pale, deep = (SAFE_PALE, SAFE_DEEP) if safe else (LOST_PALE, LOST_DEEP)
    r, g, b, a = (p + (d - p) * depth for p, d in zip(pale, deep))
    return (r, g, b, a)


def contact_position(voltages: np.ndarray, threshold: float, positions: np.ndarray) -> Point:
    """Centroid of the taxels above v_t weighted by their excess over it; the pad centre when none is."""
    excess = np.clip(np.nan_to_num(np.asarray(voltages, dtype=np.float64) - threshold, nan=0.0), 0.0, None)
    total = float(excess.sum())
    if total <= 0.0:
        return (0.0, 0.0, 0.0)
    x, y, z = (excess @ positions) / total
    return (float(x), float(y), float(z))


@dataclass(frozen=True)
class PadDrawing:
    """One pad as RViz shows it, in its pad frame."""

    finger: str
    frame_id: str
    stamp_ns: int  # the ContactState's sample
    cell_centres: tuple[Point, ...]  # 9
    cell_colours: tuple[Rgba, ...]  # 9
    safe: tuple[bool, ...]  # 9, the ContactState's decision
    contact: Point | None  # None: no contact (force below contact_force_n, or not estimated)
    normal_force_n: float | None  # the newest estimated Fz; None before the first or when NaN

    def arrow(self, m_per_n: float, max_m: float) -> tuple[Point, Point] | None:
        """Start and end of the force arrow: from outside the pad onto the contact point."""
        if self.contact is None or self.normal_force_n is None:
            return None
        length = min(self.normal_force_n * m_per_n, max_m)
        x, y, z = self.contact
        return (x, y, z + length), (x, y, z)


class TactileMarkers:
    def __init__(self, config: TactileMarkersConfig) -> None:
        self.config = config
        self._positions = taxel_positions(config.taxel_pitch)
        self._contacts: dict[str, tuple[ContactEvaluation, str]] = {}
        self._forces: dict[str, float | None] = {}
        self._changed: set[str] = set()

    def on_contact(self, evaluation: ContactEvaluation, frame_id: str) -> None:
        if evaluation.finger in self.config.fingers:
            self._contacts[evaluation.finger] = (evaluation, frame_id)
            self._changed.add(evaluation.finger)

    def on_wrench(self, finger: str, sample: WrenchSample) -> None:
        if finger in self.config.fingers:
            fz = float(sample.wrench[2])
            self._forces[finger] = fz if math.isfinite(fz) else None
            self._changed.add(finger)

    def take_drawings(self) -> list[PadDrawing]:
        """The pads whose ContactState or wrench changed since the last call (pads without a
        ContactState yet are not drawn), in finger order."""
        changed, self._changed = self._changed, set()
        return [self.drawing(f) for f in self.config.fingers if f in changed and f in self._contacts]

    def drawing(self, finger: str) -> PadDrawing:
        evaluation, frame_id = self._contacts[finger]
        force = self._forces.get(finger)
        touching = force is not None and force >= self.config.contact_force_n
        lift = self.config.cell_thickness / 2.0  # cells sit on the pad surface
        centres = tuple((float(x), float(y), lift) for x, y, _ in self._positions)
        colours = tuple(taxel_colour(float(v), evaluation.threshold, bool(s))
                        for v, s in zip(evaluation.voltages, evaluation.safe))
        contact = contact_position(evaluation.voltages, evaluation.threshold, self._positions) if touching else None
        return PadDrawing(finger, frame_id, evaluation.stamp_ns, centres, colours,
                          tuple(bool(s) for s in evaluation.safe), contact, force)
