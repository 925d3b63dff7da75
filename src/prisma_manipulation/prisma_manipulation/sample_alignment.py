"""Groups per-finger messages of one sensor sample by header stamp.

The tactile driver publishes the five fingers of one scan with the same stamp, one message each,
and the force estimator republishes each as a wrench with that stamp, a little later. A controller
must be stepped once per scan with everything of that scan: `ready()` answers the newest stamp for
which every required (stream, finger) entry has arrived and that was not consumed yet.
"""
from __future__ import annotations

from collections import OrderedDict
from collections.abc import Hashable
from typing import Any


class SampleAligner:
    def __init__(self, history: int = 16) -> None:
        if history < 1:
            raise ValueError(f"history {history} must be >= 1")
        self.history = history
        self._by_stamp: OrderedDict[int, dict[Hashable, Any]] = OrderedDict()
        self._consumed_ns = -1

    def add(self, key: Hashable, stamp_ns: int, value: Any) -> None:
        if stamp_ns <= self._consumed_ns:
            return  # late for a scan already used
        entries = self._by_stamp.get(stamp_ns)
        if entries is None:
            entries = self._by_stamp[stamp_ns] = {}
            if len(self._by_stamp) > 1 and stamp_ns < next(reversed(self._by_stamp)):
                self._by_stamp = OrderedDict(sorted(self._by_stamp.items()))
            while len(self._by_stamp) > self.history:
                self._by_stamp.popitem(last=False)
        entries[key] = value

    def ready(self, required: set[Hashable] | frozenset[Hashable]) -> tuple[int, dict[Hashable, Any]] | None:
        """(stamp, entries) of the newest complete scan, consuming it and everything older."""
        for stamp in reversed(self._by_stamp):
            entries = self._by_stamp[stamp]
            if required <= entries.keys():
                self._consumed_ns = stamp
                for old in [s for s in self._by_stamp if s <= stamp]:
                    del self._by_stamp[old]
                return stamp, entries
        return None

    def reset(self) -> None:
        self._by_stamp.clear()
        self._consumed_ns = -1
