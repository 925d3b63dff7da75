"""Contact monitor with hand-made inputs: edge loss below k times the mean, run-time k, and a
reference first-loss search."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from prisma_manipulation.contact_monitor import ContactMonitor, first_lost_index


def test_monitor_flags_a_whole_edge_below_k_times_mean():
    v = np.full(9, 1.2, dtype=np.float32)
    v[[0, 3, 6]] = 0.5
    e = ContactMonitor(k=0.8).evaluate("thumb", 5, v)
    assert e.mean_voltage == pytest.approx((3 * 0.5 + 6 * 1.2) / 9)
    assert e.threshold == pytest.approx(0.8 * e.mean_voltage)
    assert e.lost_edges == ("right",) and not e.feasible
    assert e.safe.tolist() == [False, True, True] * 3
    assert e.safe_count("left") == 3 and e.safe_count("bottom") == 2
    # one taxel of the edge above v_t keeps the edge
    v[3] = 1.0
    assert ContactMonitor(k=0.8).evaluate("thumb", 6, v).lost_edges == ()


def test_k_changes_at_run_time_and_bad_k_is_refused_with_its_value():
    monitor = ContactMonitor(k=0.5)
    v = np.array([0.7, 1.0, 1.0, 0.7, 1.0, 1.0, 0.7, 1.0, 1.0], dtype=np.float32)
    assert monitor.evaluate("index", 0, v).feasible
    monitor.set_k(0.9)
    e = monitor.evaluate("index", 1, v)
    assert e.k == 0.9 and e.lost_edges == ("right",)
    for bad in (0.0, -0.1, 2.0, float("nan")):
        with pytest.raises(ValueError, match=f"k {bad}"):
            monitor.set_k(bad)
    assert monitor.k == 0.9


def test_untouched_pad_is_not_a_feasible_contact_with_a_minimum_mean():
    rest = np.array([0.42, 0.47, 0.39, 0.45, 0.41, 0.50, 0.44, 0.38, 0.46], dtype=np.float32)
    assert ContactMonitor(0.8).evaluate("thumb", 0, rest).feasible  # Algorithm 1 alone
    assert not ContactMonitor(0.8, min_mean_voltage=0.55).evaluate("thumb", 0, rest).feasible


@settings(max_examples=60, deadline=None)
@given(arrays(np.float32, (20, 9), elements=st.floats(0.25, 3.0, width=32)), st.floats(0.5, 1.0))
def test_reference_first_loss_matches_the_monitor(volts, k):
    monitor = ContactMonitor(k)
    for edge in ("bottom", "top", "right", "left"):
        expected = next((i for i, row in enumerate(volts) if edge in monitor.evaluate("thumb", i, row).lost_edges),
                        None)
        assert first_lost_index(volts, k, edge) == expected
