"""Calibration bags: taxel topic + reference WrenchStamped paired by header stamp."""
import numpy as np
import pytest

from prisma_common.bag import BagWriter
from prisma_common.typestore import types
from prisma_force_estimator.calibration_bag import load_calibration_bag, pair_by_stamp
from prisma_force_estimator.ros_conversions import wrench_to_msg
from prisma_force_estimator.wrench import WrenchSample
from prisma_tactile_driver.ros_conversions import taxel_frame_to_msg
from prisma_tactile_driver.taxels import TaxelFrame

T0 = 1_700_000_000_000_000_000


def test_pair_by_stamp_takes_the_nearest_within_tolerance():
    wrench_ns = np.array([0, 10, 20, 30, 100])
    partner, offset = pair_by_stamp(np.array([1, 14, 16, 60, 99, 130]), wrench_ns, tolerance_ns=5)
    assert partner.tolist() == [0, 1, 2, -1, 4, -1]
    assert offset[[0, 1, 2, 4]].tolist() == [1, 4, 4, 1]


def _write_calibration_bag(path, n=200):
    """Taxels at 100 Hz; the F/T sensor stamps 1.5 ms later, misses every 10th sample and also
    publishes 20 extra readings in a gap after the taxel stream."""
    rng = np.random.default_rng(0)
    voltages = rng.uniform(0.4, 3.0, (n, 9)).astype(np.float32)
    wrench = rng.normal(size=(n, 6))
    with BagWriter(path) as bag:
        for k in range(n):
            stamp = T0 + k * 10_000_000
            counts = np.rint(voltages[k] / 3.3 * 4096).astype(np.uint16)
            frame = TaxelFrame("thumb", stamp, counts, voltages[k])
            bag.write("/prisma/thumb/taxels", taxel_frame_to_msg(types, frame, "prisma_thumb_pad"))
            if k % 10 != 9:
                bag.write("/ft_sensor/wrench", wrench_to_msg(types, WrenchSample(stamp + 1_500_000, wrench[k], "ft")))
        for k in range(20):
            stamp = T0 + (n + 50 + k) * 10_000_000
            bag.write("/ft_sensor/wrench", wrench_to_msg(types, WrenchSample(stamp, np.zeros(6), "ft")))
    return voltages, wrench


def test_calibration_bag_pairs_counts_and_values(tmp_path):
    voltages, wrench = _write_calibration_bag(tmp_path / "cal")
    dataset, report = load_calibration_bag(tmp_path / "cal", "/prisma/thumb/taxels", "/ft_sensor/wrench",
                                           tolerance_ns=3_000_000)
    assert report.taxel_messages == 200 and report.wrench_messages == 180 + 20
    assert report.matched == 180 and report.unmatched_taxels == 20 and report.unused_wrenches == 20
    assert report.max_offset_ns == 1_500_000
    kept = np.array([k for k in range(200) if k % 10 != 9])
    np.testing.assert_array_equal(dataset.voltages, voltages[kept])
    np.testing.assert_allclose(dataset.wrench, wrench[kept].astype(np.float32))
    assert dataset.stamp_ns.tolist() == (T0 + kept * 10_000_000).tolist()
    assert "180 pairs" in report.summary()


def test_tight_tolerance_leaves_everything_unmatched(tmp_path):
    _write_calibration_bag(tmp_path / "cal", n=30)
    dataset, report = load_calibration_bag(tmp_path / "cal", "/prisma/thumb/taxels", "/ft_sensor/wrench",
                                           tolerance_ns=1_000_000)
    assert len(dataset) == 0 and report.unmatched_taxels == 30


def test_missing_topics_are_named(tmp_path):
    _write_calibration_bag(tmp_path / "cal", n=5)
    with pytest.raises(ValueError, match="'/prisma/index/taxels'"):
        load_calibration_bag(tmp_path / "cal", "/prisma/index/taxels", "/ft_sensor/wrench")
    with pytest.raises(ValueError, match="'/ati/wrench'"):
        load_calibration_bag(tmp_path / "cal", "/prisma/thumb/taxels", "/ati/wrench")
