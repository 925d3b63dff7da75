"""Simulated hub: one optical pad model per finger, driven by a contact source."""
from __future__ import annotations

from collections.abc import Iterable

from prisma_common.hand import FINGERS, check_finger
from prisma_hand_sim.contact_source import ContactSource
from prisma_hand_sim.pad_model import PadModel, PadParams

from .backend import HubReading


class SimHubBackend:
    def __init__(self, source: ContactSource, fingers: Iterable[str] = FINGERS,
                 params: PadParams | None = None, seed: int = 0) -> None:
        self.fingers = tuple(check_finger(f) for f in fingers)
        self.source = source
        # one physical pad per finger; distinct noise streams, same calibrated unit
        self.pads = {f: PadModel(params, seed=seed + i) for i, f in enumerate(self.fingers)}
        self._sequence = 0

    def read(self, stamp_ns: int) -> list[HubReading]:
        counts = {f: self.pads[f].sample(self.source.contact(f, stamp_ns)) for f in self.fingers}
        self._sequence += 1
        return [HubReading(self._sequence - 1, counts)]

    def counters(self) -> dict[str, int]:
        return {"scans": self._sequence}

    def close(self) -> None:
        pass
