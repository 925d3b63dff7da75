"""glove_driver and glove_perception nodes on real rclpy over DDS: topics, image, the empty-hand
service, diagnostics, serial and replay backends, parameters, model bundles, and their main() as a
process (a bad parameter or bundle exits 1, SIGINT exits 0).

The sim and replay backends are paced by the node's clock: under sim time (a /clock the test
publishes) their frames carry exact stamps, one every round(1e9 / rate) ns from the first poll.
"""
import os

import numpy as np
import pytest
import torch
import yaml

from repo_paths import CONFIG
from ros_harness import external_shutdown_command, require_ros, run_process, stamp_ns, start_and_interrupt

require_ros()

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from prisma_msgs.msg import GloveFrame, ObjectEstimate, WeightEstimate  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from prisma_common.parameters import ParameterError
from stag_glove.bundle import save_bundle  # noqa: E402
from stag_glove.dataset import save_hdf5  # noqa: E402
from stag_glove.models import TouchNet, WeightNet  # noqa: E402
from stag_glove.node_config import GloveDriverConfig, GlovePerceptionConfig  # noqa: E402
from stag_glove.processing import normalise  # noqa: E402
from stag_glove.protocol import encode_frame  # noqa: E402
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove  # noqa: E402

DRIVER_YAML = CONFIG / "glove_driver.yaml"
PERCEPTION_YAML = CONFIG / "glove_perception.yaml"
SIM_PERIOD_NS = round(1e9 / 7.3)  # 136_986_301: the simulated glove's frame period
POLL_STEP = 0.02  # advance in the driver's poll period (50 Hz)


@pytest.fixture(autouse=True)
def restore_threads():
    """glove_perception limits torch/BLAS threads for its process; give other tests theirs back."""
    from stag_glove import glove_perception_core
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)
    if glove_perception_core._thread_limit is not None:
        glove_perception_core._thread_limit.restore_original_limits()
        glove_perception_core._thread_limit = None


@pytest.fixture
def driver_cls():
    from stag_glove.glove_driver_node import GloveDriverNode
    return GloveDriverNode


@pytest.fixture
def perception_cls():
    from stag_glove.glove_perception_node import GlovePerceptionNode
    return GlovePerceptionNode


@pytest.fixture(scope="module")
def tiny_bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundles")
    torch.manual_seed(0)
    save_bundle(root / "object", "object", TouchNet(3, 2, width=4),
                {"width": 4, "n_frames": 2, "labels": ["a", "b", "c"]})
    save_bundle(root / "pose", "pose", TouchNet(2, 1, width=4), {"width": 4, "n_frames": 1, "labels": ["open", "fist"]})
    save_bundle(root / "weight", "weight", WeightNet(width=4), {"width": 4, "linear_baseline": {"a": 1.0, "b": 5.0}})
    return {k: str(root / k) for k in ("object", "pose", "weight")}


def node_parameters(path, node):
    """A node's section of a parameter file (keyed by node name, bare or `/**/`-prefixed)."""
    sections = yaml.safe_load(path.read_text())
    (key,) = [k for k in sections if k.split("/")[-1] == node]
    return sections[key]["ros__parameters"]


def test_config_yaml_matches_declared_defaults():
    assert node_parameters(DRIVER_YAML, "glove_driver") == GloveDriverConfig().as_parameters()
    assert node_parameters(PERCEPTION_YAML, "glove_perception") == GlovePerceptionConfig().as_parameters()


def test_sim_driver_publishes_frames_and_32fc1_images_at_7_3_hz(ros, driver_cls):
    frames = ros.collect(GloveFrame, "/stag/frame")
    images = ros.collect(Image, "/stag/image")
    ros.node(driver_cls, params_files=[DRIVER_YAML], params={"sim_short_probability": 0.0}, sim_time=True)
    start = ros.now_ns()
    ros.advance(3.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(frames) == len(images) == 22)  # 7.3 frames/s for 3 s, the first at the start
    ros.spin_for(0.1)
    assert len(frames) == len(images) == 22
    # the first poll runs at the start instant; the frames follow at exactly 1/7.3 s
    assert [stamp_ns(m) for m in frames] == [start + k * SIM_PERIOD_NS for k in range(22)]
    assert [stamp_ns(m) for m in images] == [stamp_ns(m) for m in frames]
    msg = frames[-1]
    assert (msg.rows, msg.cols, msg.header.frame_id) == (32, 32, "stag_glove")
    raw = np.asarray(msg.raw).reshape(32, 32)
    np.testing.assert_allclose(np.asarray(msg.pressure).reshape(32, 32), normalise(raw), atol=1e-6)
    image = images[-1]
    assert (image.encoding, image.height, image.width, image.step) == ("32FC1", 32, 32, 128)
    assert image.header.frame_id == "stag_glove"
    np.testing.assert_array_equal(np.frombuffer(np.asarray(image.data, np.uint8).tobytes(), "<f4"),
                                  np.asarray(msg.pressure, np.float32))


def test_capture_empty_hand_service_and_diagnostics(ros, driver_cls):
    frames = ros.collect(GloveFrame, "/stag/frame")
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.capture_logs()
    ros.node(driver_cls, params={"empty_hand_frames": 50, "sim_short_probability": 0.0}, sim_time=True)
    start = ros.now_ns()
    early = ros.call(Trigger, "/glove_driver/capture_empty_hand", Trigger.Request())
    assert early.success is False and "need 50 good frames" in early.message
    assert "have 1;" in early.message  # the frame of the first poll, at the start instant
    assert ros.wait_for_log(severity="warn", name="glove_driver", contains="need 50 good frames")
    ros.advance(7.5, step=POLL_STEP)  # the simulated wearer moves the empty hand for the first ~8 s
    assert ros.spin_until(lambda: len(frames) == 55)  # frames at k / 7.3 s for k = 0..54
    assert sum(m.contact for m in frames) > 20  # uncalibrated: bending fingers press the glove
    response = ros.call(Trigger, "/glove_driver/capture_empty_hand", Trigger.Request())
    assert response.success is True and "50 frames" in response.message
    assert ros.wait_for_log(severity="info", name="glove_driver", contains="empty-hand calibration from 50 frames")
    ros.advance(0.55, step=POLL_STEP)  # to 8.05 s: frames 55..58 (7.534 s .. 7.945 s)
    assert ros.spin_until(lambda: len(frames) == 59 and len(diagnostics) == 9)  # diagnostics at 0 s .. 8 s
    ros.spin_for(0.1)
    assert len(frames) == 59 and not any(m.contact for m in frames[55:])  # still empty: no contact
    assert [stamp_ns(m) - start for m in diagnostics] == [k * 10**9 for k in range(9)]
    status = diagnostics[-1].status[0]
    assert status.name == "glove_driver: readout" and status.level == DiagnosticStatus.OK
    values = {kv.key: kv.value for kv in status.values}
    assert values["empty_hand_calibrated"] == "True" and int(values["frames_processed"]) == len(frames)


def test_shorted_frames_are_published_flagged(ros, driver_cls):
    frames = ros.collect(GloveFrame, "/stag/frame")
    ros.node(driver_cls, params={"sim_short_probability": 0.3, "sim_seed": 4}, sim_time=True)
    ros.advance(4.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(frames) == 30)  # frames at k / 7.3 s for k = 0..29
    shorted = [m for m in frames if m.shorted]
    assert shorted and all((np.asarray(m.raw) > 950).any() and not m.contact for m in shorted)
    assert all(not (np.asarray(m.raw) > 950).any() for m in frames if not m.shorted)


def test_serial_backend_reads_the_readout_board(ros, driver_cls):
    frames = ros.collect(GloveFrame, "/stag/frame")
    master, slave = os.openpty()
    try:
        node = ros.node(driver_cls, params={"backend": "serial", "port": os.ttyname(slave)})
        # the first poll opens the port (and sets it raw) before the board's bytes arrive
        assert ros.spin_until(lambda: node.driver.backend.stats.opens == 1)
        rng = np.random.default_rng(1)
        sent = [rng.integers(400, 900, (32, 32)) for _ in range(3)]
        sent[1][5, 5] = 1000
        os.write(master, b"\x00junk" + b"".join(encode_frame(r, i) for i, r in enumerate(sent)))
        assert ros.spin_until(lambda: len(frames) == 3)
        ros.spin_for(0.1)
        assert [np.asarray(m.raw).reshape(32, 32).tolist() for m in frames] == [r.tolist() for r in sent]
        assert [m.shorted for m in frames] == [False, True, False]
    finally:
        os.close(master)
        os.close(slave)


def test_replay_backend_publishes_the_file(ros, driver_cls, tmp_path):
    config = SyntheticConfig(n_objects=1, sessions=1, test_sessions=(0,), frames_per_session=8)
    ds = SyntheticGlove(config).object_dataset()
    save_hdf5(ds, tmp_path / "rec.h5")
    frames = ros.collect(GloveFrame, "/stag/frame")
    ros.node(driver_cls, params={"backend": "replay", "replay_file": str(tmp_path / "rec.h5"), "replay_loop": False,
                                 "frame_rate_hz": 10.0}, sim_time=True)
    start = ros.now_ns()
    ros.advance(3.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(frames) == 16)
    ros.spin_for(0.1)
    assert len(frames) == len(ds) == 16  # the file once, no loop
    assert [stamp_ns(m) for m in frames] == [start + k * 100_000_000 for k in range(16)]
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
    with pytest.raises(ParameterError) as info:
        ros.node(driver_cls, params=override)
    assert info.value.name == name and bad in str(info.value)
    assert str(info.value).startswith(f"invalid parameter '{name}' = ")


def glove_frame(stamp, pressure, contact=True, shorted=False):
    raw = (500 + 150 * pressure).astype(np.uint16)
    if shorted:
        raw[0, 0] = 1000
    msg = GloveFrame(rows=32, cols=32, raw=raw.ravel(), pressure=pressure.astype(np.float32).ravel(),
                     shorted=shorted, contact=contact and not shorted)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
    return msg


def send_frame(ros, node, msg):
    """Publish one GloveFrame and wait until the node has taken it in."""
    before = node.perception.stats.frames
    ros.publish("/stag/frame", msg)
    assert ros.spin_until(lambda: node.perception.stats.frames == before + 1), "the frame never arrived"


def test_perception_node_publishes_object_pose_weight_and_ignores_shorted(ros, perception_cls, tiny_bundles):
    objects = ros.collect(ObjectEstimate, "/stag/object")
    poses = ros.collect(ObjectEstimate, "/stag/hand_pose")
    weights = ros.collect(WeightEstimate, "/stag/weight")
    node = ros.node(perception_cls, params={"object_bundle": tiny_bundles["object"],
                                            "pose_bundle": tiny_bundles["pose"],
                                            "weight_bundle": tiny_bundles["weight"]})
    rng = np.random.default_rng(0)
    base = 1_700_000_000 * 10**9
    send_frame(ros, node, glove_frame(base, rng.random((32, 32)) * 0.3, shorted=True))
    ros.spin_for(0.2)
    assert node.perception.stats.shorted_rejected == 1
    assert (len(objects), len(poses), len(weights)) == (0, 0, 0)
    for k in range(3):
        send_frame(ros, node, glove_frame(base + k, rng.random((32, 32)) * 0.3))
    send_frame(ros, node, glove_frame(base + 3, rng.random((32, 32)) * 0.1, contact=False))
    assert ros.spin_until(lambda: (len(objects), len(poses), len(weights)) == (2, 4, 3))
    ros.spin_for(0.2)
    assert (len(objects), len(poses), len(weights)) == (2, 4, 3)  # object from the 2nd contact frame on
    assert [stamp_ns(m) for m in objects] == [base + 1, base + 2]
    assert [stamp_ns(m) for m in poses] == [base, base + 1, base + 2, base + 3]
    assert [stamp_ns(m) for m in weights] == [base, base + 1, base + 2]
    assert objects[-1].frames_used == 2 and list(objects[-1].labels) == ["a", "b", "c"]
    assert poses[-1].label in ("open", "fist") and poses[-1].frames_used == 1
    assert weights[-1].grams > 0 and weights[-1].header.frame_id == "stag_glove"


def test_perception_fails_at_start_on_a_missing_or_mismatched_bundle(ros, perception_cls, tiny_bundles, tmp_path):
    with pytest.raises(ParameterError, match=r"'object_bundle'.*missing"):
        ros.node(perception_cls, params={"object_bundle": str(tmp_path / "missing")})


def test_perception_rejects_a_pose_bundle_given_as_object_model(ros, perception_cls, tiny_bundles):
    with pytest.raises(ParameterError, match=r"'object_bundle'.*holds a 'pose' model"):
        ros.node(perception_cls, params={"object_bundle": tiny_bundles["pose"]})


def test_default_bundles_drive_the_graph_from_the_simulated_glove(ros, driver_cls, perception_cls):
    """The shipped models (config/models/glove_*) on the simulated glove: after the empty-hand
    capture the object estimate appears once N contact frames are buffered."""
    frames = ros.collect(GloveFrame, "/stag/frame")
    objects = ros.collect(ObjectEstimate, "/stag/object")
    poses = ros.collect(ObjectEstimate, "/stag/hand_pose")
    weights = ros.collect(WeightEstimate, "/stag/weight")
    # perception first: its subscription is matched before the driver's first frame
    perception = ros.node(perception_cls, params_files=[PERCEPTION_YAML], sim_time=True)
    ros.node(driver_cls, params_files=[DRIVER_YAML], params={"sim_short_probability": 0.0}, sim_time=True)
    ros.advance(4.5, step=POLL_STEP)
    assert ros.call(Trigger, "/glove_driver/capture_empty_hand", Trigger.Request()).success
    ros.advance(8.0, step=POLL_STEP)
    # frames at k / 7.3 s up to 12.5 s: 92, each one given a hand pose (none is shorted)
    assert ros.spin_until(lambda: len(frames) == 92 and perception.perception.stats.frames == 92
                          and len(poses) == 92, timeout_sec=30.0)
    assert len(poses) > 80
    assert objects and weights
    assert objects[-1].frames_used == 8 and len(objects[-1].labels) == 27
    assert 0 < objects[-1].confidence <= 1


# ---- main() as a process ------------------------------------------------------------------------
DRIVER_RUN = ["ros2", "run", "stag_glove", "glove_driver"]
PERCEPTION_RUN = ["ros2", "run", "stag_glove", "glove_perception"]


def test_driver_main_logs_an_invalid_parameter_and_exits_1():
    result = run_process([*DRIVER_RUN, "--ros-args", "-p", "backend:=usb"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and "[glove_driver]: invalid parameter 'backend' = 'usb'" in result.output
    assert "Traceback" not in result.output


def test_driver_main_logs_a_missing_replay_file_and_exits_1(tmp_path):
    missing = tmp_path / "metadata.mat"
    result = run_process([*DRIVER_RUN, "--ros-args", "-p", "backend:=replay", "-p", f"replay_file:={missing}"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and f"[glove_driver]: invalid parameter 'replay_file' = '{missing}'" \
        in result.output
    assert "Traceback" not in result.output


def test_perception_main_logs_a_missing_bundle_and_exits_1(tmp_path):
    missing = tmp_path / "missing"
    result = run_process([*PERCEPTION_RUN, "--ros-args", "-p", f"object_bundle:={missing}"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output
    assert f"[glove_perception]: invalid parameter 'object_bundle' = '{missing}'" in result.output
    assert "does not exist" in result.output and "Traceback" not in result.output


def test_perception_main_logs_a_pose_bundle_as_object_model_and_exits_1(tiny_bundles):
    result = run_process([*PERCEPTION_RUN, "--ros-args", "-p", f"object_bundle:={tiny_bundles['pose']}"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and "holds a 'pose' model" in result.output
    assert "Traceback" not in result.output


def test_driver_main_exits_0_on_sigint_without_a_traceback(ros):
    result = start_and_interrupt(DRIVER_RUN, "[glove_driver]: sim backend (sim/seed0), polling at 50 Hz",
                                 ros, "/glove_driver")
    assert result.returncode == 0, result.output
    assert "Traceback" not in result.output


def test_perception_main_exits_0_on_sigint_without_a_traceback(ros):
    result = start_and_interrupt(PERCEPTION_RUN, "; selection cluster", ros, "/glove_perception")
    assert result.returncode == 0, result.output
    assert "[glove_perception]: object: " in result.output and "Traceback" not in result.output


@pytest.mark.parametrize("module, node_name", [
    ("stag_glove.glove_driver_node", "glove_driver"),
    ("stag_glove.glove_perception_node", "glove_perception"),
])
def test_main_exits_0_when_its_context_is_shut_down_from_outside(module, node_name):
    result = run_process(external_shutdown_command(module))
    assert result.returncode == 0, result.output
    assert f"[{node_name}]: " in result.output and "Traceback" not in result.output
