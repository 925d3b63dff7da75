"""show's picture: the moments it draws the pads at, found in the frames."""
from __future__ import annotations

import numpy as np

from prisma_dataset.dataset_summary import DEFAULT_TOUCH_LIMIT_N, moments


def frames(contact: list[list[float]], fz: list[list[float]]) -> dict[str, np.ndarray]:
    wrench = np.zeros((len(fz), 5, 6), np.float32)
    wrench[:, :, 2] = fz
    return {"observation.contact": np.asarray(contact, np.float32), "observation.wrench": wrench}


def test_first_contact_and_peak_force_are_found_in_the_episodes_frames():
    contact = [[0, 0, 0, 0, 0], [0, 0, 0, 0, 0], [0, 1, 0, 0, 0], [1, 1, 0, 0, 0], [0, 0, 0, 0, 0]]
    fz = [[0, 0, 0, 0, 0], [0.1, 0, 0, 0, 0], [0.5, 0.4, 0, 0, 0], [1.9, 2.1, 0, 0, 0], [0.2, 0, 0, 0, 0]]
    assert moments(frames(contact, fz), slice(0, 5)) == [("first contact", 2), ("peak force", 3)]
    # within an episode's span: frames counted from its start
    assert moments(frames(contact, fz), slice(3, 5)) == [("first contact", 0), ("peak force", 0)]
    # no contact at all: only the peak force; a force not estimated (NaN) is skipped
    nan_fz = [[np.nan] * 5, [0.3, np.nan, 0, 0, 0]]
    assert moments(frames([[0] * 5, [0] * 5], nan_fz), slice(0, 2)) == [("peak force", 1)]


def test_the_touch_limit_drawn_is_the_manipulation_nodes_default():
    assert DEFAULT_TOUCH_LIMIT_N == 2.0
