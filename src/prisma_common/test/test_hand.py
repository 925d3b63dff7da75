"""Hand names and ADC conversions."""
import numpy as np
import pytest

from prisma_common.hand import counts_to_voltages, voltages_to_counts


def test_counts_to_voltages_uses_4096_and_vref():
    v = counts_to_voltages(np.array([0, 2048, 4095], dtype=np.uint16))
    assert v.dtype == np.float32
    np.testing.assert_allclose(v, [0.0, 1.65, 3.3 * 4095 / 4096], rtol=1e-6)
    np.testing.assert_array_equal(voltages_to_counts(v), [0, 2048, 4095])
    with pytest.raises(ValueError, match="vref"):
        counts_to_voltages([1], vref=0.0)
