"""The glove session's scripted wearer (prisma_sim.glove_session.SessionGloveBackend) without ROS:
the empty hand, then per object grasps of it without a load (the object set's kind of recording:
lifted frames in the buffer cost the object decision, docs/glove.md, "Weight") and a release."""
from __future__ import annotations

import numpy as np

from prisma_sim.glove_session import (
    EMPTY_FIRST_FRAMES,
    EPISODE_FRAMES,
    GRASP_FRAMES,
    RELEASE_FRAMES,
    SessionGloveBackend,
)
from stag_glove.synthetic import EMPTY_HAND, SyntheticConfig, SyntheticGlove


def test_session_grasps_hold_the_object_without_lifting_it():
    rate_hz = 7.3
    backend = SessionGloveBackend(objects=2, rate_hz=rate_hz, seed=3, short_probability=0.0)
    assert backend.total_frames == EMPTY_FIRST_FRAMES + 2 * EPISODE_FRAMES
    frames, truths = [], []
    now = 0
    while backend.frames_sent < backend.total_frames:
        got = backend.poll(now)
        frames += [f.raw for f in got]
        truths += [backend.truth[0]] * len(got)  # one frame per poll at the frame period
        now += round(1e9 / rate_hz)
    assert len(frames) == backend.total_frames

    # the same script, written out: grasps without a load
    glove = SyntheticGlove(SyntheticConfig(seed=3))
    session = glove.new_session()
    expected = list(glove.record(None, session, EMPTY_FIRST_FRAMES).raw)
    names = [EMPTY_HAND] * EMPTY_FIRST_FRAMES
    for obj in backend.objects:
        same = glove.objects[[o.name for o in glove.objects].index(obj.name)]
        expected += list(glove.record(same, session, GRASP_FRAMES).raw)
        expected += list(glove.record(None, session, RELEASE_FRAMES, pose="empty").raw)
        names += [obj.name] * GRASP_FRAMES + [EMPTY_HAND] * RELEASE_FRAMES
    np.testing.assert_array_equal(np.stack(frames), np.stack(expected))
    assert truths == names
