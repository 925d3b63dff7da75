"""The synthetic glove's objects: a library of grasp primitives and objects built from it.

A primitive (pinch, tripod, lateral, power, hook, spherical, flat...) says which hand regions touch
and how the fingers bend. Each object uses a few modes drawn from the primitives that fit its size,
perturbed per object, plus an object-specific contact texture (shape class: sphere blobs, cylinder
bands, box edges, thin tip contact, soft irregular), a weight and a typical grip. Everything is drawn
from the generator's random stream, in a fixed order: the same seed builds the same objects.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import ndimage

from .layout import GloveLayout

SHAPES = ("sphere", "cylinder", "box", "thin", "soft")

# Grasp primitives: region contact strengths (by region name prefix) and finger flexion
# (thumb, index, middle, ring, little). Sizes say which object sizes (0 small .. 1 large) use them.
_ALL_FINGERS = ("index", "middle", "ring", "little")
PRIMITIVES: dict[str, dict] = {
    "pinch": dict(contact={"thumb_distal": 1.0, "index_distal": 1.0},
                  flexion=(0.6, 0.6, 0.3, 0.3, 0.3), size=0.15),
    "tripod": dict(contact={"thumb_distal": 1.0, "index_distal": 0.9, "middle_distal": 0.8},
                   flexion=(0.6, 0.55, 0.55, 0.35, 0.35), size=0.3),
    "lateral": dict(contact={"thumb_distal": 1.0, "index_middle": 0.8, "index_distal": 0.4},
                    flexion=(0.4, 0.8, 0.75, 0.75, 0.75), size=0.2),
    "tip": dict(contact={"thumb_distal": 1.0, **{f"{f}_distal": 0.8 for f in _ALL_FINGERS}},
                flexion=(0.5, 0.5, 0.5, 0.5, 0.5), size=0.45),
    "power": dict(contact={"palm": 0.8, "thumb_distal": 0.6, "thumb_proximal": 0.7,
                           **{f"{f}_{p}": 0.8 for f in _ALL_FINGERS for p in ("distal", "middle", "proximal")}},
                  flexion=(0.7, 0.75, 0.75, 0.75, 0.75), size=0.7),
    "spherical": dict(contact={"palm": 0.5, "thumb_distal": 1.0,
                               **{f"{f}_distal": 1.0 for f in _ALL_FINGERS},
                               **{f"{f}_middle": 0.5 for f in _ALL_FINGERS}},
                      flexion=(0.5, 0.55, 0.55, 0.55, 0.55), size=0.8),
    "hook": dict(contact={f"{f}_{p}": 0.9 for f in _ALL_FINGERS for p in ("middle", "proximal")},
                 flexion=(0.2, 0.8, 0.8, 0.8, 0.8), size=0.6),
    "flat": dict(contact={"palm": 1.0, **{f"{f}_proximal": 0.5 for f in _ALL_FINGERS}},
                 flexion=(0.15, 0.15, 0.15, 0.15, 0.15), size=0.9),
    "disc": dict(contact={"thumb_distal": 1.0, "index_distal": 0.8, "middle_distal": 0.8,
                          "ring_distal": 0.6, "index_middle": 0.3, "middle_middle": 0.3},
                 flexion=(0.45, 0.4, 0.4, 0.4, 0.45), size=0.5),
    "scissor": dict(contact={"index_middle": 0.9, "middle_middle": 0.9, "index_distal": 0.4},
                    flexion=(0.3, 0.3, 0.3, 0.7, 0.7), size=0.1),
}


@dataclass
class GraspMode:
    primitive: str
    strength: np.ndarray   # [regions] contact strength
    flexion: np.ndarray    # [5]
    probability: float


@dataclass
class ObjectSpec:
    name: str
    weight_g: float
    size: float
    shape: str
    modes: list[GraspMode]
    texture: np.ndarray    # [rows, cols] in 0..1
    grip: float            # typical grip intensity
    friction: float = 0.8  # skin-object friction coefficient: how hard a lift must squeeze


def region_vector(region_names: Sequence[str], contact: dict[str, float]) -> np.ndarray:
    """Contact strength per region (in `region_names` order) from {region name: strength}."""
    vector = np.zeros(len(region_names))
    for name, value in contact.items():
        vector[region_names.index(name)] = value
    return vector


class ObjectSetSettings(Protocol):
    """What the object set is drawn from (synthetic.SyntheticConfig has these fields): this module
    names the settings it reads, so that it need not import the generator that imports it."""

    @property
    def n_objects(self) -> int: ...
    @property
    def weight_range_g(self) -> tuple[float, float]: ...
    @property
    def modes_per_object(self) -> tuple[int, int]: ...  # inclusive range
    @property
    def mode_perturbation(self) -> float: ...  # log-sd of per-object region strength changes


def make_objects(cfg: ObjectSetSettings, layout: GloveLayout, region_masks: np.ndarray,
                 rng: np.random.Generator) -> list[ObjectSpec]:
    """`cfg.n_objects` objects (friction left at its default: the generator draws it from a stream of
    its own)."""
    # generic names: these are not the paper's objects (weights, sizes and shapes are random),
    # so borrowing real names would mislead
    names = [f"object_{i:02d}" for i in range(cfg.n_objects)]
    lo, hi = np.log(cfg.weight_range_g[0]), np.log(cfg.weight_range_g[1])
    primitives = list(PRIMITIVES)
    sizes = np.array([PRIMITIVES[p]["size"] for p in primitives])
    objects = []
    for i in range(cfg.n_objects):
        size = rng.uniform(0.0, 1.0)
        weight = float(np.exp(rng.uniform(lo, hi)))
        shape = SHAPES[rng.integers(len(SHAPES))]
        affinity = np.exp(-((sizes - size) ** 2) / (2 * 0.25 ** 2))
        n_modes = int(rng.integers(cfg.modes_per_object[0], cfg.modes_per_object[1] + 1))
        chosen = rng.choice(len(primitives), size=n_modes, replace=False, p=affinity / affinity.sum())
        usage = rng.dirichlet(np.full(n_modes, 2.0))
        modes = []
        for j, p in enumerate(chosen):
            prim = PRIMITIVES[primitives[p]]
            strength = region_vector(layout.region_names, prim["contact"])
            strength = np.clip(strength * np.exp(rng.normal(0, cfg.mode_perturbation, strength.shape)), 0, 1.3)
            if rng.random() < 0.3:  # an extra, weak contact particular to this object
                strength[rng.integers(len(strength))] += rng.uniform(0.2, 0.5)
            flexion = np.clip(np.array(prim["flexion"]) * (1.2 - 0.4 * size) + rng.normal(0, 0.05, 5), 0, 1)
            modes.append(GraspMode(primitives[p], strength, flexion, float(usage[j])))
        grip = 0.45 * (weight / 100.0) ** 0.25 * float(np.exp(rng.normal(0, 0.2)))
        texture = object_texture(layout, region_masks, shape, size, rng)
        objects.append(ObjectSpec(names[i], weight, size, shape, modes, texture, grip))
    return objects


def object_texture(layout: GloveLayout, region_masks: np.ndarray, shape: str, size: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Object-specific contact texture in 0..1 over the grid."""
    rows, cols = layout.shape
    rr, cc = np.mgrid[0:rows, 0:cols].astype(float)
    if shape == "sphere":  # a blob per region, size-dependent radius
        field_ = np.zeros(layout.shape)
        for i in range(len(region_masks)):
            r0, c0 = layout.centroid(layout.region_names[i])
            r0 += rng.normal(0, 1.0)
            c0 += rng.normal(0, 0.8)
            radius = 1.0 + 2.5 * size
            field_ = np.maximum(field_, np.exp(-((rr - r0) ** 2 + (cc - c0) ** 2) / (2 * radius ** 2)))
    elif shape == "cylinder":  # bands across the fingers
        period = rng.uniform(3.0, 6.0)
        phase = rng.uniform(0, 2 * np.pi)
        field_ = 0.25 + 0.75 * np.cos(2 * np.pi * rr / period + phase) ** 2
    elif shape == "box":  # edges along columns
        period = rng.uniform(2.5, 4.5)
        phase = rng.uniform(0, 2 * np.pi)
        field_ = 0.2 + 0.8 * (np.cos(2 * np.pi * cc / period + phase) > 0.3)
    elif shape == "thin":  # toward the fingertip end of each phalanx
        slope = rng.uniform(0.3, 0.8)
        field_ = np.zeros(layout.shape)
        for i in range(len(region_masks)):
            m = region_masks[i]
            r_top = rr[m].min()
            field_[m] = np.exp(-slope * (rr[m] - r_top))
    else:  # soft / irregular
        field_ = ndimage.gaussian_filter(rng.random(layout.shape), 1.5)
        field_ = (field_ - field_.min()) / (np.ptp(field_) + 1e-9)
    detail = ndimage.gaussian_filter(rng.random(layout.shape), 1.0)
    detail = (detail - detail.min()) / (np.ptp(detail) + 1e-9)
    field_ = field_ * (0.6 + 0.4 * detail)
    return (field_ / field_.max()).astype(np.float32)
