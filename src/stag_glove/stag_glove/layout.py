"""Glove layout: which of the 32x32 readout cells are real sensors (548 on STAG) and which hand
region (palm, thumb and finger phalanges) each sensor lies on.

The layout ships as config/glove/layout.yaml: a legend of one-character region codes and 32
strings of 32 characters ('.' = no sensor). For recorded data the mask can also be recovered from
the data alone: non-sensor cells are constant, so mask = pressure.max(0) != pressure.min(0).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .paths import resolve

DEFAULT_LAYOUT = "config/glove/layout.yaml"
NO_SENSOR = "."
STAG_SENSOR_COUNT = 548


@dataclass(frozen=True)
class GloveLayout:
    """mask [rows, cols] bool; region_index [rows, cols] int (-1 off-mask); region_names."""

    mask: np.ndarray
    region_index: np.ndarray
    region_names: tuple[str, ...]

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.mask.shape)

    @property
    def sensor_count(self) -> int:
        return int(self.mask.sum())

    def region_mask(self, name: str) -> np.ndarray:
        try:
            index = self.region_names.index(name)
        except ValueError:
            raise KeyError(f"unknown hand region {name!r}; have {list(self.region_names)}") from None
        return self.region_index == index

    def finger_of(self, region: str) -> str:
        """'index_distal' -> 'index'; 'palm' -> 'palm'."""
        return region.split("_", 1)[0]

    def centroid(self, name: str) -> tuple[float, float]:
        rows, cols = np.nonzero(self.region_mask(name))
        return float(rows.mean()), float(cols.mean())


def parse_layout(document: dict, source: str = "<layout>") -> GloveLayout:
    try:
        rows, cols = int(document["rows"]), int(document["cols"])
        legend: dict = document["legend"]
        grid: list = document["grid"]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{source}: layout needs rows, cols, legend and grid ({exc})") from None
    if len(grid) != rows:
        raise ValueError(f"{source}: grid has {len(grid)} lines, rows says {rows}")
    codes = {str(code): str(name) for code, name in legend.items()}
    if NO_SENSOR in codes:
        raise ValueError(f"{source}: legend must not use {NO_SENSOR!r} (it marks cells without sensor)")
    names = tuple(codes.values())
    region_index = np.full((rows, cols), -1, dtype=np.int16)
    for r, line in enumerate(grid):
        if len(line) != cols:
            raise ValueError(f"{source}: grid line {r} has {len(line)} characters, cols says {cols}")
        for c, char in enumerate(line):
            if char == NO_SENSOR:
                continue
            if char not in codes:
                raise ValueError(f"{source}: grid line {r} column {c}: unknown region code {char!r}")
            region_index[r, c] = names.index(codes[char])
    return GloveLayout(region_index >= 0, region_index, names)


def load_layout(path: str | Path = DEFAULT_LAYOUT) -> GloveLayout:
    resolved = resolve(path)
    with open(resolved) as stream:
        return parse_layout(yaml.safe_load(stream), str(resolved))


def layout_document(layout: GloveLayout, codes: dict[str, str]) -> dict:
    """Inverse of parse_layout; codes maps region name -> one character."""
    grid = []
    for r in range(layout.shape[0]):
        grid.append("".join(
            NO_SENSOR if idx < 0 else codes[layout.region_names[idx]] for idx in layout.region_index[r]))
    return {"rows": layout.shape[0], "cols": layout.shape[1],
            "legend": {codes[name]: name for name in layout.region_names}, "grid": grid}


def mask_from_pressure(pressure: np.ndarray) -> np.ndarray:
    """Sensor mask of a recording [N, rows, cols]: cells whose value ever changes."""
    pressure = np.asarray(pressure)
    if pressure.ndim != 3 or pressure.shape[0] < 2:
        raise ValueError(f"need a recording [N>=2, rows, cols], got shape {pressure.shape}")
    return pressure.max(axis=0) != pressure.min(axis=0)
