"""glove_perception node on real rclpy over DDS: object, hand pose and weight from GloveFrames,
shorted frames ignored, model bundles checked at start, the shipped bundles fed by the simulated
glove through glove_driver, and main() as a process (a bad bundle exits 1, SIGINT exits 0).
"""

import numpy as np
import pytest
import torch

from prisma_testing.node_process import external_shutdown_command, run_process, start_and_interrupt
from prisma_testing.repo_paths import CONFIG, node_parameters
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from prisma_msgs.msg import GloveFrame, ObjectEstimate, WeightEstimate  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from prisma_common.parameters import ParameterError
from stag_glove.bundle import save_bundle  # noqa: E402
from stag_glove.models import TouchNet, WeightNet  # noqa: E402
from stag_glove.node_config import GlovePerceptionConfig  # noqa: E402

DRIVER_YAML = CONFIG / "glove_driver.yaml"
PERCEPTION_YAML = CONFIG / "glove_perception.yaml"
POLL_STEP = 0.02  # advance in the driver's poll period (50 Hz)


@pytest.fixture(scope="module")
def tiny_bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundles")
    torch.manual_seed(0)
    save_bundle(root / "object", "object", TouchNet(3, 2, width=4),
                {"width": 4, "n_frames": 2, "labels": ["a", "b", "c"]})
    save_bundle(root / "pose", "pose", TouchNet(2, 1, width=4), {"width": 4, "n_frames": 1, "labels": ["open", "fist"]})
    save_bundle(root / "weight", "weight", WeightNet(width=4), {"width": 4, "linear_baseline": {"a": 1.0, "b": 5.0}})
    return {k: str(root / k) for k in ("object", "pose", "weight")}


def test_config_yaml_matches_declared_defaults():
    assert node_parameters(PERCEPTION_YAML, "glove_perception") == GlovePerceptionConfig().as_parameters()


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


def test_release_frames_changes_at_run_time_the_models_do_not(ros, perception_cls, tiny_bundles):
    node = ros.node(perception_cls, params={"object_bundle": tiny_bundles["object"]})
    (ok,) = ros.set_parameters("/glove_perception", release_frames=5)
    assert ok.successful and node.perception.config.release_frames == 5 and node.config.release_frames == 5
    for name, value in (("object_bundle", ""), ("selection", "random"), ("buffer_size", 8)):
        (refused,) = ros.set_parameters("/glove_perception", **{name: value})
        assert (refused.successful, refused.reason) == (False, f"Trying to set a read-only parameter: {name}.")
    assert node.perception.config.selection == "cluster"


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
PERCEPTION_RUN = ["ros2", "run", "stag_glove", "glove_perception"]


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


def test_perception_main_exits_0_on_sigint_without_a_traceback(ros):
    result = start_and_interrupt(PERCEPTION_RUN, "; selection cluster", ros, "/glove_perception")
    assert result.returncode == 0, result.output
    assert "[glove_perception]: object: " in result.output and "Traceback" not in result.output


def test_main_exits_0_when_its_context_is_shut_down_from_outside():
    result = run_process(external_shutdown_command("stag_glove.glove_perception_node"))
    assert result.returncode == 0, result.output
    assert "[glove_perception]: " in result.output and "Traceback" not in result.output
