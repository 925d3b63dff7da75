"""Frame processing core and glove layout (issue: STAG glove, build item 1)."""
import numpy as np
import pytest

from stag_glove.layout import STAG_SENSOR_COUNT, load_layout, mask_from_pressure, parse_layout
from stag_glove.processing import (
    EmptyHandCalibration,
    FrameProcessor,
    NormalisationConfig,
    is_shorted,
    normalise,
    shorted_frames,
)


def test_normalisation_maps_500_650_to_0_1_and_clips():
    raw = np.array([[0, 499, 500, 575], [650, 651, 900, 1023]], dtype=np.uint16)
    p = normalise(raw)
    assert p.dtype == np.float32
    np.testing.assert_allclose(p, [[0, 0, 0, 0.5], [1, 1, 1, 1]], atol=1e-6)


def test_normalisation_range_is_configurable():
    np.testing.assert_allclose(normalise(np.array([400, 450, 500]), low=400, high=500), [0, 0.5, 1])
    with pytest.raises(ValueError, match="high"):
        NormalisationConfig(low=650, high=500)


def test_any_reading_above_950_marks_the_frame_shorted():
    raw = np.full((32, 32), 520, np.uint16)
    assert not is_shorted(raw)
    raw[3, 4] = 950
    assert not is_shorted(raw)  # the threshold itself is still a reading
    raw[3, 4] = 951
    assert is_shorted(raw)
    mask = np.zeros((32, 32), bool)
    assert not is_shorted(raw, mask=mask)  # outside the sensor mask it does not count
    stack = np.stack([np.full((32, 32), 520), raw])
    assert shorted_frames(stack).tolist() == [False, True]


def test_shorted_frame_is_flagged_and_never_has_contact():
    proc = FrameProcessor()
    raw = np.full((32, 32), 640, np.uint16)  # strong pressure everywhere
    raw[0, 0] = 1000
    frame = proc.process(raw, stamp_ns=5)
    assert frame.shorted and not frame.contact
    assert frame.stamp_ns == 5 and frame.pressure.shape == (32, 32)


def test_empty_hand_calibration_is_the_per_sensor_maximum_and_skips_shorted_frames():
    rng = np.random.default_rng(0)
    empty = rng.integers(480, 520, size=(20, 32, 32)).astype(np.uint16)
    shorted = empty[0].copy()
    shorted[5, 5] = 1000
    cal = EmptyHandCalibration.from_frames(np.concatenate([empty, shorted[None]]))
    assert cal.frames_used == 20
    np.testing.assert_allclose(cal.maximum, normalise(empty).max(axis=0))
    with pytest.raises(ValueError, match="shorted"):
        EmptyHandCalibration.from_frames(shorted[None])


def test_contact_flag_follows_the_empty_hand_calibration():
    empty = np.full((10, 32, 32), 490, np.uint16)
    empty[:, 7, 7] = 560  # this sensor reads 0.4 even with the empty hand
    proc = FrameProcessor(NormalisationConfig(contact_margin=0.02))
    frame = empty[0].copy()
    assert proc.process(frame, 0).contact  # uncalibrated: 0.4 > margin -> contact
    proc.calibrate(empty)
    assert not proc.process(frame, 0).contact  # at its empty-hand maximum: no contact
    frame[7, 7] = 562  # +0.013: inside the margin
    assert not proc.process(frame, 0).contact
    frame[7, 7] = 570  # +0.067 above this sensor's maximum
    assert proc.process(frame, 0).contact
    other = empty[0].copy()
    other[20, 20] = 505  # 0.033 where the empty hand read 0
    assert proc.process(other, 0).contact


def test_shipped_layout_has_548_sensors_and_hand_regions():
    layout = load_layout()
    assert layout.shape == (32, 32)
    assert layout.sensor_count == STAG_SENSOR_COUNT == 548
    assert (layout.region_index >= 0).sum() == 548
    names = set(layout.region_names)
    assert {"palm", "thumb_distal", "thumb_proximal"} <= names
    for finger in ("index", "middle", "ring", "little"):
        assert {f"{finger}_distal", f"{finger}_middle", f"{finger}_proximal"} <= names
    assert layout.region_mask("palm").sum() > 200
    with pytest.raises(KeyError, match="wrist"):
        layout.region_mask("wrist")


def test_layout_parser_names_bad_lines():
    doc = {"rows": 2, "cols": 3, "legend": {"P": "palm"}, "grid": ["PP.", "P?."]}
    with pytest.raises(ValueError, match="line 1 column 1"):
        parse_layout(doc)
    with pytest.raises(ValueError, match="3 characters|has 2"):
        parse_layout({**doc, "grid": ["PP.", "P."]})


def test_mask_recovered_from_data_where_non_sensor_cells_are_constant():
    layout = load_layout()
    rng = np.random.default_rng(1)
    frames = np.where(layout.mask, rng.integers(400, 700, (50, 32, 32)), 7)
    np.testing.assert_array_equal(mask_from_pressure(frames), layout.mask)
    with pytest.raises(ValueError):
        mask_from_pressure(frames[:1])
