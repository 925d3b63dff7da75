"""A bag's episode markers (prisma/teleop/episode, prisma_teleop.episodes) -> the spans exported as
episodes, one per marked start (docs/datasets.md, "Episode markers").

A span runs from its start marker's stamp to its end marker's stamp (the same episode index); its
task is the start's, its outcome and reason the end's. What a recording can hold besides:
- an end without its start in the bag (a recorder started after the start, or one that got the
  latched end of an earlier episode): nothing of it is exported;
- a start without its end (the recording stopped inside the episode, or the end was lost): the span
  runs to the next start, else to the bag's end, with outcome `unfinished`;
- markers out of stamp order in the bag (the recorder's arrival order): read in stamp order.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from prisma_teleop.episodes import END, START, EpisodeMarker

UNFINISHED = "unfinished"  # a span without its end marker


@dataclass(frozen=True)
class Span:
    """One marked episode: frames from `start_ns` to `end_ns` (header stamps, inclusive)."""

    episode: int  # the teleop node's index
    task: str
    start_ns: int
    end_ns: int
    outcome: str
    reason: str


def episode_spans(markers: Iterable[EpisodeMarker], bag_end_ns: int) -> list[Span]:
    """The spans of `markers` in start order; `bag_end_ns` ends a start without its end."""
    ordered = sorted(markers, key=lambda m: (m.stamp_ns, m.event != END))  # an end before a start at one stamp
    starts = [m for m in ordered if m.event == START]
    ends = {m.episode: m for m in ordered if m.event == END}
    spans = []
    for number, start in enumerate(starts):
        end = ends.get(start.episode)
        if end is not None and end.stamp_ns >= start.stamp_ns:
            spans.append(Span(start.episode, start.task, start.stamp_ns, end.stamp_ns, end.outcome, end.reason))
            continue
        following = starts[number + 1].stamp_ns if number + 1 < len(starts) else bag_end_ns
        why = "the next episode started without its end" if number + 1 < len(starts) else \
            "the recording ended inside the episode"
        spans.append(Span(start.episode, start.task, start.stamp_ns, max(following, start.stamp_ns), UNFINISHED,
                          why))
    return spans
