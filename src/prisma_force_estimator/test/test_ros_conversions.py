"""WrenchStamped and HandWrench converters: CDR round trips through the typestore, input stamp kept,
NaN axes."""
import numpy as np
import pytest

from prisma_common.messages import ns_from_stamp
from prisma_common.typestore import types
from prisma_force_estimator.ros_conversions import (
    hand_wrench_samples,
    hand_wrench_to_msg,
    wrench_from_msg,
    wrench_to_msg,
)
from prisma_force_estimator.wrench import WrenchSample, full_wrench
from prisma_testing.cdr import cdr_round_trip


def test_wrench_round_trips_through_cdr_with_its_stamp():
    sample = WrenchSample(1_700_000_123_456_789_012, np.array([0.1, -0.25, 1.5, 0.002, -0.003, 0.0004]),
                          "prisma_index_pad")
    msg = wrench_to_msg(types, sample)
    assert msg.__msgtype__ == "geometry_msgs/msg/WrenchStamped"
    assert msg.header.stamp.sec == 1_700_000_123 and msg.header.stamp.nanosec == 456_789_012
    back = wrench_from_msg(cdr_round_trip(msg))
    assert back.stamp_ns == sample.stamp_ns and back.frame_id == "prisma_index_pad"
    np.testing.assert_array_equal(back.wrench, sample.wrench)


def test_axes_a_model_lacks_travel_as_nan():
    wrench = full_wrench([0.5, 0.1, 2.0], ["fx", "fy", "fz"])
    assert wrench[:3].tolist() == [0.5, 0.1, 2.0] and np.isnan(wrench[3:]).all()
    back = wrench_from_msg(cdr_round_trip(wrench_to_msg(types, WrenchSample(5, wrench, "f"))))
    assert back.wrench[:3].tolist() == [0.5, 0.1, 2.0] and np.isnan(back.wrench[3:]).all()
    assert full_wrench([1.0, 2.0], ["fz", "tx"]).tolist()[2:4] == [1.0, 2.0]


def test_diagnostics_of_the_pipeline_round_trip(tmp_path):
    from prisma_common.diagnostics import diagnostics_from_msg, diagnostics_to_msg
    from prisma_force_estimator.bundle import save_untrained_bundle
    from prisma_force_estimator.diagnostics import pipeline_diagnostics
    from prisma_force_estimator.force_estimator_core import TaxelSample, WrenchPipeline
    from prisma_force_estimator.inference import ForceEstimator

    est = ForceEstimator.from_bundle(save_untrained_bundle(tmp_path / "b", "ann"))
    pipe = WrenchPipeline({"thumb": est, "index": est})
    pipe.add(TaxelSample("thumb", 0, np.full(9, np.nan)))
    pipe.add(TaxelSample("index", 0, np.full(9, 0.5)))
    statuses = pipeline_diagnostics(pipe, "force_estimator", {"thumb": "b", "index": "b"})
    msg = cdr_round_trip(diagnostics_to_msg(types, 42, statuses))
    back = {s.name: s for s in diagnostics_from_msg(msg)}
    assert back["force_estimator: thumb"].level == 1
    assert back["force_estimator: thumb"].values["rejected"] == "1"
    assert back["force_estimator: index"].level == 0
    assert back["force_estimator: index"].values["estimated"] == "1"


def test_hand_wrench_needs_one_wrench_per_finger():
    with pytest.raises(ValueError, match="2 fingers for 1 wrenches"):
        hand_wrench_to_msg(types, ["thumb", "index"], [wrench_to_msg(types, WrenchSample(1, np.zeros(6), ""))])


def test_hand_wrench_pairs_each_finger_with_its_wrench():
    samples = {"thumb": WrenchSample(2_000_000_000, np.array([0.1, 0.2, 0.9, 0.0, 0.0, 0.01]), "thumb_pad"),
               "index": WrenchSample(2_000_150_000, np.array([0.0, -0.1, 0.8, 0.001, 0.0, 0.0]), "index_pad")}
    msg = cdr_round_trip(hand_wrench_to_msg(types, list(samples), [wrench_to_msg(types, s) for s in samples.values()]))
    assert msg.__msgtype__ == "prisma_msgs/msg/HandWrench"
    assert ns_from_stamp(msg.header.stamp) == 2_000_150_000
    pairs = hand_wrench_samples(msg)
    assert [finger for finger, _ in pairs] == ["thumb", "index"]
    for finger, wrench in pairs:
        back = wrench_from_msg(wrench)
        assert back.stamp_ns == samples[finger].stamp_ns and back.frame_id == f"{finger}_pad"
        np.testing.assert_array_equal(back.wrench, samples[finger].wrench)

