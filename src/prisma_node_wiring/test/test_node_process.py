"""settle_garbage_collector: what a node holds from its start is left out of later collections."""
from __future__ import annotations

import gc

import pytest

pytest.importorskip("rclpy", reason="prisma_node_wiring needs rclpy (source ROS 2)")

from prisma_node_wiring.node_process import settle_garbage_collector  # noqa: E402


def test_objects_alive_at_start_are_frozen_and_new_ones_still_collected():
    gc.unfreeze()
    try:
        kept = [[i] for i in range(10_000)]  # what a node builds at start and keeps
        settle_garbage_collector()
        assert gc.get_freeze_count() >= len(kept)
        cycle: list = []
        cycle.append(cycle)  # garbage made after the start: still the collector's
        del cycle
        assert gc.collect() >= 1
    finally:
        gc.unfreeze()
