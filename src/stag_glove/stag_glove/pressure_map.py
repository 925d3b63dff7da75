"""The glove's pressure drawn where people look at it: an RGB image of the hand, each of the 548
sensors a square at its place on the layout's 32 x 32 readout (a left hand seen from the palm,
fingers up: config/glove/layout.yaml), coloured by its pressure, with the outline of each hand region
(palm, thumb and finger phalanges) and the cells without a sensor left dark.

An image rather than RViz markers: the glove is worn by a person, not mounted on the robot, so it has
no place in the hand's TF tree, while rqt_image_view, RViz's Image display and a bag viewer all show
an image as it is. It is /stag/image (32FC1, one pixel per readout cell, for tools that want the
values) made readable: a hand's shape and a colour scale.
"""
from __future__ import annotations

import numpy as np

# "inferno"-like scale at five anchors (black-purple-red-orange-yellow): dark at no pressure, so the
# hand's outline stays readable, bright at saturation
_ANCHORS = np.array([[0.0, 0.0, 4.0], [87.0, 16.0, 110.0], [188.0, 55.0, 84.0], [249.0, 142.0, 9.0],
                     [252.0, 255.0, 164.0]])
NO_SENSOR_RGB = (28, 28, 30)
OUTLINE_RGB = (200, 200, 205)
SHORTED_RGB = (230, 30, 30)


def pressure_colours(pressure: np.ndarray) -> np.ndarray:
    """uint8 [..., 3] colours for pressures 0..1 (clipped; NaN counts as 0)."""
    p = np.clip(np.nan_to_num(np.asarray(pressure, dtype=np.float64), nan=0.0), 0.0, 1.0)
    position = p * (len(_ANCHORS) - 1)
    low = np.minimum(position.astype(int), len(_ANCHORS) - 2)
    fraction = (position - low)[..., None]
    return np.rint(_ANCHORS[low] * (1.0 - fraction) + _ANCHORS[low + 1] * fraction).astype(np.uint8)


class PressureMap:
    """Draws frames of one layout: the static parts (seams, region outlines) are worked out once."""

    def __init__(self, mask: np.ndarray, region_index: np.ndarray | None = None, cell_px: int = 12) -> None:
        if cell_px < 3:
            raise ValueError(f"cell_px {cell_px}: at least 3 pixels per cell")
        self.mask = np.asarray(mask, dtype=bool)
        self.cell_px = cell_px
        rows, cols = self.mask.shape
        regions = np.where(self.mask, region_index if region_index is not None else 0, -1)
        big = np.repeat(np.repeat(self.mask, cell_px, axis=0), cell_px, axis=1)
        seam = np.zeros_like(big)  # the 1-pixel gap between sensor cells
        seam[cell_px - 1::cell_px, :] = True
        seam[:, cell_px - 1::cell_px] = True
        self._seam = seam & big
        outline = np.zeros_like(big)  # where the region changes (or a sensor borders no sensor)
        for r, c in zip(*np.nonzero(regions[:, 1:] != regions[:, :-1])):
            outline[r * cell_px:(r + 1) * cell_px, (c + 1) * cell_px - 1] = True
        for r, c in zip(*np.nonzero(regions[1:, :] != regions[:-1, :])):
            outline[(r + 1) * cell_px - 1, c * cell_px:(c + 1) * cell_px] = True
        self._outline = outline
        self._border = np.zeros_like(big)
        self._border[:3, :] = self._border[-3:, :] = self._border[:, :3] = self._border[:, -3:] = True

    @property
    def shape(self) -> tuple[int, int, int]:
        rows, cols = self.mask.shape
        return rows * self.cell_px, cols * self.cell_px, 3

    def draw(self, pressure: np.ndarray, shorted: bool = False) -> np.ndarray:
        """uint8 [rows * cell_px, cols * cell_px, 3]: each sensor a square of its pressure's colour,
        region outlines, and a red border on a shorted frame (whose values are not pressures)."""
        pressure = np.asarray(pressure)
        if pressure.shape != self.mask.shape:
            raise ValueError(f"pressure is {'x'.join(map(str, pressure.shape))}, the layout "
                             f"{self.mask.shape[0]}x{self.mask.shape[1]}")
        cells = np.where(self.mask[..., None], pressure_colours(pressure), np.array(NO_SENSOR_RGB, dtype=np.uint8))
        image = np.repeat(np.repeat(cells, self.cell_px, axis=0), self.cell_px, axis=1)
        image[self._seam] = NO_SENSOR_RGB
        image[self._outline] = OUTLINE_RGB
        if shorted:
            image[self._border] = SHORTED_RGB
        return image
