"""Taxel data: frames from counts."""
import numpy as np
import pytest

from prisma_common.hand import FINGERS
from prisma_tactile_driver.taxels import TaxelFrame


def test_taxel_frame_holds_raw_counts_and_their_voltages():
    frame = TaxelFrame.from_counts("index", 5, np.full(9, 1241))
    assert frame.voltages[0] == pytest.approx(1.0, abs=1e-3)
    np.testing.assert_allclose(frame.voltages, frame.counts * 3.3 / 4096, rtol=1e-6)
    with pytest.raises(ValueError, match="9 counts"):
        TaxelFrame("index", 0, np.zeros(8), np.zeros(9))
    assert FINGERS == ("thumb", "index", "middle", "ring", "little")
