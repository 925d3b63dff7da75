"""Episode markers -> the spans exported: start..end with the end's outcome; an end without its start
left out; a start without its end runs to the next start or the bag's end, `unfinished`."""
from __future__ import annotations

from prisma_dataset.episode_spans import UNFINISHED, Span, episode_spans
from prisma_teleop.episodes import EpisodeMarker

S = 1_000_000_000


def test_start_and_end_make_a_span_with_the_ends_outcome_in_stamp_order():
    markers = [
        EpisodeMarker(5 * S, 1, "end", "lift", "failure", "the operator"),  # recorded before its start
        EpisodeMarker(1 * S, 0, "start", "pinch", "", "engaged"),
        EpisodeMarker(2 * S, 0, "end", "pinch", "success", "let go; a goal was running"),
        EpisodeMarker(3 * S, 1, "start", "lift", "", "the operator"),
    ]
    assert episode_spans(markers, 9 * S) == [
        Span(0, "pinch", 1 * S, 2 * S, "success", "let go; a goal was running"),
        Span(1, "lift", 3 * S, 5 * S, "failure", "the operator"),
    ]


def test_an_end_without_its_start_is_left_out_and_a_start_without_its_end_is_unfinished():
    markers = [
        EpisodeMarker(1 * S, 4, "end", "pinch", "success", "let go"),  # latched from before the recording
        EpisodeMarker(2 * S, 5, "start", "pinch", "", "engaged"),  # its end lost
        EpisodeMarker(4 * S, 6, "start", "pinch", "", "engaged"),  # the recording stops inside it
    ]
    assert episode_spans(markers, 7 * S) == [
        Span(5, "pinch", 2 * S, 4 * S, UNFINISHED, "the next episode started without its end"),
        Span(6, "pinch", 4 * S, 7 * S, UNFINISHED, "the recording ended inside the episode"),
    ]
    assert episode_spans([], 7 * S) == []
    assert episode_spans(markers[:1], 7 * S) == []
