"""Synthetic glove: layout, determinism, split by session, contact labels, difficulty (one frame
is ambiguous, several frames help), weight set, pose set, decomposition and correlation maps."""
import numpy as np
import pytest
from sklearn.linear_model import LogisticRegression
from threadpoolctl import threadpool_limits

from stag_glove.dataset import SPLIT_TEST, SPLIT_TRAIN
from stag_glove.decomposition import grasp_segments, object_signal, pearson_map, pearson_matrix, region_cca
from stag_glove.layout import load_layout, mask_from_pressure
from stag_glove.processing import normalise
from stag_glove.synthetic import EMPTY_HAND, POSES, SyntheticConfig, SyntheticGlove


@pytest.fixture(scope="module")
def small():
    glove = SyntheticGlove(SyntheticConfig(n_objects=8, frames_per_session=120, seed=5))
    return glove, glove.object_dataset()


def test_default_object_set_shape_and_classes():
    glove = SyntheticGlove(SyntheticConfig(frames_per_session=4))
    assert len(glove.objects) == 26 and glove.class_names()[-1] == EMPTY_HAND
    weights = np.array([o.weight_g for o in glove.objects])
    assert weights.min() >= 15 and weights.max() <= 1000
    assert all(3 <= len(o.modes) <= 5 for o in glove.objects)


def test_deterministic_for_a_seed(small):
    _, ds = small
    again = SyntheticGlove(SyntheticConfig(n_objects=8, frames_per_session=120, seed=5)).object_dataset()
    np.testing.assert_array_equal(ds.pressure, again.pressure)
    other = SyntheticGlove(SyntheticConfig(n_objects=8, frames_per_session=120, seed=6)).object_dataset()
    assert not np.array_equal(ds.pressure, other.pressure)


def test_readout_format_mask_and_session_split(small):
    glove, ds = small
    assert ds.pressure.dtype == np.uint16 and ds.pressure.max() <= 1023
    assert not (ds.pressure > 950).any()  # no shorted frames unless asked for
    np.testing.assert_array_equal(mask_from_pressure(ds.pressure), load_layout().mask)
    session = ds.extras["session"]
    assert set(session[ds.split_id == SPLIT_TEST]) == {2} and set(session[ds.split_id == SPLIT_TRAIN]) == {0, 1}
    assert len(np.unique(ds.recording_id)) == 9 * 3  # one recording per class and session
    for rec in np.unique(ds.recording_id):
        assert len(np.unique(ds.object_id[ds.recording_id == rec])) == 1
    # balanced anchors: the same count per class in each split
    for split in (SPLIT_TRAIN, SPLIT_TEST):
        counts = np.bincount(ds.object_id[ds.is_balanced & (ds.split_id == split)])
        assert len(set(counts)) == 1 and counts[0] > 0
    assert not (ds.is_balanced & ~ds.has_valid_label).any()


def test_object_frames_press_harder_than_open_hand_frames(small):
    glove, ds = small
    p = normalise(ds.pressure).reshape(len(ds), -1).sum(1)
    is_object = ds.object_id < len(glove.objects)
    touching = p[is_object & ds.has_valid_label]
    open_hand = p[is_object & ~ds.has_valid_label]
    assert np.median(touching) > 2 * np.median(open_hand)
    assert 0.6 < ds.has_valid_label[is_object].mean() < 0.95  # pauses between grasps exist


def test_one_frame_is_ambiguous_and_more_frames_help(small):
    """A linear classifier on single frames of held-out sessions is far from perfect, and pooling
    its evidence over random frames of the same recording helps."""
    glove, ds = small
    x = normalise(ds.pressure)[:, glove.mask]
    train = ds.has_valid_label & (ds.split_id == SPLIT_TRAIN)
    test = ds.has_valid_label & (ds.split_id == SPLIT_TEST)
    with threadpool_limits(1):  # multi-threaded BLAS on a shared 2-core machine is slower
        clf = LogisticRegression(max_iter=200).fit(x[train], ds.object_id[train])
    logp = clf.predict_log_proba(x[test])
    y, rec = ds.object_id[test], ds.recording_id[test]
    single = float(np.mean(logp.argmax(1) == y))
    rng = np.random.default_rng(0)
    pooled = []
    for i in range(len(y)):
        others = rng.choice(np.nonzero(rec == rec[i])[0], 7)
        pooled.append(logp[[i, *others]].sum(0).argmax() == y[i])
    assert 1 / 9 < single < 0.8
    assert np.mean(pooled) > single + 0.1


def test_weight_set_is_one_recording_per_object():
    glove = SyntheticGlove(SyntheticConfig(n_objects=4, seed=1))
    ds = glove.weight_dataset(grasps_per_object=3, frames_per_grasp=5)
    assert len(ds) == 4 * 15 and ds.has_valid_label.all()
    np.testing.assert_allclose(ds.weights_g, [o.weight_g for o in glove.objects])
    # heavier objects press harder on average (grip and load grow with weight)
    sums = normalise(ds.pressure).reshape(len(ds), -1).sum(1)
    per_object = [sums[ds.object_id == k].mean() for k in range(4)]
    order = np.argsort(ds.weights_g)
    assert per_object[order[-1]] > per_object[order[0]]


def test_lifts_leave_the_load_free_sets_as_they_were():
    """The lift model's settings (friction, safety margin, force scale) act on recordings with a
    load only: the object and pose sets, which the shipped object and pose bundles were trained on,
    stay the same frames."""
    base = dict(n_objects=4, frames_per_session=30, seed=1)
    other = dict(friction=(0.3, 0.6), lift_safety=3.0, pressure_per_newton=80.0)
    a, b = SyntheticGlove(SyntheticConfig(**base)), SyntheticGlove(SyntheticConfig(**base, **other))
    assert [o.friction for o in a.objects] != [o.friction for o in b.objects]
    np.testing.assert_array_equal(a.object_dataset().pressure, b.object_dataset().pressure)
    np.testing.assert_array_equal(a.pose_dataset(frames_per_session=10).pressure,
                                  b.pose_dataset(frames_per_session=10).pressure)
    assert not np.array_equal(a.weight_dataset(2, 4).pressure, b.weight_dataset(2, 4).pressure)


def test_lift_pressure_sum_follows_the_weight():
    """The grip holding a lift grows with its load, so over the weight set a frame's pressure sum
    correlates with the object's weight (the linear baseline's information), though far from fully:
    contact area, friction and the safety margin vary."""
    ds = SyntheticGlove(SyntheticConfig(seed=0)).weight_dataset(grasps_per_object=2, frames_per_grasp=5)
    sums = normalise(ds.pressure).reshape(len(ds), -1).sum(1)
    r = np.corrcoef(sums, ds.weights_g[ds.object_id])[0, 1]
    assert 0.4 < r < 0.9


def test_pose_set_has_eight_poses():
    glove = SyntheticGlove(SyntheticConfig(seed=2))
    ds = glove.pose_dataset(frames_per_session=30)
    assert ds.objects == list(POSES) and len(ds.objects) == 8
    assert len(ds) == 8 * 3 * 30


def test_shorted_frames_on_request():
    glove = SyntheticGlove(SyntheticConfig(n_objects=1, short_probability=0.5, seed=3))
    rec = glove.record(glove.objects[0], glove.new_session(), 40)
    shorted = (rec.raw > 950).reshape(40, -1).any(1)
    assert 5 < shorted.sum() < 35


def test_decomposition_recovers_the_object_signal():
    """Grasp detection finds the grasps of a recording, and subtracting the onset (hand-pose) frame
    leaves a signal closer to the true object contact than the raw frames are."""
    glove = SyntheticGlove(SyntheticConfig(n_objects=3, gap_frames=(4, 8), seed=4))
    rec = glove.record(glove.objects[1], glove.new_session(), 200)
    pressure = normalise(rec.raw)
    segments = grasp_segments(pressure)
    starts = np.nonzero(np.diff(rec.contact.astype(int)) == 1)[0] + 1
    assert len(segments) >= 0.6 * len(starts)
    for seg in segments:
        assert seg.onset < seg.start <= seg.peak <= seg.end
        assert rec.contact[seg.peak]  # every detected peak is a real grasp
    signal, inside = object_signal(pressure, segments)
    truth = rec.object_field[inside].reshape(inside.sum(), -1)

    def mean_corr(a):
        a = a.reshape(len(a), -1)
        return np.nanmean([np.corrcoef(x, t)[0, 1] for x, t in zip(a, truth) if x.std() > 0 and t.std() > 0])

    assert mean_corr(signal[inside]) > mean_corr(pressure[inside]) + 0.02


def test_pearson_and_cca_maps():
    layout = load_layout()
    rng = np.random.default_rng(0)
    t = 200
    common = rng.standard_normal(t)
    signal = 0.05 * rng.standard_normal((t, 32, 32))
    signal[:, layout.region_mask("thumb_distal")] += common[:, None]
    signal[:, layout.region_mask("index_distal")] += common[:, None]
    r, c = (int(v) for v in np.argwhere(layout.region_mask("thumb_distal"))[0])
    corr = pearson_map(signal, layout.mask, (r, c))
    assert np.nanmin(corr[layout.region_mask("index_distal")]) > 0.9
    assert np.nanmax(np.abs(corr[layout.region_mask("palm")])) < 0.4
    assert np.isnan(corr[~layout.mask]).all()
    matrix = pearson_matrix(signal, layout.mask)
    assert matrix.shape == (548, 548) and np.allclose(np.diag(matrix), 1)
    with threadpool_limits(1):
        names, cca = region_cca(signal, layout)
    i, j, k = names.index("thumb_distal"), names.index("index_distal"), names.index("palm")
    assert cca[i, j] > 0.95 and cca[i, k] < cca[i, j]
    with pytest.raises(ValueError, match="not a sensor"):
        pearson_map(signal, layout.mask, (0, 0))


def test_live_stream_puts_each_object_down_long_enough_for_perception_to_reset():
    from itertools import islice

    from stag_glove.glove_perception_core import PerceptionConfig

    glove = SyntheticGlove(SyntheticConfig(n_objects=8, frames_per_session=4, seed=3))
    frames = list(islice(glove.stream(episode_frames=30, empty_first=20, release_frames=22), 20 + 3 * 52))
    labels = [label for _, label, _ in frames]
    contact = [touching for _, _, touching in frames]
    assert labels[:20] == [EMPTY_HAND] * 20 and not any(contact[:20])
    for episode in range(3):
        start = 20 + episode * 52
        grasp, release = labels[start:start + 30], labels[start + 30:start + 52]
        assert len(set(grasp)) == 1 and grasp[0] != EMPTY_HAND
        assert release == [EMPTY_HAND] * 22 and not any(contact[start + 30:start + 52])
    assert 22 > PerceptionConfig().release_frames  # perception clears its buffer in each pause
