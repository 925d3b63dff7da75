"""The hub core the node drives: backend readings -> TaxelFrames, staleness, diagnostics.

Time comes from the caller (`stamp_ns`), so the same code runs on live time, sim time and bag
replay. A frame is stamped with its reading's own stamp when the backend has one (serial: the
hub's clock, hub_clock.py), else with the poll's stamp_ns (I2C and sim scan when polled).
Link errors (the port and the OS reason) go to /diagnostics and, once per change, to
`take_errors()` for the node to log.
"""
from __future__ import annotations

from collections.abc import Iterable

from prisma_common.diagnostics import ERROR, OK, STALE, WARN, DiagnosticStatusData
from prisma_common.hand import DEFAULT_VREF, check_finger

from .backend import HubBackend, LinkStatus
from .taxels import TaxelFrame

# counters worth a word in an OK hub status: (key, what it counts)
_LINK_EVENTS = (("missed_frames", "dropped frames"), ("crc_errors", "CRC errors"),
                ("disconnects", "disconnects"))
# a link error is reported again only after the link worked this long: a flapping finger on the
# I2C bus fails and recovers scan after scan, and must not log 100 lines a second
REPORT_AGAIN_AFTER_NS = 1_000_000_000


class TactileHub:
    def __init__(self, backend: HubBackend, fingers: Iterable[str], *, vref: float = DEFAULT_VREF,
                 stale_timeout_ns: int = 100_000_000,
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
        self.last_stamp_ns: dict[str, int | None] = {f: None for f in self.fingers}
        self.published = {f: 0 for f in self.fingers}
        self._reported_error = ""  # the link error last handed out by take_errors()
        self._ok_since_ns: int | None = None  # the link has worked since then
        self._new_errors: list[str] = []

    def poll(self, stamp_ns: int) -> list[TaxelFrame]:
        """Read the backend once; one TaxelFrame per finger sample that arrived."""
        frames = []
        for reading in self.backend.read(stamp_ns):
            stamp = stamp_ns if reading.stamp_ns is None else reading.stamp_ns
            for finger in self.fingers:
                counts = reading.counts.get(finger)
                if counts is None:
                    continue
                frame = TaxelFrame.from_counts(finger, stamp, counts, self.vref)
                self.last_stamp_ns[finger] = stamp
                self.published[finger] += 1
                frames.append(frame)
        self._note_link_error(self.link_status().error, stamp_ns)
        return frames

    def _note_link_error(self, error: str, stamp_ns: int) -> None:
        """A new reason is reported at once; the same one again after the link worked a while."""
        if error:
            self._ok_since_ns = None
            if error != self._reported_error:
                self._new_errors.append(error)
                self._reported_error = error
        elif self._reported_error:
            if self._ok_since_ns is None:
                self._ok_since_ns = stamp_ns
            elif stamp_ns - self._ok_since_ns >= REPORT_AGAIN_AFTER_NS:
                self._reported_error = ""

    def take_errors(self) -> list[str]:
        """Link errors that appeared since the last call, each once (the node logs them)."""
        errors, self._new_errors = self._new_errors, []
        return errors

    def link_status(self) -> LinkStatus:
        status = getattr(self.backend, "link_status", None)
        return status() if status is not None else LinkStatus()

    def stale_fingers(self, stamp_ns: int) -> list[str]:
        return [f for f, last in self.last_stamp_ns.items()
                if last is None or stamp_ns - last > self.stale_timeout_ns]

    def diagnostics(self, stamp_ns: int) -> list[DiagnosticStatusData]:
        counts = self.backend.counters()
        link = self.link_status()
        values = {**{k: str(v) for k, v in counts.items()}, **link.values}
        stale = self.stale_fingers(stamp_ns)
        level = ERROR if len(stale) == len(self.fingers) else WARN if stale else OK
        message = "all fingers streaming" if not stale else f"stale: {', '.join(stale)}"
        if link.error:
            message += f"; {link.error}"
        elif level == OK:
            so_far = [f"{counts[key]} {label}" for key, label in _LINK_EVENTS if counts.get(key)]
            if so_far:
                message += f" ({', '.join(so_far)} so far)"
        statuses = [DiagnosticStatusData(f"{self.name}: hub", level, message, self.hardware_id, values)]
        for finger in self.fingers:
            last = self.last_stamp_ns[finger]
            values = {"samples": str(self.published[finger]),
                      "age_ms": "never" if last is None else f"{(stamp_ns - last) / 1e6:.1f}"}
            if finger in stale:
                age = "no sample yet" if last is None else f"no sample for {(stamp_ns - last) / 1e6:.0f} ms"
                statuses.append(DiagnosticStatusData(f"{self.name}: {finger}", STALE, f"stale: {age}",
                                                     self.hardware_id, values))
            else:
                statuses.append(DiagnosticStatusData(f"{self.name}: {finger}", OK, "ok", self.hardware_id, values))
        return statuses

    def close(self) -> None:
        self.backend.close()
