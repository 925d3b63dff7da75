"""Inputs for the manipulation core's tests (prisma_manipulation/test): a core that has seen the hand
at rest, and a thumb pad pressed at its centre, whose right column a slide can lose."""
from __future__ import annotations

import numpy as np

from prisma_manipulation.controllers import JointSample
from prisma_manipulation.manipulation_core import ManipulationCore
from prisma_manipulation.node_config import ManipulationConfig

HAND_AT_REST = {"fingers": 0.0, "thumb_flexion": 0.0, "thumb_rotation": 0.0}


def core_at_rest(config: ManipulationConfig | None = None) -> ManipulationCore:
    """A ManipulationCore that took /joint_states of the hand at rest at t = 0."""
    core = ManipulationCore(config or ManipulationConfig())
    core.on_joints(JointSample(0, dict(HAND_AT_REST)), 0)
    return core


def pressed_pad(right_lost: bool = False) -> np.ndarray:
    """A pad's nine taxel voltages pressed at its centre (every edge in contact); right_lost: its
    right column dark (0.5 V), as when the object slid off that edge."""
    v = np.array([0.8, 1.1, 0.8, 1.0, 1.5, 1.3, 0.8, 1.2, 0.8], dtype=np.float32)
    if right_lost:
        v[[0, 3, 6]] = 0.5
    return v
