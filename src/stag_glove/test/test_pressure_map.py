"""The pressure map: the layout's sensors as coloured squares on a hand-shaped image."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_testing.repo_paths import CONFIG
from stag_glove.layout import load_layout
from stag_glove.pressure_map import NO_SENSOR_RGB, OUTLINE_RGB, SHORTED_RGB, PressureMap, pressure_colours

LAYOUT = load_layout(CONFIG / "glove" / "layout.yaml")


def centre(row: int, col: int, cell_px: int = 12) -> tuple[int, int]:
    return row * cell_px + cell_px // 2, col * cell_px + cell_px // 2


def test_colour_scale_is_dark_at_no_pressure_bright_at_saturation_and_monotonic():
    colours = pressure_colours(np.linspace(0.0, 1.0, 11)).astype(int)
    np.testing.assert_array_equal(colours[0], [0, 0, 4])
    np.testing.assert_array_equal(colours[-1], [252, 255, 164])
    assert np.all(np.diff(colours.sum(axis=1)) > 0)  # brighter with every step
    np.testing.assert_array_equal(pressure_colours(np.array([-1.0, np.nan, 7.0])),
                                  pressure_colours(np.array([0.0, 0.0, 1.0])))


def test_every_sensor_is_a_square_of_its_pressure_and_the_rest_is_dark():
    pressure = np.where(LAYOUT.region_mask("index_distal"), 0.9, 0.1) * LAYOUT.mask
    image = PressureMap(LAYOUT.mask, LAYOUT.region_index).draw(pressure)
    assert image.shape == (384, 384, 3) and image.dtype == np.uint8
    rows, cols = np.nonzero(LAYOUT.mask)
    for r, c in zip(rows, cols):
        np.testing.assert_array_equal(image[centre(r, c)], pressure_colours(pressure[r, c]))
    r, c = np.argwhere(~LAYOUT.mask)[0]
    np.testing.assert_array_equal(image[centre(r, c)], NO_SENSOR_RGB)
    assert LAYOUT.mask.sum() == 548  # every STAG sensor drawn


def test_region_borders_are_outlined():
    image = PressureMap(LAYOUT.mask, LAYOUT.region_index).draw(np.zeros(LAYOUT.mask.shape))
    index = LAYOUT.region_mask("index_distal")
    top = np.argwhere(index)[:, 0].max()  # the last row of the distal phalanx; the middle one below
    col = np.argwhere(index[top])[0, 0]
    np.testing.assert_array_equal(image[(top + 1) * 12 - 1, col * 12 + 5], OUTLINE_RGB)
    np.testing.assert_array_equal(image[top * 12 + 5, col * 12 + 5], pressure_colours(0.0))


def test_a_shorted_frame_has_a_red_border_and_a_mismatched_frame_is_refused():
    drawer = PressureMap(LAYOUT.mask, LAYOUT.region_index, cell_px=8)
    image = drawer.draw(np.zeros(LAYOUT.mask.shape), shorted=True)
    assert image.shape == drawer.shape == (256, 256, 3)
    np.testing.assert_array_equal(image[0, 100], SHORTED_RGB)
    np.testing.assert_array_equal(image[128, -1], SHORTED_RGB)
    with pytest.raises(ValueError, match="pressure is 16x16, the layout 32x32"):
        drawer.draw(np.zeros((16, 16)))
    with pytest.raises(ValueError, match="cell_px 2: at least 3"):
        PressureMap(LAYOUT.mask, cell_px=2)
