"""force_estimator node on real rclpy over DDS: topics, stamps, NaN handling, diagnostics, the
~/bias service, start errors, and its main() as a process (a bad bundle or parameter exits 1,
SIGINT exits 0).

Taxel messages are published one at a time, each awaited until the node counted it, so the node
sees them in the order a tactile driver publishes them; sim-time tests run the node's diagnostics
timer on a /clock the test publishes.
"""
import json
import shutil

import numpy as np
import pytest
import yaml

from prisma_testing.node_process import external_shutdown_command, run_process, start_and_interrupt
from prisma_testing.repo_paths import CONFIG, node_parameters
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from prisma_msgs.msg import HandTaxels, HandWrench, TaxelArray  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402
from prisma_common.hand_config import HandConfigError  # noqa: E402
from prisma_force_estimator.bundle import BundleError, save_untrained_bundle  # noqa: E402
from prisma_force_estimator.inference import ForceEstimator  # noqa: E402
from prisma_force_estimator.node_config import ForceEstimatorConfig, ParameterError  # noqa: E402
from prisma_hand_sim.pad_model import PadParams  # noqa: E402

CONFIG = CONFIG / "force_estimator.yaml"


@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    root = tmp_path_factory.mktemp("node")
    return {"cnn2": save_untrained_bundle(root / "cnn2", "cnn2", seed=4),
            "cnn": save_untrained_bundle(root / "cnn", "cnn", seed=5)}


@pytest.fixture
def node_cls():
    from prisma_force_estimator.force_estimator_node import ForceEstimatorNode
    return ForceEstimatorNode


def taxel_msg(finger, stamp, voltages, frame_id=None):
    header = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id=frame_id or f"prisma_{finger}_pad")
    counts = np.clip(np.nan_to_num(np.asarray(voltages)) / 3.3 * 4096, 0, 4095).astype(np.uint16)
    return TaxelArray(header=header, finger=finger, counts=counts, voltages=np.asarray(voltages, dtype=np.float32))


def send(ros, node, finger, msg):
    """Publish one TaxelArray and wait until the node has taken it in."""
    before = node.pipeline.counts[finger].received
    ros.publish(f"/prisma/{finger}/taxels", msg)
    assert ros.spin_until(lambda: node.pipeline.counts[finger].received == before + 1), f"{finger} never arrived"


def wrench_rows(msgs):
    return np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                      m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for m in msgs])


def test_config_yaml_matches_declared_defaults():
    params = node_parameters(CONFIG, "force_estimator")
    flat = {k: v for k, v in params.items() if k != "finger_bundles"}
    flat.update({f"finger_bundles.{f}": p for f, p in params["finger_bundles"].items()})
    assert flat == ForceEstimatorConfig().as_parameters()


def test_one_wrench_per_taxel_message_with_the_input_stamp(ros, node_cls, bundles):
    wrenches = {f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS}
    node = ros.node(node_cls, params_files=[CONFIG], params={"model_bundle": str(bundles["cnn2"])})
    rng = np.random.default_rng(0)
    reference = ForceEstimator.from_bundle(bundles["cnn2"])
    sent = {f: [] for f in FINGERS}
    t0 = ros.now_ns()
    for k in range(3):
        stamp = t0 + k * 10_000_000
        for f in FINGERS:
            v = rng.uniform(0.4, 2.5, 9).astype(np.float32)
            sent[f].append((stamp, v))
            send(ros, node, f, taxel_msg(f, stamp, v))
    assert ros.spin_until(lambda: all(len(wrenches[f]) == 3 for f in FINGERS))
    ros.spin_for(0.1)
    for f in FINGERS:
        got = wrenches[f]
        assert [stamp_ns(m) for m in got] == [s for s, _ in sent[f]]
        assert all(m.header.frame_id == f"prisma_{f}_pad" for m in got)
        expected = reference.estimate(np.stack([v for _, v in sent[f]]))
        np.testing.assert_allclose(wrench_rows(got), expected, atol=1e-5)


def test_nan_input_is_counted_and_does_not_stop_the_node(ros, node_cls, bundles):
    wrenches = ros.collect(WrenchStamped, "/prisma/thumb/wrench")
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    node = ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"]), "fingers": ["thumb", "index"]},
                    sim_time=True)
    bad = np.full(9, 0.5, dtype=np.float32)
    bad[4] = np.nan
    t0 = ros.now_ns()
    send(ros, node, "thumb", taxel_msg("thumb", t0, bad))
    send(ros, node, "index", taxel_msg("index", t0, np.full(9, 0.5)))
    send(ros, node, "thumb", taxel_msg("thumb", t0 + 10_000_000, np.full(9, 0.6)))
    send(ros, node, "index", taxel_msg("index", t0 + 10_000_000, np.full(9, 0.6)))
    ros.advance(1.0, step=0.01)  # diagnostics at the start instant and 1 s later
    assert ros.spin_until(lambda: len(diagnostics) == 2 and wrenches)
    ros.spin_for(0.1)
    assert [stamp_ns(m) for m in wrenches] == [t0 + 10_000_000]
    assert np.isfinite(wrenches[0].wrench.force.z)
    assert stamp_ns(diagnostics[-1]) == t0 + 10**9
    status = {s.name: s for s in diagnostics[-1].status}
    thumb = status["force_estimator: thumb"]
    values = {kv.key: kv.value for kv in thumb.values}
    assert thumb.level == DiagnosticStatus.WARN and "1 sample(s) rejected" in thumb.message
    assert values == {"received": "2", "estimated": "1", "rejected": "1", "model_kind": "cnn2", "bias": "none"}
    assert status["force_estimator: index"].level == DiagnosticStatus.OK
    assert set(status) == {"force_estimator: thumb", "force_estimator: index"}


def test_bias_service_zeroes_the_no_load_wrench_and_refuses_in_contact(ros, node_cls, bundles):
    """`ros2 service call /force_estimator/bias std_srvs/srv/Trigger`: each finger's offset is the
    mean of its last bias_samples estimates, subtracted from every wrench published after it and
    shown in /diagnostics; refused while too few samples or while a pad is pressed."""
    wrenches = ros.collect(WrenchStamped, "/prisma/thumb/wrench")
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.capture_logs()
    node = ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"]), "fingers": ["thumb"],
                                      "bias_samples": 5}, sim_time=True)
    reference = ForceEstimator.from_bundle(bundles["cnn2"])
    rest = np.array(PadParams().rest_volts, dtype=np.float32)  # untouched: mean 0.436 V
    rng = np.random.default_rng(7)
    t0 = ros.now_ns()
    sent = []

    def publish(n, volts):
        for _ in range(n):
            v = (volts + rng.normal(0, 0.002, 9)).astype(np.float32)
            sent.append(v)
            send(ros, node, "thumb", taxel_msg("thumb", t0 + len(sent) * 10_000_000, v))

    publish(3, rest)
    early = ros.call(Trigger, "/force_estimator/bias", Trigger.Request())
    assert (early.success, early.message) == (False, "refused: not enough samples yet: thumb 3/5")
    publish(4, rest)
    response = ros.call(Trigger, "/force_estimator/bias", Trigger.Request())
    offset = reference.estimate(np.stack(sent[-5:])).mean(axis=0)
    assert response.success and response.message == f"biased over 5 samples: thumb Fz {offset[2]:+.4f} N"
    assert ros.wait_for_log(severity="info", name="force_estimator", contains="biased over 5 samples")
    publish(3, rest)
    assert ros.spin_until(lambda: len(wrenches) == 10)
    raw = reference.estimate(np.stack(sent))
    np.testing.assert_allclose(wrench_rows(wrenches[:7]), raw[:7], atol=1e-5)  # before: as estimated
    np.testing.assert_allclose(wrench_rows(wrenches[7:]), raw[7:] - offset, atol=1e-5)  # after: less the offset
    publish(1, rest + np.float32(0.3))  # a press: taxel mean 0.74 V
    refused = ros.call(Trigger, "/force_estimator/bias", Trigger.Request())
    assert not refused.success
    assert refused.message == ("refused: in contact: thumb (taxel mean 0.74 V), at or above 0.55 V; "
                               "take the bias with nothing touching the pads")
    assert ros.wait_for_log(severity="warn", name="force_estimator", contains="bias refused: in contact: thumb")
    ros.advance(1.0, step=0.01)
    assert ros.spin_until(lambda: len(diagnostics) == 2)
    values = {kv.key: kv.value for kv in diagnostics[-1].status[0].values}
    assert values["bias"] == " ".join(f"{v:.4f}" for v in offset)  # the first offset, kept


def test_bias_is_saved_to_the_hand_directory_and_loaded_by_a_restarted_node(ros, node_cls, bundles, tmp_path):
    """With hand_config, ~/bias writes force_bias.yaml there (the message names it); the next start
    subtracts that bias from the first wrench on, and a node with another network does not."""
    hand_dir = tmp_path / "hand"
    params = {"model_bundle": str(bundles["cnn2"]), "fingers": ["thumb"], "bias_samples": 3,
              "hand_config": str(hand_dir)}
    reference = ForceEstimator.from_bundle(bundles["cnn2"])
    rest = np.array(PadParams().rest_volts, dtype=np.float32)
    t0 = ros.now_ns()
    ros.capture_logs()
    node = ros.node(node_cls, params=params)
    assert ros.wait_for_log(severity="info", name="force_estimator",
                            contains=f"hand directory {hand_dir}: nothing saved yet")
    for k in range(3):
        send(ros, node, "thumb", taxel_msg("thumb", t0 + k * 10_000_000, rest))
    response = ros.call(Trigger, "/force_estimator/bias", Trigger.Request())
    offset = reference.estimate(np.stack([rest] * 3)).mean(axis=0)
    saved = hand_dir / "force_bias.yaml"
    assert response.success
    assert response.message == f"biased over 3 samples: thumb Fz {offset[2]:+.4f} N; saved to {saved}"
    entry = yaml.safe_load(saved.read_text())["force_bias"]["thumb"]
    np.testing.assert_allclose(entry["offset"], offset, atol=1e-6)
    assert (entry["bundle"], entry["samples"], entry["note"]) == (str(bundles["cnn2"]), 3, "~/bias")
    ros.destroy_node(node)

    wrenches = ros.collect(WrenchStamped, "/prisma/thumb/wrench")
    restarted = ros.node(node_cls, params=params)
    assert ros.wait_for_log(severity="info", name="force_estimator",
                            contains=f"hand directory {hand_dir}: thumb: saved bias Fz {offset[2]:+.4f} N from ")
    pressed = rest + np.float32(0.5)
    send(ros, restarted, "thumb", taxel_msg("thumb", t0 + 10**9, pressed))
    assert ros.spin_until(lambda: len(wrenches) == 1)
    np.testing.assert_allclose(wrench_rows(wrenches)[0], reference.estimate(pressed[None])[0] - offset, atol=1e-5)
    ros.destroy_node(restarted)

    other = ros.node(node_cls, params={**params, "model_bundle": str(bundles["cnn"])})
    assert ros.wait_for_log(severity="info", name="force_estimator",
                            contains=f"thumb: saved bias not applied: taken with {bundles['cnn2']}, this run uses "
                                     f"{bundles['cnn']}; take ~/bias again")
    assert other.pipeline.bias.offsets == {}


def test_a_damaged_hand_file_fails_at_start_naming_it(ros, node_cls, bundles, tmp_path):
    (tmp_path / "force_bias.yaml").write_text("force_bias: [thumb]\n")
    with pytest.raises(HandConfigError, match=f"{tmp_path / 'force_bias.yaml'}: 'force_bias' must be a mapping"):
        ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"]), "hand_config": str(tmp_path)})


def test_per_finger_bundle_override_and_frame_id_format(ros, node_cls, bundles):
    thumb = ros.collect(WrenchStamped, "/prisma/thumb/wrench")
    index = ros.collect(WrenchStamped, "/prisma/index/wrench")
    ros.capture_logs()
    node = ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"]), "fingers": ["thumb", "index"],
                                      "frame_id_format": "{finger}_tip",
                                      "finger_bundles.thumb": str(bundles["cnn"])})
    assert node.pipeline.estimators["thumb"].model_kind == "cnn"
    assert node.pipeline.estimators["index"].model_kind == "cnn2"
    assert ros.wait_for_log(severity="info", name="force_estimator",
                            contains=f"fingers thumb, index; model cnn ({bundles['cnn']}); cnn2 ({bundles['cnn2']})")
    t0 = ros.now_ns()
    for f in ("thumb", "index"):
        send(ros, node, f, taxel_msg(f, t0, np.full(9, 1.0)))
    assert ros.spin_until(lambda: thumb and index)
    assert thumb[0].header.frame_id == "thumb_tip" and index[0].header.frame_id == "index_tip"
    assert stamp_ns(thumb[0]) == stamp_ns(index[0]) == t0
    assert np.isnan(thumb[0].wrench.torque.x)  # a force-only network estimates no torque
    assert np.isfinite(index[0].wrench.torque.x)


def test_missing_bundle_fails_at_start_with_the_path(ros, node_cls, tmp_path):
    missing = tmp_path / "no_such_bundle"
    with pytest.raises(BundleError) as err:
        ros.node(node_cls, params={"model_bundle": str(missing)})
    assert str(missing) in str(err.value) and "does not exist" in str(err.value)


def broken_bundle(bundles, tmp_path):
    """A copy of the cnn2 bundle whose input normalisation has 12 channels instead of 9."""
    broken = tmp_path / "broken"
    shutil.copytree(bundles["cnn2"], broken)
    meta = json.loads((broken / "metadata.json").read_text())
    meta["normalisation"]["input"] = {"mean": [0.0] * 12, "std": [1.0] * 12}
    (broken / "metadata.json").write_text(json.dumps(meta))
    return broken


def test_mismatched_bundle_fails_at_start_with_the_problem(ros, node_cls, bundles, tmp_path):
    broken = broken_bundle(bundles, tmp_path)
    with pytest.raises(BundleError, match="normalisation.input has 12 channels, expected 9") as err:
        ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"]), "finger_bundles.ring": str(broken)})
    assert str(broken) in str(err.value)


@pytest.mark.parametrize("name,value,message", [
    ("fingers", ["thumb", "pinky"], "'pinky' is not one of"),
    ("torch_threads", 0, "'torch_threads' = 0"),
    ("network_precision", "int8", "'network_precision' = 'int8'"),
    ("batch_window", -0.1, "'batch_window' = -0.1"),
    ("frame_id_format", "{hand}", "'frame_id_format'"),
    ("bias_samples", 0, "'bias_samples' = 0: must be >= 1 and <= 10000"),
    ("bias_contact_voltage", 4.0, "'bias_contact_voltage' = 4.0: must be > 0.0 and < 3.3"),
])
def test_invalid_parameters_fail_at_start(ros, node_cls, bundles, name, value, message):
    with pytest.raises(ParameterError, match=message):
        ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"]), name: value})


def test_every_parameter_is_read_only_after_start(ros, node_cls, bundles):
    ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"])})
    for name, value in (("batch_window", 0.01), ("model_bundle", str(bundles["cnn"])),
                        ("finger_bundles.thumb", str(bundles["cnn"])), ("network_precision", "float32")):
        (refused,) = ros.set_parameters("/force_estimator", **{name: value})
        assert (refused.successful, refused.reason) == (False, f"Trying to set a read-only parameter: {name}.")


def test_behind_the_simulated_tactile_driver_every_scan_gets_wrenches(ros, node_cls, bundles):
    from prisma_tactile_driver.tactile_driver_node import TactileDriverNode
    taxels = {f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS}
    wrenches = {f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS}
    # the estimator first: its subscriptions are matched before the driver's first scan
    node = ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"])}, sim_time=True)
    ros.node(TactileDriverNode, sim_time=True)
    ros.advance(0.49, step=0.01)  # scans at the start instant and every 10 ms: 50
    assert ros.spin_until(lambda: all(len(taxels[f]) == len(wrenches[f]) == 50 for f in FINGERS)), (
        {f: (len(taxels[f]), len(wrenches[f])) for f in FINGERS}, node.pipeline.counts)
    ros.spin_for(0.1)
    for f in FINGERS:
        assert len(taxels[f]) == 50
        # a whole scan is estimated as soon as its fifth finger arrives, so nothing lags behind
        assert [stamp_ns(m) for m in wrenches[f]] == [stamp_ns(m) for m in taxels[f]]


def test_takes_the_per_hand_taxels_once_they_come_each_sample_once(ros, node_cls, bundles):
    wrenches = {f: ros.collect(WrenchStamped, f"/prisma/{f}/wrench") for f in FINGERS}
    hands = ros.collect(HandWrench, "/prisma/hand/wrench")
    node = ros.node(node_cls, params={"model_bundle": str(bundles["cnn2"])})
    reference = ForceEstimator.from_bundle(bundles["cnn2"])
    rng = np.random.default_rng(3)
    t0 = ros.now_ns()
    scans = [(t0 + k * 10_000_000, {f: rng.uniform(0.4, 2.5, 9).astype(np.float32) for f in FINGERS})
             for k in range(4)]
    # scans 0 and 1 per finger (a bag recorded without the per-hand topic plays only these) ...
    for stamp, volts in scans[:2]:
        for f in FINGERS:
            send(ros, node, f, taxel_msg(f, stamp, volts[f]))
    # ... then per hand, from scan 1 on: around the switch both forms carry the same scan
    for k, (stamp, volts) in enumerate(scans[1:]):
        received = sum(c.received for c in node.pipeline.counts.values())
        hand = HandTaxels(header=Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9)),
                          samples=[taxel_msg(f, stamp, volts[f]) for f in FINGERS])
        ros.publish("/prisma/hand/taxels", hand)
        if k == 0:
            assert ros.spin_until(lambda: node._taxels.state.switched)
        else:
            assert ros.spin_until(lambda: sum(c.received for c in node.pipeline.counts.values())
                                  == received + 5)  # noqa: B023 - spin_until runs it now
    assert ros.spin_until(lambda: len(hands) == 4)
    ros.spin_for(0.1)
    stamps = [s for s, _ in scans]
    for f in FINGERS:
        assert [stamp_ns(m) for m in wrenches[f]] == stamps  # scan 1 once, not twice
        expected = reference.estimate(np.stack([volts[f] for _, volts in scans]))
        np.testing.assert_allclose(wrench_rows(wrenches[f]), expected, atol=1e-5)
    assert [stamp_ns(m) for m in hands] == stamps
    for m, (stamp, _) in zip(hands, scans):
        assert list(m.fingers) == list(FINGERS) and [stamp_ns(w) for w in m.wrenches] == [stamp] * 5
    assert hands[-1].wrenches[2] == wrenches["middle"][-1]
    # the per-finger subscriptions are gone: the tactile driver's per-finger topics cost it nothing
    assert ros.spin_until(lambda: all(ros.probe.count_subscribers(f"/prisma/{f}/taxels") == 0 for f in FINGERS))
    assert [c.received for c in node.pipeline.counts.values()] == [4] * 5


# ---- main() as a process ------------------------------------------------------------------------
RUN = ["ros2", "run", "prisma_force_estimator", "force_estimator"]


def test_main_logs_the_bundle_problem_and_exits_1(tmp_path):
    gone = tmp_path / "gone"
    result = run_process([*RUN, "--ros-args", "-p", f"model_bundle:={gone}"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and f"[force_estimator]: model bundle {gone}: directory does not exist" \
        in result.output
    assert "Traceback" not in result.output


def test_main_logs_the_mismatch_and_exits_1(bundles, tmp_path):
    broken = broken_bundle(bundles, tmp_path)
    result = run_process([*RUN, "--ros-args", "-p", f"model_bundle:={broken}"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and "normalisation.input has 12 channels, expected 9" in result.output
    assert "Traceback" not in result.output


def test_main_logs_a_damaged_hand_file_and_exits_1(bundles, tmp_path):
    (tmp_path / "force_bias.yaml").write_text("force_bias:\n  thumb: {offset: [0, 0, 0], bundle: b, samples: 5}\n")
    result = run_process([*RUN, "--ros-args", "-p", f"model_bundle:={bundles['cnn2']}",
                          "-p", f"hand_config:={tmp_path}"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and f"{tmp_path / 'force_bias.yaml'}: force_bias thumb offset = [0, 0, 0] " \
        "is not 6 numbers" in result.output
    assert "Traceback" not in result.output


def test_main_logs_an_invalid_parameter_and_exits_1(bundles):
    result = run_process([*RUN, "--ros-args", "-p", f"model_bundle:={bundles['cnn2']}", "-p", "torch_threads:=0"])
    assert result.returncode == 1, result.output
    assert "[FATAL]" in result.output and "[force_estimator]: invalid parameter 'torch_threads' = 0" in result.output
    assert "Traceback" not in result.output


def test_main_exits_0_on_sigint_without_a_traceback(ros, bundles):
    result = start_and_interrupt([*RUN, "--ros-args", "-p", f"model_bundle:={bundles['cnn2']}"],
                                 "[force_estimator]: fingers thumb, index, middle, ring, little", ros,
                                 "/force_estimator")
    assert result.returncode == 0, result.output
    assert "Traceback" not in result.output


def test_main_exits_0_when_its_context_is_shut_down_from_outside(bundles):
    result = run_process(external_shutdown_command("prisma_force_estimator.force_estimator_node",
                                                   "--ros-args", "-p", f"model_bundle:={bundles['cnn2']}"))
    assert result.returncode == 0, result.output
    assert "[force_estimator]: fingers" in result.output and "Traceback" not in result.output
