"""A STAG glove session of held hand poses, as a dataset file that glove_driver replays, for the
teleop node's stag input without a glove (`prisma-teleop-stag-session`, cli.py).

    prisma-teleop-stag-session /tmp/stag_poses.h5
    ros2 launch prisma_bringup teleop.launch.py input:=stag glove_backend:=replay replay_file:=/tmp/stag_poses.h5

The wearer (stag_glove.synthetic.SyntheticGlove, one session) holds each pose of the script for
its frames (formed in 2, held, released in 2) with the empty hand between them: empty, pinch, empty,
power, empty, lateral, empty, 108 frames, 15 s at the glove's 7.3 frames/s (glove_driver replays it
in a loop). Each frame is labelled with its pose (objects = the pose classes).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from stag_glove.dataset import SPLIT_TRAIN, GloveDataset, save_dataset
from stag_glove.synthetic import POSES, SyntheticConfig, SyntheticGlove

# (pose, frames): each grasp pose formed, held and released within its frames, the empty hand between
SESSION: tuple[tuple[str, int], ...] = (
    ("empty", 12), ("pinch", 20), ("empty", 12), ("power", 20), ("empty", 12), ("lateral", 20), ("empty", 12),
)


def stag_session(seed: int = 0, script: tuple[tuple[str, int], ...] = SESSION) -> GloveDataset:
    """The session's raw frames, each labelled with its pose."""
    unknown = [pose for pose, _ in script if pose not in POSES]
    if unknown:
        raise ValueError(f"unknown pose(s) {unknown}; the synthetic glove has {list(POSES)}")
    glove = SyntheticGlove(SyntheticConfig(seed=seed))
    session = glove.new_session()
    names = list(dict.fromkeys(pose for pose, _ in script))
    raws, labels = [], []
    for pose, frames in script:
        if frames < 5:
            raise ValueError(f"{pose}: {frames} frames; a pose needs at least 5 (formed in 2, released in 2)")
        # one grasp of the pose per part: held for all but the 4 frames that form and release it
        glove.config = replace(glove.config, hold_frames=(frames - 4, frames - 4), gap_frames=(0, 0))
        raws.append(glove.record(None, session, frames, pose=pose).raw)
        labels.append(np.full(frames, names.index(pose)))
    raw = np.concatenate(raws)
    n = len(raw)
    return GloveDataset(raw, np.concatenate(labels), np.zeros(n, np.int64), np.full(n, SPLIT_TRAIN),
                        np.ones(n, bool), np.ones(n, bool), names)


def write_session(path: str | Path, seed: int = 0) -> GloveDataset:
    """The session written to `path` (.h5, .hdf5 or .mat; whole or not at all)."""
    ds = stag_session(seed)
    save_dataset(ds, Path(path))
    return ds
