"""Perception core and driver core: shorted frames never reach perception, buffering of contact
frames, release, the empty-hand capture, diagnostics, sim and replay backends."""
import numpy as np
import pytest
import torch

from prisma_common.diagnostics import ERROR, OK, WARN
from stag_glove.bundle import load_bundle, save_bundle
from stag_glove.dataset import save_hdf5
from stag_glove.glove_driver_core import GloveDriver
from stag_glove.glove_perception_core import GlovePerception, PerceptionConfig
from stag_glove.models import TouchNet, WeightNet
from stag_glove.processing import FrameProcessor, ProcessedFrame
from stag_glove.replay_backend import ReplayGloveBackend
from stag_glove.sim_backend import SimGloveBackend
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove

NS = 1_000_000_000


@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundles")
    torch.manual_seed(0)
    save_bundle(root / "object", "object", TouchNet(3, 4, width=4),
                {"width": 4, "n_frames": 4, "labels": ["a", "b", "c"]})
    save_bundle(root / "pose", "pose", TouchNet(2, 1, width=4), {"width": 4, "n_frames": 1, "labels": ["open", "fist"]})
    save_bundle(root / "weight", "weight", WeightNet(width=4),
                {"width": 4, "linear_baseline": {"a": 2.0, "b": 10.0}})
    return {k: load_bundle(root / k, k) for k in ("object", "pose", "weight")}


def frame(stamp, contact=True, shorted=False, seed=0):
    rng = np.random.default_rng(seed)
    pressure = (rng.random((32, 32)) * 0.3).astype(np.float32)
    raw = (500 + 150 * pressure).astype(np.uint16)
    if shorted:
        raw[0, 0] = 1000
    return ProcessedFrame(stamp, raw, pressure, shorted, contact and not shorted)


def test_shorted_frames_never_reach_perception(bundles, monkeypatch):
    perception = GlovePerception(bundles["object"], bundles["pose"], bundles["weight"])
    seen = []
    for name in ("classify_object", "classify_pose", "estimate_weight"):
        original = getattr(perception, name)
        monkeypatch.setattr(perception, name, lambda *a, _o=original, _n=name: seen.append(_n) or _o(*a))
    for i in range(10):
        out = perception.update(frame(i, shorted=True, seed=i))
        assert out.object is None and out.pose is None and out.weight is None
    assert seen == [] and len(perception.buffer) == 0
    assert perception.stats.shorted_rejected == 10


def test_object_decision_after_n_contact_frames_and_release(bundles):
    perception = GlovePerception(bundles["object"], bundles["pose"], bundles["weight"],
                                 PerceptionConfig(buffer_size=6, release_frames=3))
    outs = [perception.update(frame(i, seed=i)) for i in range(5)]
    assert [o.object is not None for o in outs] == [False, False, False, True, True]
    est = outs[-1].object
    assert est.frames_used == 4 and est.labels == ["a", "b", "c"]
    assert est.label == est.labels[int(np.argmax(est.probabilities))]
    assert est.probabilities.sum() == pytest.approx(1.0, abs=1e-5)
    assert all(o.pose is not None and o.weight is not None for o in outs)
    w = outs[0].weight
    assert w.baseline_grams == pytest.approx(2.0 * float(frame(0).pressure.sum()) + 10.0, rel=1e-5)
    assert w.grams > 0
    # no contact: pose only; three frames without contact clear the buffer
    out = perception.update(frame(10, contact=False))
    assert out.pose is not None and out.object is None and out.weight is None
    perception.update(frame(11, contact=False))
    assert len(perception.buffer) == 5
    perception.update(frame(12, contact=False))
    assert len(perception.buffer) == 0 and perception.stats.releases == 1
    for i in range(6):
        perception.update(frame(20 + i, seed=20 + i))
    assert len(perception.buffer) == 6  # bounded by buffer_size


def test_release_frames_changed_while_frames_come(bundles):
    """Lowered below the frames without contact already seen, the next one releases the object."""
    perception = GlovePerception(bundles["object"], None, None, PerceptionConfig(buffer_size=6, release_frames=5))
    for i in range(4):
        perception.update(frame(i, seed=i))
    for i in range(3):
        perception.update(frame(10 + i, contact=False))
    assert len(perception.buffer) == 4
    perception.reconfigure(release_frames=2)
    assert perception.config == PerceptionConfig(buffer_size=6, release_frames=2)
    perception.update(frame(13, contact=False))
    assert len(perception.buffer) == 0 and perception.stats.releases == 1


def test_perception_rejects_wrong_bundles(bundles):
    with pytest.raises(ValueError, match="'pose' model, given as the object model"):
        GlovePerception(object_bundle=bundles["pose"])
    with pytest.raises(ValueError, match="buffer_size 2 is smaller"):
        GlovePerception(bundles["object"], config=PerceptionConfig(buffer_size=2))
    with pytest.raises(ValueError, match="selection"):
        PerceptionConfig(selection="nearest")


def test_driver_flags_shorted_frames_and_calibrates_from_good_ones():
    backend = SimGloveBackend(rate_hz=10.0, seed=1, short_probability=0.2)
    driver = GloveDriver(backend, FrameProcessor(), empty_hand_frames=10)
    assert not driver.capture_empty_hand().success
    frames = []
    for k in range(30):
        frames += driver.poll(k * NS // 10)
    assert len(frames) == 30
    assert [f.stamp_ns for f in frames] == [k * NS // 10 for k in range(30)]
    shorted = [f for f in frames if f.shorted]
    assert shorted and all(not f.contact for f in shorted) and all((f.raw > 950).any() for f in shorted)
    assert driver.stats.shorted == len(shorted)
    assert all(not (r > 950).any() for r in driver.recent)  # shorted frames are not calibration material
    result = driver.capture_empty_hand()
    assert result.success and "10 frames" in result.message


def test_contact_follows_calibration_on_the_simulated_glove():
    """The sim stream starts with the empty hand, then grasps objects: after the empty-hand
    capture, empty-hand frames have no contact and grasp frames do."""
    backend = SimGloveBackend(rate_hz=10.0, seed=2)
    driver = GloveDriver(backend, FrameProcessor(), empty_hand_frames=60)
    uncalibrated = [f.contact for k in range(60) for f in driver.poll(k * NS // 10)]
    assert np.mean(uncalibrated) > 0.3  # the bending hand alone presses the glove
    assert driver.capture_empty_hand().success
    flags, truth = [], []
    for k in range(60, 400):
        for f in driver.poll(k * NS // 10):
            flags.append(f.contact)
            truth.append(backend.truth[1])
    flags, truth = np.array(flags), np.array(truth)
    assert truth.sum() > 100 and (~truth).sum() > 20
    assert flags[truth].mean() > 0.8     # touching an object -> contact (a light touch may not show)
    assert flags[~truth].mean() < 0.1    # open hand between grasps -> no contact


def test_driver_diagnostics_levels():
    backend = SimGloveBackend(rate_hz=10.0, seed=0)
    driver = GloveDriver(backend, FrameProcessor(), stale_timeout_s=1.0, hardware_id="sim")
    driver.poll(0)
    (status,) = driver.diagnostics(0)
    assert status.level == OK and "no empty-hand calibration" in status.message
    assert status.values["frames_processed"] == "1"
    (status,) = driver.diagnostics(3 * NS)  # nothing polled for 3 s
    assert status.level == WARN and "no frame for 3.0 s" in status.message


def test_replay_backend_plays_a_dataset_file_in_order(tmp_path):
    config = SyntheticConfig(n_objects=2, sessions=1, test_sessions=(0,), frames_per_session=10)
    ds = SyntheticGlove(config).object_dataset()
    save_hdf5(ds, tmp_path / "rec.h5")
    backend = ReplayGloveBackend(tmp_path / "rec.h5", rate_hz=10.0, loop=False)
    got = []
    for k in range(40):
        got += backend.poll(k * NS // 10)
    assert len(got) == len(ds) == 30
    np.testing.assert_array_equal(np.stack([f.raw for f in got]), ds.pressure)
    assert backend.finished and not backend.status().connected
    driver = GloveDriver(ReplayGloveBackend(tmp_path / "rec.h5", rate_hz=10.0, loop=False), FrameProcessor())
    for k in range(40):
        driver.poll(k * NS // 10)
    assert driver.diagnostics(4 * NS)[0].level == ERROR
