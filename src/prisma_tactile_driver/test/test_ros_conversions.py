"""Tactile converters: CDR round trips through the rosbags typestore."""
import numpy as np
import pytest

from prisma_common.diagnostics import DiagnosticStatusData, diagnostics_from_msg, diagnostics_to_msg
from prisma_common.messages import make_header, ns_from_stamp, stamp_from_ns
from prisma_common.typestore import types
from prisma_tactile_driver.ros_conversions import (
    hand_taxels_samples,
    hand_taxels_to_msg,
    taxel_frame_from_msg,
    taxel_frame_to_msg,
)
from prisma_tactile_driver.taxels import TaxelFrame
from prisma_testing.cdr import cdr_round_trip


def test_stamp_helpers():
    stamp = stamp_from_ns(types, 12_345_678_901)
    assert (stamp.sec, stamp.nanosec) == (12, 345_678_901)
    assert ns_from_stamp(stamp) == 12_345_678_901
    header = make_header(types, 5, "thumb_pad")
    assert header.frame_id == "thumb_pad" and ns_from_stamp(header.stamp) == 5
    with pytest.raises(ValueError, match="stamp_ns"):
        stamp_from_ns(types, -1)


def test_taxel_frame_cdr_round_trip():
    counts = np.array([0, 1, 512, 1241, 2048, 3000, 4000, 4094, 4095], dtype=np.uint16)
    frame = TaxelFrame.from_counts("ring", 1_700_000_000_123_456_789, counts)
    msg = cdr_round_trip(taxel_frame_to_msg(types, frame, "ring_pad"))
    assert msg.header.frame_id == "ring_pad"
    back = taxel_frame_from_msg(msg)
    assert back.finger == "ring" and back.stamp_ns == frame.stamp_ns
    np.testing.assert_array_equal(back.counts, counts)
    np.testing.assert_array_equal(back.voltages, frame.voltages)
    np.testing.assert_allclose(back.voltages, counts * 3.3 / 4096, rtol=1e-6)


def test_hand_taxels_carry_every_sample_of_a_poll_in_order():
    # a serial poll that drained two scans of the thumb and one of the index
    frames = [TaxelFrame.from_counts("thumb", 1_000_000_000, np.full(9, 1000, np.uint16)),
              TaxelFrame.from_counts("index", 1_000_200_000, np.arange(9, dtype=np.uint16) * 400),
              TaxelFrame.from_counts("thumb", 1_010_000_000, np.full(9, 1100, np.uint16))]
    msg = cdr_round_trip(hand_taxels_to_msg(types, [taxel_frame_to_msg(types, f, f"{f.finger}_pad") for f in frames]))
    assert msg.__msgtype__ == "prisma_msgs/msg/HandTaxels"
    assert ns_from_stamp(msg.header.stamp) == 1_010_000_000  # the newest sample's
    pairs = hand_taxels_samples(msg)
    assert [finger for finger, _ in pairs] == ["thumb", "index", "thumb"]
    for frame, (_, sample) in zip(frames, pairs):
        back = taxel_frame_from_msg(sample)
        assert back.stamp_ns == frame.stamp_ns and sample.header.frame_id == f"{frame.finger}_pad"
        np.testing.assert_array_equal(back.counts, frame.counts)
        np.testing.assert_array_equal(back.voltages, frame.voltages)


def test_diagnostics_cdr_round_trip():
    statuses = [DiagnosticStatusData("tactile_driver: hub", 1, "stale: ring", "hub0", {"crc_errors": "3"}),
                DiagnosticStatusData("tactile_driver: ring", 3, "stale: no sample for 250 ms", "hub0", {})]
    msg = cdr_round_trip(diagnostics_to_msg(types, 2_000_000_000, statuses))
    assert ns_from_stamp(msg.header.stamp) == 2_000_000_000
    assert diagnostics_from_msg(msg) == statuses
