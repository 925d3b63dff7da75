"""glove_driver and glove_perception nodes on the rclpy stand-in: topics, image, the empty-hand
service, diagnostics, serial and replay backends, parameters, model bundles."""
import os
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from stag_glove.bundle import save_bundle
from stag_glove.dataset import save_hdf5
from stag_glove.models import TouchNet, WeightNet
from stag_glove.node_config import GloveDriverConfig, GlovePerceptionConfig, ParameterError
from stag_glove.processing import normalise
from stag_glove.protocol import encode_frame
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove

ROOT = Path(__file__).resolve().parents[1]
DRIVER_YAML = ROOT / "config" / "glove_driver.yaml"
PERCEPTION_YAML = ROOT / "config" / "glove_perception.yaml"


@pytest.fixture(autouse=True)
def restore_threads():
    """glove_perception limits torch/BLAS threads for its process; give other tests theirs back."""
    from stag_glove import perception
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)
    if perception._thread_limit is not None:
        perception._thread_limit.restore_original_limits()
        perception._thread_limit = None


@pytest.fixture
def driver_cls(ros):
    from stag_glove.glove_driver_node import GloveDriverNode
    return GloveDriverNode


@pytest.fixture
def perception_cls(ros):
    from stag_glove.glove_perception_node import GlovePerceptionNode
    return GlovePerceptionNode


def stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


@pytest.fixture(scope="module")
def tiny_bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundles")
    torch.manual_seed(0)
    save_bundle(root / "object", "object", TouchNet(3, 2, width=4), {"width": 4, "n_frames": 2, "labels": ["a", "b", "c"]})
    save_bundle(root / "pose", "pose", TouchNet(2, 1, width=4), {"width": 4, "n_frames": 1, "labels": ["open", "fist"]})
    save_bundle(root / "weight", "weight", WeightNet(width=4), {"width": 4, "linear_baseline": {"a": 1.0, "b": 5.0}})
    return {k: str(root / k) for k in ("object", "pose", "weight")}


def test_config_yaml_matches_declared_defaults():
    driver = yaml.safe_load(DRIVER_YAML.read_text())["glove_driver"]["ros__parameters"]
    assert driver == GloveDriverConfig().as_parameters()
    perception = yaml.safe_load(PERCEPTION_YAML.read_text())["glove_perception"]["ros__parameters"]
    assert perception == GlovePerceptionConfig().as_parameters()


def test_sim_driver_publishes_frames_and_32fc1_images_at_7_3_hz(ros, driver_cls):
    from prisma_msgs.msg import GloveFrame
    from sensor_msgs.msg import Image
    ros.params_file(DRIVER_YAML)
    ros.override(sim_short_probability=0.0)
    start = ros.now_ns()
    driver_cls()
    frames = ros.collect(GloveFrame, "/stag/frame")
    images = ros.collect(Image, "/stag/image")
    ros.advance(3.0)
    assert len(frames) == len(images) == 22  # 7.3 frames/s for 3 s, the first at the first poll
    stamps = np.array([stamp_ns(m) for m in frames])
    np.testing.assert_allclose(np.diff(stamps), 1e9 / 7.3, atol=1)
    assert start < stamps[0] <= start + 20_000_000
    msg = frames[-1]
    assert (msg.rows, msg.cols, msg.header.frame_id) == (32, 32, "stag_glove")
    raw = np.asarray(msg.raw).reshape(32, 32)
    np.testing.assert_allclose(np.asarray(msg.pressure).reshape(32, 32), normalise(raw), atol=1e-6)
    image = images[-1]
    assert (image.encoding, image.height, image.width, image.step) == ("32FC1", 32, 32, 128)
    assert stamp_ns(image) == stamp_ns(msg)
    np.testing.assert_array_equal(np.frombuffer(np.asarray(image.data, np.uint8).tobytes(), "<f4"),
                                  np.asarray(msg.pressure, np.float32))


def test_capture_empty_hand_service_and_diagnostics(ros, driver_cls):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from prisma_msgs.msg import GloveFrame
    from std_srvs.srv import Trigger
    ros.override(empty_hand_frames=50, sim_short_probability=0.0)
    driver_cls()
    frames = ros.collect(GloveFrame, "/stag/frame")
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    early = ros.call(Trigger, "/glove_driver/capture_empty_hand", Trigger.Request())
    assert early.success is False and "need 50 good frames" in early.message
    ros.advance(7.5)  # the simulated wearer moves the empty hand for the first ~8 s (60 frames)
    assert sum(m.contact for m in frames) > 20  # uncalibrated: bending fingers press the glove
    response = ros.call(Trigger, "/glove_driver/capture_empty_hand", Trigger.Request())
    assert response.success is True and "50 frames" in response.message
    before = len(frames)
    ros.advance(0.6)
    assert len(frames) - before == 4 and not any(m.contact for m in frames[before:])  # still empty
    status = diagnostics[-1].status[0]
    assert status.name == "glove_driver: readout" and status.level == DiagnosticStatus.OK
    values = {kv.key: kv.value for kv in status.values}
    assert values["empty_hand_calibrated"] == "True" and int(values["frames_processed"]) == len(frames)


def test_shorted_frames_are_published_flagged(ros, driver_cls):
    from prisma_msgs.msg import GloveFrame
    ros.override(sim_short_probability=0.3, sim_seed=4)
    driver_cls()
    frames = ros.collect(GloveFrame, "/stag/frame")
    ros.advance(4.0)
    shorted = [m for m in frames if m.shorted]
    assert shorted and all((np.asarray(m.raw) > 950).any() and not m.contact for m in shorted)
    assert all(not (np.asarray(m.raw) > 950).any() for m in frames if not m.shorted)


def test_serial_backend_reads_the_readout_board(ros, driver_cls):
    from prisma_msgs.msg import GloveFrame
    master, slave = os.openpty()
    try:
        ros.override(backend="serial", port=os.ttyname(slave))
        driver_cls()
        frames = ros.collect(GloveFrame, "/stag/frame")
        ros.advance(0.02)  # first poll opens the port
        rng = np.random.default_rng(1)
        sent = [rng.integers(400, 900, (32, 32)) for _ in range(3)]
        sent[1][5, 5] = 1000
        os.write(master, b"\x00junk" + b"".join(encode_frame(r, i) for i, r in enumerate(sent)))
        for _ in range(100):
            ros.advance(0.02)
            if len(frames) == 3:
                break
        assert [np.asarray(m.raw).reshape(32, 32).tolist() for m in frames] == [r.tolist() for r in sent]
        assert [m.shorted for m in frames] == [False, True, False]
    finally:
        os.close(master)
        os.close(slave)


def test_replay_backend_publishes_the_file(ros, driver_cls, tmp_path):
    from prisma_msgs.msg import GloveFrame
    ds = SyntheticGlove(SyntheticConfig(n_objects=1, sessions=1, test_sessions=(0,), frames_per_session=8)).object_dataset()
    save_hdf5(ds, tmp_path / "rec.h5")
    ros.override(backend="replay", replay_file=str(tmp_path / "rec.h5"), replay_loop=False, frame_rate_hz=10.0)
    driver_cls()
    frames = ros.collect(GloveFrame, "/stag/frame")
    ros.advance(3.0)
    assert len(frames) == len(ds) == 16
    np.testing.assert_array_equal(np.stack([np.asarray(m.raw).reshape(32, 32) for m in frames]), ds.pressure)


@pytest.mark.parametrize("override, name, bad", [
    ({"backend": "usb"}, "backend", "usb"),
    ({"backend": "replay"}, "replay_file", "''"),
    ({"backend": "replay", "replay_file": "/nonexistent/metadata.mat"}, "replay_file", "/nonexistent/metadata.mat"),
    ({"normalisation_high": 400.0}, "normalisation_high", "400.0"),
    ({"short_threshold": 2000}, "short_threshold", "2000"),
    ({"layout_file": "config/glove/nope.yaml"}, "layout_file", "nope.yaml"),
])
def test_driver_rejects_invalid_parameters_at_start(ros, driver_cls, override, name, bad):
    ros.override(**override)
    with pytest.raises(ParameterError) as info:
        driver_cls()
    assert f"'{name}'" in str(info.value) and bad in str(info.value)


def glove_frame(ros, stamp, pressure, contact=True, shorted=False):
    from prisma_msgs.msg import GloveFrame
    raw = (500 + 150 * pressure).astype(np.uint16)
    if shorted:
        raw[0, 0] = 1000
    msg = GloveFrame(rows=32, cols=32, raw=raw.ravel(), pressure=pressure.astype(np.float32).ravel(),
                     shorted=shorted, contact=contact and not shorted)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
    return msg


def test_perception_node_publishes_object_pose_weight_and_ignores_shorted(ros, perception_cls, tiny_bundles):
    from prisma_msgs.msg import ObjectEstimate, WeightEstimate
    ros.override(object_bundle=tiny_bundles["object"], pose_bundle=tiny_bundles["pose"],
                 weight_bundle=tiny_bundles["weight"])
    perception_cls()
    objects = ros.collect(ObjectEstimate, "/stag/object")
    poses = ros.collect(ObjectEstimate, "/stag/hand_pose")
    weights = ros.collect(WeightEstimate, "/stag/weight")
    rng = np.random.default_rng(0)
    base = 1_700_000_000 * 10**9
    ros.publish("/stag/frame", glove_frame(ros, base, rng.random((32, 32)) * 0.3, shorted=True))
    ros.process()
    assert (len(objects), len(poses), len(weights)) == (0, 0, 0)
    for k in range(3):
        ros.publish("/stag/frame", glove_frame(ros, base + k, rng.random((32, 32)) * 0.3))
        ros.process()
    ros.publish("/stag/frame", glove_frame(ros, base + 3, rng.random((32, 32)) * 0.1, contact=False))
    ros.process()
    assert (len(objects), len(poses), len(weights)) == (2, 4, 3)  # object from the 2nd contact frame on
    assert [stamp_ns(m) for m in objects] == [base + 1, base + 2]
    assert objects[-1].frames_used == 2 and list(objects[-1].labels) == ["a", "b", "c"]
    assert poses[-1].label in ("open", "fist") and poses[-1].frames_used == 1
    assert weights[-1].grams > 0 and weights[-1].header.frame_id == "stag_glove"


def test_perception_fails_at_start_on_a_missing_or_mismatched_bundle(ros, perception_cls, tiny_bundles, tmp_path):
    ros.override(object_bundle=str(tmp_path / "missing"))
    with pytest.raises(ParameterError, match=r"'object_bundle'.*missing"):
        perception_cls()


def test_perception_rejects_a_pose_bundle_given_as_object_model(ros, perception_cls, tiny_bundles):
    ros.override(object_bundle=tiny_bundles["pose"])
    with pytest.raises(ParameterError, match=r"'object_bundle'.*holds a 'pose' model"):
        perception_cls()


def test_default_bundles_drive_the_graph_from_the_simulated_glove(ros, driver_cls, perception_cls):
    """The shipped models (config/models/glove_*) on the simulated glove: after the empty-hand
    capture the object estimate appears once N contact frames are buffered."""
    from prisma_msgs.msg import ObjectEstimate, WeightEstimate
    from std_srvs.srv import Trigger
    ros.params_file(DRIVER_YAML)
    ros.params_file(PERCEPTION_YAML)
    ros.override(node="glove_driver", sim_short_probability=0.0)
    driver_cls()
    perception_cls()
    objects = ros.collect(ObjectEstimate, "/stag/object")
    poses = ros.collect(ObjectEstimate, "/stag/hand_pose")
    weights = ros.collect(WeightEstimate, "/stag/weight")
    ros.advance(4.5)
    assert ros.call(Trigger, "/glove_driver/capture_empty_hand", Trigger.Request()).success
    ros.advance(8.0)
    assert len(poses) > 80
    assert objects and weights
    assert objects[-1].frames_used == 8 and len(objects[-1].labels) == 27
    assert 0 < objects[-1].confidence <= 1
