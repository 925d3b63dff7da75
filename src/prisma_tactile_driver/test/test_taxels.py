"""Taxel data: frames from counts, the tare baseline."""
import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_tactile_driver.taxels import TareBuffer, TaxelFrame


def test_taxel_frame_validates_and_keeps_baseline_beside_raw():
    frame = TaxelFrame.from_counts("index", 5, np.full(9, 1241))
    assert frame.voltages[0] == pytest.approx(1.0, abs=1e-3)
    assert frame.baseline is None
    np.testing.assert_array_equal(frame.tared_voltages(), frame.voltages)
    frame.baseline = np.full(9, 0.25, dtype=np.float32)
    np.testing.assert_allclose(frame.tared_voltages(), frame.voltages - 0.25)
    with pytest.raises(ValueError, match="9 counts"):
        TaxelFrame("index", 0, np.zeros(8), np.zeros(9))
    assert FINGERS == ("thumb", "index", "middle", "ring", "little")


def test_tare_buffer_is_mean_of_last_n():
    tare = TareBuffer(3)
    with pytest.raises(ValueError, match="3 samples"):
        tare.baseline()
    for level in (1.0, 2.0, 3.0, 4.0):
        tare.add(np.full(9, level))
    np.testing.assert_allclose(tare.baseline(), np.full(9, 3.0))
