"""A small LeRobot dataset written by prisma_dataset's own writer, with the features the policy
learns from and an action that is a known function of them."""
from __future__ import annotations

import numpy as np
import pytest

from prisma_dataset.bag_export import ACTION, STATE, TACTILE, WRENCH, features_for
from prisma_dataset.lerobot_format import Dataset, Episode, write_dataset


def write_tiny_dataset(root, episodes=3, frames=60, drop=None, seed=0):
    """Episodes where the action is a fixed function of the state and the thumb's pad force:
    fingers target = 1.5 x fingers position + 0.5; thumb target = 2 - thumb Fz; rotation constant."""
    rng = np.random.default_rng(seed)
    features = [f for f in features_for([]) if f.name != drop]
    recorded = []
    for number in range(episodes):
        state = rng.uniform(0, 3, (frames, 6)).astype(np.float32)
        tactile = rng.uniform(0, 1, (frames, 5, 3, 3)).astype(np.float32)
        wrench = rng.normal(0, 0.5, (frames, 5, 6)).astype(np.float32)
        action = np.stack([1.5 * state[:, 0] + 0.5, 2.0 - wrench[:, 0, 2], np.full(frames, 0.1)], axis=1)
        values = {STATE: state, TACTILE: tactile, WRENCH: wrench, ACTION: action.astype(np.float32),
                  "observation.contact": np.zeros((frames, 5), np.float32)}
        notes = {"demonstration": {"index_contact_rad": 2.9 + 0.1 * number, "thumb_contact_rad": 2.5,
                                   "stiffness_n_per_mm": 0.4}}
        recorded.append(Episode("pinch", {f.name: values[f.name] for f in features}, notes))
    write_dataset(root, Dataset(50, features, recorded))
    return root


@pytest.fixture
def tiny_dataset():
    return write_tiny_dataset
