"""The hub core the node drives: backend readings -> TaxelFrames, tare, staleness, diagnostics.

Everything is stamped by the caller (`stamp_ns`), so the same code runs on live time, sim time
and bag replay.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from .backend import HubBackend
from .taxels import DEFAULT_VREF, TareBuffer, TaxelFrame, check_finger

# diagnostic_msgs/DiagnosticStatus levels
OK, WARN, ERROR, STALE = 0, 1, 2, 3


@dataclass
class DiagnosticStatusData:
    """Plain form of diagnostic_msgs/DiagnosticStatus."""

    name: str
    level: int
    message: str
    hardware_id: str = ""
    values: dict[str, str] = field(default_factory=dict)


@dataclass
class TareResult:
    success: bool
    message: str
    baselines: dict[str, np.ndarray] = field(default_factory=dict)


class TactileHub:
    def __init__(self, backend: HubBackend, fingers: Iterable[str], *, vref: float = DEFAULT_VREF,
                 tare_samples: int = 100, stale_timeout_ns: int = 100_000_000,
                 name: str = "tactile_driver", hardware_id: str = "") -> None:
        if vref <= 0:
            raise ValueError(f"vref must be > 0, got {vref}")
        if stale_timeout_ns <= 0:
            raise ValueError(f"stale_timeout_ns must be > 0, got {stale_timeout_ns}")
        self.backend = backend
        self.fingers = tuple(check_finger(f) for f in fingers)
        self.vref = vref
        self.stale_timeout_ns = stale_timeout_ns
        self.name, self.hardware_id = name, hardware_id
        self._tare = {f: TareBuffer(tare_samples) for f in self.fingers}
        self.baselines: dict[str, np.ndarray | None] = {f: None for f in self.fingers}
        self.last_stamp_ns: dict[str, int | None] = {f: None for f in self.fingers}
        self.published = {f: 0 for f in self.fingers}

    def poll(self, stamp_ns: int) -> list[TaxelFrame]:
        """Read the backend once; one TaxelFrame per finger sample that arrived."""
        frames = []
        for reading in self.backend.read(stamp_ns):
            for finger in self.fingers:
                counts = reading.counts.get(finger)
                if counts is None:
                    continue
                frame = TaxelFrame.from_counts(finger, stamp_ns, counts, self.vref, self.baselines[finger])
                self._tare[finger].add(frame.voltages)
                self.last_stamp_ns[finger] = stamp_ns
                self.published[finger] += 1
                frames.append(frame)
        return frames

    def tare(self) -> TareResult:
        """Baseline = mean of each finger's last tare_samples voltages; all fingers or none."""
        short = {f: len(t) for f, t in self._tare.items() if not t.ready}
        if short:
            need = next(iter(self._tare.values())).n_samples
            detail = ", ".join(f"{f} {n}/{need}" for f, n in short.items())
            return TareResult(False, f"not enough samples to tare: {detail}")
        baselines = {f: t.baseline() for f, t in self._tare.items()}
        self.baselines.update(baselines)
        detail = "; ".join(f"{f} [{' '.join(f'{v:.3f}' for v in b)}] V" for f, b in baselines.items())
        return TareResult(True, f"tared: {detail}", baselines)

    def stale_fingers(self, stamp_ns: int) -> list[str]:
        return [f for f, last in self.last_stamp_ns.items()
                if last is None or stamp_ns - last > self.stale_timeout_ns]

    def diagnostics(self, stamp_ns: int) -> list[DiagnosticStatusData]:
        counters = {k: str(v) for k, v in self.backend.counters().items()}
        link_errors = sum(int(counters.get(k, 0)) for k in ("crc_errors", "missed_frames", "disconnects"))
        stale = self.stale_fingers(stamp_ns)
        level = ERROR if len(stale) == len(self.fingers) else WARN if stale else OK
        message = "all fingers streaming" if not stale else f"stale: {', '.join(stale)}"
        if link_errors and level == OK:
            message += f" ({link_errors} link errors so far)"
        statuses = [DiagnosticStatusData(f"{self.name}: hub", level, message, self.hardware_id, counters)]
        for finger in self.fingers:
            last = self.last_stamp_ns[finger]
            values = {"samples": str(self.published[finger]),
                      "age_ms": "never" if last is None else f"{(stamp_ns - last) / 1e6:.1f}"}
            if self.baselines[finger] is not None:
                values["baseline_v"] = " ".join(f"{v:.3f}" for v in self.baselines[finger])
            if finger in stale:
                age = "no sample yet" if last is None else f"no sample for {(stamp_ns - last) / 1e6:.0f} ms"
                statuses.append(DiagnosticStatusData(f"{self.name}: {finger}", STALE, f"stale: {age}",
                                                     self.hardware_id, values))
            else:
                statuses.append(DiagnosticStatusData(f"{self.name}: {finger}", OK, "ok", self.hardware_id, values))
        return statuses

    def close(self) -> None:
        self.backend.close()
