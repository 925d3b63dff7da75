"""The frame grid and sample-and-hold within a max age, with stamps chosen by hand."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_dataset.sampling import Stream, grid, sample_and_hold

MS = 1_000_000


def test_grid_steps_by_one_over_fps_in_whole_nanoseconds():
    assert grid(0, 100 * MS, 50).tolist() == [0, 20 * MS, 40 * MS, 60 * MS, 80 * MS, 100 * MS]
    # 1/3 s does not divide into nanoseconds: floor(k * 1e9 / 3), no drift over many frames
    assert grid(5, 1_000_000_005, 3).tolist() == [5, 333_333_338, 666_666_671, 1_000_000_005]
    assert grid(10, 9, 50).tolist() == []
    with pytest.raises(ValueError, match="fps 0"):
        grid(0, 1, 0)


def test_each_frame_holds_the_newest_sample_at_or_before_its_instant():
    a = Stream.from_samples("a", [0, 15 * MS, 20 * MS, 41 * MS], [1.0, 2.0, 3.0, 4.0], 30 * MS)
    b = Stream.from_samples("b", [5 * MS, 39 * MS], [10.0, 20.0], 30 * MS)
    sampled = sample_and_hold([a, b], 50)
    # the grid starts where both have a sample (5 ms) and runs to the last stamp (41 ms)
    assert sampled.instants_ns.tolist() == [5 * MS, 25 * MS]
    assert sampled.values["a"].tolist() == [1.0, 3.0]
    assert sampled.values["b"].tolist() == [10.0, 10.0]
    assert sampled.gap is None
    assert sampled.dropped_ns == 16 * MS  # 25 ms .. 41 ms: no grid instant left


def test_stamps_out_of_order_are_read_in_stamp_order_and_the_last_of_equal_stamps_wins():
    s = Stream.from_samples("s", [20 * MS, 0, 10 * MS, 10 * MS], [3.0, 1.0, 2.0, 2.5], 100 * MS)
    assert s.stamps_ns.tolist() == [0, 10 * MS, 10 * MS, 20 * MS]
    sampled = sample_and_hold([s], 100)
    assert sampled.values["s"].tolist() == [1.0, 2.5, 3.0]


def test_a_stream_older_than_its_max_age_ends_the_episode_at_that_frame():
    steady = Stream.from_samples("steady", np.arange(0, 200 * MS, 10 * MS), np.arange(20.0), 15 * MS)
    # silent from 50 ms to 120 ms
    stamps = [0, 10 * MS, 20 * MS, 30 * MS, 40 * MS, 50 * MS, 120 * MS, 130 * MS]
    gappy = Stream.from_samples("gappy", stamps, np.arange(8.0), 25 * MS)
    sampled = sample_and_hold([steady, gappy], 50)
    # frames at 0, 20, 40, 60 ms; at 80 ms gappy's newest sample (50 ms) is 30 ms old > 25 ms
    assert sampled.instants_ns.tolist() == [0, 20 * MS, 40 * MS, 60 * MS]
    assert sampled.values["gappy"].tolist() == [0.0, 2.0, 4.0, 5.0]
    assert sampled.gap is not None
    assert (sampled.gap.stream, sampled.gap.at_ns, sampled.gap.age_ns) == ("gappy", 80 * MS, 30 * MS)
    assert sampled.gap.describe() == "gappy's newest sample was 0.030 s old at 0.080 s (max age 0.025 s)"
    assert sampled.dropped_ns == 190 * MS - 60 * MS
    # an age equal to the max age is still fresh
    at_limit = Stream.from_samples("gappy", stamps, np.arange(8.0), 30 * MS)
    assert sample_and_hold([steady, at_limit], 50).instants_ns.tolist()[-1] == 80 * MS  # 30 ms old there


def test_the_earliest_stale_stream_names_the_gap():
    a = Stream.from_samples("a", [0, 100 * MS], [0.0, 1.0], 50 * MS)  # stale from 60 ms
    b = Stream.from_samples("b", [0, 100 * MS], [0.0, 1.0], 30 * MS)  # stale from 40 ms
    sampled = sample_and_hold([a, b], 50)
    assert sampled.gap is not None and sampled.gap.stream == "b" and sampled.gap.at_ns == 40 * MS
    assert sampled.instants_ns.tolist() == [0, 20 * MS]


def test_streams_must_have_samples_and_matching_values():
    with pytest.raises(ValueError, match="x: no samples"):
        Stream.from_samples("x", [], [], MS)
    with pytest.raises(ValueError, match="2 stamps for 1 values"):
        Stream.from_samples("x", [0, 1], [1.0], MS)


def test_a_spans_stale_start_is_skipped_and_a_gap_after_it_still_ends_the_episode():
    steady = Stream.from_samples("steady", [k * 10 * MS for k in range(20)], np.arange(20.0), 25 * MS)
    # silent from 10 to 70 ms, then every 10 ms to 120 ms, then silent again
    late = Stream.from_samples("late", [0, 70 * MS, 80 * MS, 90 * MS, 100 * MS, 110 * MS, 120 * MS],
                               np.arange(7.0), 25 * MS)
    sampled = sample_and_hold([steady, late], 50, span=(40 * MS, 190 * MS))
    # frames at 40 (late 40 ms old: skipped), 60 (60 ms old: skipped), 80, 100, 120, 140 (20 ms: kept),
    # 160 (40 ms old: ends it)
    assert sampled.skipped == 2
    assert sampled.instants_ns.tolist() == [80 * MS, 100 * MS, 120 * MS, 140 * MS]
    assert sampled.values["late"].tolist() == [2.0, 4.0, 6.0, 6.0]
    assert sampled.gap is not None and (sampled.gap.stream, sampled.gap.at_ns) == ("late", 160 * MS)
    # without a span (a whole bag) the rule is as before: 0 and 20 ms fresh, late stale at 40 ms ends it
    whole = sample_and_hold([steady, late], 50)
    assert whole.instants_ns.tolist() == [0, 20 * MS] and whole.skipped == 0
    assert whole.gap is not None and whole.gap.at_ns == 40 * MS
