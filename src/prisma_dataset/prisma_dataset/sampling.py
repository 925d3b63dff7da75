"""Streams of stamped samples onto a fixed frame grid: sample-and-hold within a max age per stream.

The rule (docs/datasets.md, "Sampling"): the frame at instant t takes, from each stream, its newest
sample whose header stamp is <= t (samples are ordered by stamp first, so a stream recorded with
stamps out of order is read in stamp order; of equal stamps the one recorded last wins). The grid
starts at the first instant every stream has a sample (the latest of the streams' first stamps) and
steps by 1/fps (t_k = start + floor(k * 1e9 / fps) ns) up to the last stamp of any stream. The first
frame where a stream's newest sample is older than that stream's max age ends the episode: that
frame and every one after it are dropped, and the result names the stream, its age and the instant.
A marked episode's span narrows the grid: it starts at the later of the span's start and the streams'
first instant, and ends at the earlier of the span's end and the streams' last stamp. Frames at the
start of a span where a stream is already older than its max age (a recording begun in a moment a
stream stalled) are skipped: the episode starts at the first frame every stream is fresh, and the
result counts the frames skipped (`skipped`); the whole-bag grid starts as before.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

NS = 1_000_000_000


@dataclass
class Stream:
    """One stream's samples: `stamps_ns` [n] int64 in stamp order, `values` [n, ...]."""

    name: str
    stamps_ns: np.ndarray
    values: np.ndarray
    max_age_ns: int

    @classmethod
    def from_samples(cls, name: str, stamps_ns: Sequence[int], values: Sequence[np.ndarray] | np.ndarray,
                     max_age_ns: int) -> Stream:
        """Samples in any order, sorted by stamp (stable: of equal stamps the later one stays later)."""
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        data = np.asarray(values)
        if len(stamps) != len(data):
            raise ValueError(f"{name}: {len(stamps)} stamps for {len(data)} values")
        if not len(stamps):
            raise ValueError(f"{name}: no samples")
        order = np.argsort(stamps, kind="stable")
        return cls(name, stamps[order], data[order], int(max_age_ns))


@dataclass(frozen=True)
class Gap:
    """The stream that ended an episode: at `at_ns` its newest sample was `age_ns` old."""

    stream: str
    at_ns: int
    age_ns: int
    max_age_ns: int

    def describe(self, origin_ns: int = 0) -> str:
        return (f"{self.stream}'s newest sample was {self.age_ns / NS:.3f} s old at "
                f"{(self.at_ns - origin_ns) / NS:.3f} s (max age {self.max_age_ns / NS:.3f} s)")


@dataclass
class Sampled:
    """The frames of one episode: `instants_ns` [frames], stream name -> values [frames, ...];
    `gap` is the stale stream that ended it (None: it ran to the streams' end at `end_ns`)."""

    instants_ns: np.ndarray
    values: dict[str, np.ndarray]
    gap: Gap | None
    end_ns: int
    skipped: int = 0  # frames of a span's start skipped while a stream was stale

    @property
    def dropped_ns(self) -> int:
        """Time after the last frame that the grid covered but the episode does not."""
        return int(self.end_ns - self.instants_ns[-1]) if len(self.instants_ns) else 0


def grid(start_ns: int, end_ns: int, fps: int) -> np.ndarray:
    """start + floor(k * 1e9 / fps) for k = 0, 1, ... up to end (inclusive)."""
    if fps <= 0:
        raise ValueError(f"fps {fps} must be > 0")
    count = (end_ns - start_ns) * fps // NS + 1 if end_ns >= start_ns else 0
    k = np.arange(count, dtype=np.int64)
    instants = start_ns + k * NS // fps
    return instants[instants <= end_ns]


def sample_and_hold(streams: Sequence[Stream], fps: int, span: tuple[int, int] | None = None) -> Sampled:
    """The frames of `streams` on the grid; `span` (start, end ns, inclusive: a marked episode) narrows
    the grid to start no earlier than its start and to end no later than its end."""
    if not streams:
        raise ValueError("no streams to sample")
    start = max(int(s.stamps_ns[0]) for s in streams)
    end = max(int(s.stamps_ns[-1]) for s in streams)
    if span is not None:
        start, end = max(start, int(span[0])), min(end, int(span[1]))
    instants = grid(start, end, fps)
    picks, ages = {}, {}
    for stream in streams:
        index = np.searchsorted(stream.stamps_ns, instants, side="right") - 1  # >= 0: every instant >= start
        picks[stream.name], ages[stream.name] = index, instants - stream.stamps_ns[index]
    first = 0
    if span is not None and len(instants):  # a span's stale start is skipped
        fresh = np.all([ages[s.name] <= s.max_age_ns for s in streams], axis=0)
        first = int(np.argmax(fresh)) if fresh.any() else 0
    cut = len(instants)
    gap = None
    for stream in streams:
        age = ages[stream.name]
        stale = first + np.flatnonzero(age[first:] > stream.max_age_ns)
        if stale.size and stale[0] < cut:
            cut = int(stale[0])
            gap = Gap(stream.name, int(instants[cut]), int(age[cut]), stream.max_age_ns)
    values = {s.name: s.values[picks[s.name][first:cut]] for s in streams}
    return Sampled(instants[first:cut], values, gap, end, first if cut > first else 0)
