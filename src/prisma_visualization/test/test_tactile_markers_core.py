"""The tactile markers' content from a ContactState and a wrench: the per-taxel decision and its
colour, the contact point, the force arrow, and what is taken when."""
from __future__ import annotations

import numpy as np
import pytest
from prisma_visualization.node_config import TactileMarkersConfig
from prisma_visualization.tactile_markers_core import TactileMarkers, contact_position, taxel_colour, taxel_positions

from prisma_force_estimator.wrench import WrenchSample
from prisma_manipulation.contact_monitor import ContactMonitor

# a contact toward the left column (2-5-8): the right column (0-3-6) falls below v_t = 0.8 v_a
LEFT_PRESS = np.array([0.40, 1.10, 2.00, 0.45, 1.30, 2.40, 0.42, 1.05, 1.90], dtype=np.float32)
REST = np.array([0.42, 0.47, 0.39, 0.45, 0.41, 0.50, 0.44, 0.38, 0.46], dtype=np.float32)


def wrench(fz: float, stamp_ns: int = 1) -> WrenchSample:
    return WrenchSample(stamp_ns, np.array([0.0, 0.0, fz, 0.0, 0.0, 0.0]), "prisma_thumb_pad")


def test_taxel_positions_follow_the_message_numbering():
    positions = taxel_positions(0.004)
    np.testing.assert_allclose(positions[0], [-0.004, -0.004, 0.0])  # bottom row, right side
    np.testing.assert_allclose(positions[2], [0.004, -0.004, 0.0])  # bottom row, left side
    np.testing.assert_allclose(positions[4], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(positions[7], [0.0, 0.004, 0.0])  # top row, centre


def test_colour_is_red_when_safe_blue_when_not_and_deeper_with_the_margin():
    at, far, below, far_below = (taxel_colour(v, 1.0, v >= 1.0) for v in (1.0, 1.6, 0.95, 0.2))
    assert at[0] > at[2] and far[0] > far[2]  # safe: red over blue
    assert below[2] > below[0] and far_below[2] > far_below[0]  # below v_t: blue over red
    assert far[1] < at[1] and far_below[0] < below[0]  # further from v_t: deeper
    assert taxel_colour(1.0, 1.0, True) == pytest.approx((1.0, 0.80, 0.25, 1.0))  # at v_t: the palest red
    assert taxel_colour(float("nan"), 1.0, False) == pytest.approx((0.05, 0.15, 0.80, 1.0))  # NaN: deepest


def test_contact_position_is_the_excess_weighted_centroid_of_the_taxels_above_threshold():
    positions = taxel_positions(0.004)
    threshold = 0.8 * float(LEFT_PRESS.mean())
    x, y, z = contact_position(LEFT_PRESS, threshold, positions)
    excess = np.clip(LEFT_PRESS - threshold, 0, None)
    assert (x, y) == pytest.approx(tuple(excess @ positions[:, :2] / excess.sum()))
    assert x > 0.002 and abs(y) < 0.001 and z == 0.0  # toward the left column, mid height
    assert contact_position(np.full(9, 0.5), 1.0, positions) == (0.0, 0.0, 0.0)  # none above: the centre


def test_drawing_carries_the_contact_states_decision_and_the_newest_force():
    config = TactileMarkersConfig()
    markers = TactileMarkers(config)
    evaluation = ContactMonitor(k=0.8).evaluate("thumb", 5_000_000, LEFT_PRESS)
    markers.on_contact(evaluation, "left/prisma_thumb_pad")
    markers.on_wrench("thumb", wrench(0.9))
    (drawing,) = markers.take_drawings()
    assert drawing.safe == (False, True, True, False, True, True, False, True, True)
    assert drawing.safe == tuple(evaluation.safe)
    assert [c[0] > c[2] for c in drawing.cell_colours] == list(drawing.safe)
    assert (drawing.finger, drawing.frame_id, drawing.stamp_ns) == ("thumb", "left/prisma_thumb_pad", 5_000_000)
    assert drawing.cell_centres[4] == (0.0, 0.0, 0.0005)  # the cells sit on the pad
    assert drawing.normal_force_n == 0.9
    assert drawing.contact == pytest.approx(contact_position(LEFT_PRESS, evaluation.threshold,
                                                            taxel_positions(config.taxel_pitch)))
    start, end = drawing.arrow(config.arrow_m_per_n, config.arrow_max_length)
    assert end == drawing.contact and start == pytest.approx((end[0], end[1], 0.018))  # 0.9 N x 20 mm/N
    assert drawing.arrow(0.1, 0.06)[0][2] == pytest.approx(0.06)  # cut to the longest arrow


def test_no_contact_point_below_the_contact_force_or_without_an_estimate():
    markers = TactileMarkers(TactileMarkersConfig(contact_force_n=0.1))
    markers.on_contact(ContactMonitor().evaluate("index", 1, REST), "prisma_index_pad")
    (drawing,) = markers.take_drawings()
    assert drawing.contact is None and drawing.normal_force_n is None and drawing.arrow(0.02, 0.06) is None
    markers.on_wrench("index", wrench(0.05))
    assert markers.take_drawings()[0].contact is None
    markers.on_wrench("index", wrench(float("nan")))
    assert markers.take_drawings()[0].normal_force_n is None


def test_take_drawings_returns_the_pads_that_changed_once_in_finger_order():
    markers = TactileMarkers(TactileMarkersConfig(fingers=["thumb", "index"]))
    assert markers.take_drawings() == []
    markers.on_wrench("index", wrench(1.0))
    assert markers.take_drawings() == []  # no ContactState of the index yet: nothing to draw on
    monitor = ContactMonitor()
    markers.on_contact(monitor.evaluate("index", 2, REST), "prisma_index_pad")
    markers.on_contact(monitor.evaluate("thumb", 2, LEFT_PRESS), "prisma_thumb_pad")
    markers.on_contact(monitor.evaluate("middle", 2, REST), "prisma_middle_pad")  # not drawn: not configured
    assert [d.finger for d in markers.take_drawings()] == ["thumb", "index"]
    assert markers.take_drawings() == []
    markers.on_wrench("thumb", wrench(0.5))
    assert [d.finger for d in markers.take_drawings()] == ["thumb"]
