"""force_estimator node on the rclpy stand-in: topics, stamps, NaN handling, diagnostics, start errors."""
from pathlib import Path

import numpy as np
import pytest

from prisma_force_estimator.bundle import BundleError, save_untrained_bundle
from prisma_force_estimator.inference import ForceEstimator
from prisma_force_estimator.node_config import EstimatorConfig, ParameterError

CONFIG = Path(__file__).resolve().parents[1] / "config" / "force_estimator.yaml"
FINGERS = ("thumb", "index", "middle", "ring", "little")


@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("node")
    return {"cnn2": save_untrained_bundle(root / "cnn2", "cnn2", seed=4),
            "cnn": save_untrained_bundle(root / "cnn", "cnn", seed=5)}


@pytest.fixture
def node_cls(ros):
    from prisma_force_estimator.force_estimator_node import ForceEstimatorNode
    return ForceEstimatorNode


def stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def taxel_msg(finger, stamp, voltages, frame_id=None):
    from builtin_interfaces.msg import Time
    from prisma_msgs.msg import TaxelArray
    from std_msgs.msg import Header
    header = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id=frame_id or f"prisma_{finger}_pad")
    counts = np.clip(np.nan_to_num(np.asarray(voltages)) / 3.3 * 4096, 0, 4095).astype(np.uint16)
    return TaxelArray(header=header, finger=finger, counts=counts, voltages=np.asarray(voltages, dtype=np.float32))


def test_config_yaml_matches_declared_defaults():
    import yaml
    params = yaml.safe_load(CONFIG.read_text())["force_estimator"]["ros__parameters"]
    flat = {k: v for k, v in params.items() if k != "finger_bundles"}
    flat.update({f"finger_bundles.{f}": p for f, p in params["finger_bundles"].items()})
    assert flat == EstimatorConfig().as_parameters()


def test_one_wrench_per_taxel_message_with_the_input_stamp(ros, node_cls, bundles):
    from geometry_msgs.msg import WrenchStamped
    ros.params_file(CONFIG)
    ros.override(model_bundle=str(bundles["cnn2"]))
    node_cls()
    wrenches = {f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS}
    rng = np.random.default_rng(0)
    reference = ForceEstimator.from_bundle(bundles["cnn2"])
    sent = {f: [] for f in FINGERS}
    for k in range(3):
        stamp = ros.now_ns() + k * 10_000_000
        for f in FINGERS:
            v = rng.uniform(0.4, 2.5, 9).astype(np.float32)
            sent[f].append((stamp, v))
            ros.publish(f"/prisma/{f}/taxels", taxel_msg(f, stamp, v))
        ros.process()
    for f in FINGERS:
        got = wrenches[f]
        assert [stamp_ns(m) for m in got] == [s for s, _ in sent[f]]
        assert all(m.header.frame_id == f"prisma_{f}_pad" for m in got)
        expected = reference.estimate(np.stack([v for _, v in sent[f]]))
        w = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                       m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for m in got])
        np.testing.assert_allclose(w, expected, atol=1e-5)


def test_nan_input_is_counted_and_does_not_stop_the_node(ros, node_cls, bundles):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from geometry_msgs.msg import WrenchStamped
    ros.override(model_bundle=str(bundles["cnn2"]), fingers=["thumb", "index"])
    node_cls()
    wrenches = ros.collect(WrenchStamped, "/prisma/thumb/wrench")
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    bad = np.full(9, 0.5, dtype=np.float32)
    bad[4] = np.nan
    t0 = ros.now_ns()
    ros.publish("/prisma/thumb/taxels", taxel_msg("thumb", t0, bad))
    ros.publish("/prisma/index/taxels", taxel_msg("index", t0, np.full(9, 0.5)))
    ros.publish("/prisma/thumb/taxels", taxel_msg("thumb", t0 + 10_000_000, np.full(9, 0.6)))
    ros.publish("/prisma/index/taxels", taxel_msg("index", t0 + 10_000_000, np.full(9, 0.6)))
    ros.advance(1.0)
    assert [stamp_ns(m) for m in wrenches] == [t0 + 10_000_000]
    assert np.isfinite(wrenches[0].wrench.force.z)
    status = {s.name: s for s in diagnostics[-1].status}
    thumb = status["force_estimator: thumb"]
    values = {kv.key: kv.value for kv in thumb.values}
    assert thumb.level == DiagnosticStatus.WARN and "1 sample(s) rejected" in thumb.message
    assert values == {"received": "2", "estimated": "1", "rejected": "1", "model_kind": "cnn2"}
    assert status["force_estimator: index"].level == DiagnosticStatus.OK
    assert set(status) == {"force_estimator: thumb", "force_estimator: index"}


def test_per_finger_bundle_override_and_frame_id_format(ros, node_cls, bundles):
    from geometry_msgs.msg import WrenchStamped
    ros.override(model_bundle=str(bundles["cnn2"]), fingers=["thumb", "index"],
                 frame_id_format="{finger}_tip")
    ros.override(**{"finger_bundles.thumb": str(bundles["cnn"])})
    node = node_cls()
    assert node.pipeline.estimators["thumb"].model_kind == "cnn"
    assert node.pipeline.estimators["index"].model_kind == "cnn2"
    thumb = ros.collect(WrenchStamped, "/prisma/thumb/wrench")
    index = ros.collect(WrenchStamped, "/prisma/index/wrench")
    t0 = ros.now_ns()
    for f in ("thumb", "index"):
        ros.publish(f"/prisma/{f}/taxels", taxel_msg(f, t0, np.full(9, 1.0)))
    ros.process()
    assert thumb[0].header.frame_id == "thumb_tip" and index[0].header.frame_id == "index_tip"
    assert np.isnan(thumb[0].wrench.torque.x)  # a force-only network estimates no torque
    assert np.isfinite(index[0].wrench.torque.x)


def test_missing_bundle_fails_at_start_with_the_path(ros, node_cls, tmp_path):
    missing = tmp_path / "no_such_bundle"
    ros.override(model_bundle=str(missing))
    with pytest.raises(BundleError) as err:
        node_cls()
    assert str(missing) in str(err.value) and "does not exist" in str(err.value)


def test_mismatched_bundle_fails_at_start_with_the_problem(ros, node_cls, bundles, tmp_path):
    import json
    import shutil
    broken = tmp_path / "broken"
    shutil.copytree(bundles["cnn2"], broken)
    meta = json.loads((broken / "metadata.json").read_text())
    meta["normalisation"]["input"] = {"mean": [0.0] * 12, "std": [1.0] * 12}
    (broken / "metadata.json").write_text(json.dumps(meta))
    ros.override(model_bundle=str(bundles["cnn2"]))
    ros.override(**{"finger_bundles.ring": str(broken)})
    with pytest.raises(BundleError, match="normalisation.input has 12 channels, expected 9") as err:
        node_cls()
    assert str(broken) in str(err.value)


@pytest.mark.parametrize("name,value,message", [
    ("fingers", ["thumb", "pinky"], "'pinky' is not one of"),
    ("torch_threads", 0, "'torch_threads' = 0"),
    ("batch_window", -0.1, "'batch_window' = -0.1"),
    ("frame_id_format", "{hand}", "'frame_id_format'"),
])
def test_invalid_parameters_fail_at_start(ros, node_cls, bundles, name, value, message):
    ros.override(model_bundle=str(bundles["cnn2"]), **{name: value})
    with pytest.raises(ParameterError, match=message):
        node_cls()


def test_behind_the_simulated_tactile_driver_every_scan_gets_wrenches(ros, node_cls, bundles):
    from geometry_msgs.msg import WrenchStamped
    from prisma_msgs.msg import TaxelArray
    from prisma_tactile_driver.tactile_driver_node import TactileDriverNode
    ros.override(node="force_estimator", model_bundle=str(bundles["cnn2"]))
    TactileDriverNode()
    node_cls()
    taxels = {f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS}
    wrenches = {f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS}
    ros.advance(0.5)
    ros.process()
    for f in FINGERS:
        assert len(taxels[f]) == 50
        # a whole scan is estimated as soon as its fifth finger arrives, so nothing lags behind
        assert [stamp_ns(m) for m in wrenches[f]] == [stamp_ns(m) for m in taxels[f]]


def test_main_exits_with_the_bundle_problem_logged(real_rclpy, tmp_path, capfd):
    if real_rclpy:
        pytest.skip("runs main() on the stand-in's default context")
    from prisma_force_estimator.force_estimator_node import main
    with pytest.raises(SystemExit) as exit_info:
        main(["force_estimator", "--ros-args", "-p", f"model_bundle:={tmp_path / 'gone'}"])
    assert exit_info.value.code == 1
    assert f"model bundle {tmp_path / 'gone'}: directory does not exist" in "".join(capfd.readouterr())
