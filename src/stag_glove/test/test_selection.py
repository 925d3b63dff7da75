"""Frame selection for the N-frame classifier: random and cluster (PCA 8 + k-means)."""
import numpy as np
import pytest
from sklearn.decomposition import PCA

from stag_glove.selection import (
    cluster_frames,
    cluster_ids,
    cluster_tuples,
    embed,
    pca_scores,
    random_tuples,
    select_from_buffer,
)


def grouped_frames(groups=4, per_group=15, seed=0):
    """Frames from `groups` well separated grasp patterns plus noise."""
    rng = np.random.default_rng(seed)
    centres = rng.random((groups, 32, 32)) * 3
    labels = np.repeat(np.arange(groups), per_group)
    return centres[labels] + 0.05 * rng.standard_normal((len(labels), 32, 32)), labels


def test_pca_scores_match_sklearn_up_to_sign():
    rng = np.random.default_rng(1)
    basis = rng.standard_normal((5, 300))
    data = (rng.standard_normal((80, 5)) * [9, 7, 5, 3, 2]) @ basis + 0.01 * rng.standard_normal((80, 300))
    ours = pca_scores(data, 5)
    ref = PCA(5).fit_transform(data)
    for k in range(5):
        assert abs(np.corrcoef(ours[:, k], ref[:, k])[0, 1]) > 0.999
        np.testing.assert_allclose(np.abs(ours[:, k]), np.abs(ref[:, k]), rtol=1e-6, atol=1e-6)


def test_embedding_is_scaled_to_unit_range():
    frames, _ = grouped_frames()
    emb = embed(frames)
    assert emb.shape == (60, 8)
    assert emb.min() == pytest.approx(0.0) and emb.max() == pytest.approx(1.0)


def test_kmeans_recovers_separated_groups():
    frames, labels = grouped_frames()
    found = cluster_frames(frames, 4, seed=0)
    # every true group maps onto exactly one cluster
    for g in range(4):
        assert len(set(found[labels == g])) == 1
    assert len(set(found)) == 4


def test_random_tuples_stay_in_the_anchor_recording_and_pool():
    recording = np.repeat([0, 1, 2], 10)
    pool = np.ones(30, bool)
    pool[[3, 13]] = False
    anchors = np.array([0, 11, 25])
    tuples = random_tuples(anchors, pool, recording, 5, np.random.default_rng(0))
    assert tuples.shape == (3, 5)
    assert (tuples[:, 0] == anchors).all()
    for row in tuples:
        assert len(set(recording[row])) == 1
        assert pool[row[1:]].all()
        assert row[0] not in row[1:]


def test_cluster_tuples_take_one_frame_from_each_other_cluster():
    frames, groups = grouped_frames(groups=4, per_group=10)
    recording = np.zeros(len(frames), int)
    pool = np.ones(len(frames), bool)
    clusters = cluster_ids(frames, recording, pool, k=4, seed=0)
    anchors = np.arange(0, 40, 3)
    tuples = cluster_tuples(anchors, pool, recording, clusters, 4, np.random.default_rng(0))
    for row in tuples:
        assert sorted(clusters[row]) == [0, 1, 2, 3]  # anchor's cluster + the three others


def test_buffer_selection_uses_newest_frame_and_distinct_clusters():
    frames, groups = grouped_frames(groups=3, per_group=8)
    order = np.random.default_rng(2).permutation(len(frames))
    frames, groups = frames[order], groups[order]
    rng = np.random.default_rng(0)
    chosen = select_from_buffer(frames, 3, "cluster", rng)
    assert chosen[0] == len(frames) - 1
    assert sorted(groups[chosen]) == [0, 1, 2]
    for g in range(3):  # the most recent frame of each other group
        if g != groups[-1]:
            assert np.nonzero(groups == g)[0].max() in chosen
    rand = select_from_buffer(frames, 5, "random", rng)
    assert rand[0] == len(frames) - 1 and len(set(rand)) == 5
    with pytest.raises(ValueError, match="at least 8"):
        select_from_buffer(frames[:4], 8, "cluster", rng)
    with pytest.raises(ValueError, match="selection"):
        select_from_buffer(frames, 2, "best", rng)


def test_identical_frames_still_give_n_indices():
    frames = np.zeros((10, 32, 32))
    chosen = select_from_buffer(frames, 4, "cluster", np.random.default_rng(0))
    assert len(chosen) == 4 and len(set(chosen)) == 4
