"""glove_driver node on real rclpy over DDS: frames and 32FC1 images, the empty-hand service,
diagnostics, the sim, serial and replay backends, parameters, and main() as a process (a bad
parameter exits 1, SIGINT exits 0).

The sim and replay backends are paced by the node's clock: under sim time (a /clock the test
publishes) their frames carry exact stamps, one every round(1e9 / rate) ns from the first poll.
"""
import os

import numpy as np
import pytest

from prisma_testing.node_process import external_shutdown_command, run_process, start_and_interrupt
from prisma_testing.repo_paths import CONFIG, node_parameters
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from prisma_msgs.msg import GloveFrame  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from prisma_common.parameters import ParameterError
from stag_glove.dataset import save_hdf5  # noqa: E402
from stag_glove.node_config import GloveDriverConfig  # noqa: E402
from stag_glove.processing import normalise  # noqa: E402
from stag_glove.protocol import encode_frame  # noqa: E402
from stag_glove.synthetic import SyntheticConfig, SyntheticGlove  # noqa: E402

DRIVER_YAML = CONFIG / "glove_driver.yaml"
SIM_PERIOD_NS = round(1e9 / 7.3)  # 136_986_301: the simulated glove's frame period
POLL_STEP = 0.02  # advance in the driver's poll period (50 Hz)


def test_config_yaml_matches_declared_defaults():
    assert node_parameters(DRIVER_YAML, "glove_driver") == GloveDriverConfig().as_parameters()


def test_pressure_map_is_drawn_only_for_a_viewer(ros, driver_cls):
    """/stag/pressure_map: the frame's pressures on the layout (rgb8), published while subscribed."""
    from stag_glove.layout import load_layout
    from stag_glove.pressure_map import PressureMap

    frames = ros.collect(GloveFrame, "/stag/frame")
    node = ros.node(driver_cls, params_files=[DRIVER_YAML], params={"sim_short_probability": 0.0}, sim_time=True)
    ros.advance(0.5, step=POLL_STEP)
    assert node._map_pub.get_subscription_count() == 0 and frames  # nobody watches: nothing drawn
    maps = ros.collect(Image, "/stag/pressure_map")
    assert ros.spin_until(lambda: node._map_pub.get_subscription_count() == 1)
    ros.advance(1.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(maps) >= 5)
    image = maps[-1]
    frame = next(f for f in frames if stamp_ns(f) == stamp_ns(image))
    layout = load_layout(CONFIG / "glove" / "layout.yaml")
    expected = PressureMap(layout.mask, layout.region_index).draw(np.asarray(frame.pressure).reshape(32, 32))
    assert (image.encoding, image.height, image.width, image.step, image.header.frame_id) == (
        "rgb8", 384, 384, 1152, "stag_glove")
    np.testing.assert_array_equal(np.asarray(image.data, np.uint8).reshape(384, 384, 3), expected)


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


def test_the_synthetic_glove_says_its_weight_has_no_load_to_read(ros, driver_cls):
    """The sim backend's objects are held, never lifted: its log and /diagnostics say that /stag/weight
    then reads no load (a user would otherwise take ~24 g for a measurement)."""
    ros.capture_logs()
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.node(driver_cls, params_files=[DRIVER_YAML], sim_time=True)
    said = "synthetic glove: objects are held, never lifted, so /stag/weight has no load to read"
    assert ros.wait_for_log(severity="info", name="glove_driver", contains=said)
    ros.advance(0.1, step=POLL_STEP)
    assert ros.spin_until(lambda: diagnostics)
    assert said in diagnostics[-1].status[0].message


def test_shorted_frames_are_published_flagged(ros, driver_cls):
    frames = ros.collect(GloveFrame, "/stag/frame")
    ros.node(driver_cls, params={"sim_short_probability": 0.3, "sim_seed": 4}, sim_time=True)
    ros.advance(4.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(frames) == 30)  # frames at k / 7.3 s for k = 0..29
    shorted = [m for m in frames if m.shorted]
    assert shorted and all((np.asarray(m.raw) > 950).any() and not m.contact for m in shorted)
    assert all(not (np.asarray(m.raw) > 950).any() for m in frames if not m.shorted)


def test_processing_thresholds_change_at_run_time_from_the_next_frame(ros, driver_cls):
    frames = ros.collect(GloveFrame, "/stag/frame")
    node = ros.node(driver_cls, params={"sim_short_probability": 0.3, "sim_seed": 4}, sim_time=True)
    ros.advance(4.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(frames) == 30)
    assert any(m.shorted for m in frames) and any(m.contact for m in frames)
    # no reading exceeds 1023 and no pressure 0..1 exceeds the empty-hand maximum + 1: neither flag again
    results = ros.set_parameters("/glove_driver", short_threshold=1023, contact_margin=1.0, stale_timeout=5.0)
    assert [r.successful for r in results] == [True, True, True]
    assert node.driver.stale_timeout_ns == 5 * 10**9
    ros.advance(4.0, step=POLL_STEP)
    assert ros.spin_until(lambda: len(frames) == 59)
    later = frames[30:]
    assert any((np.asarray(m.raw) > 950).any() for m in later)  # electrodes still short ...
    assert not any(m.shorted or m.contact for m in later)  # ... and are no longer flagged
    (refused,) = ros.set_parameters("/glove_driver", normalisation_low=400.0)
    assert (refused.successful, refused.reason) == (False, "Trying to set a read-only parameter: normalisation_low.")
    (out,) = ros.set_parameters("/glove_driver", short_threshold=2000)
    assert not out.successful and out.reason.startswith("Parameter short_threshold out of range")


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


# ---- main() as a process ------------------------------------------------------------------------
DRIVER_RUN = ["ros2", "run", "stag_glove", "glove_driver"]


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


def test_driver_main_exits_0_on_sigint_without_a_traceback(ros):
    result = start_and_interrupt(DRIVER_RUN, "[glove_driver]: sim backend (sim/seed0), polling at 50 Hz",
                                 ros, "/glove_driver")
    assert result.returncode == 0, result.output
    assert "Traceback" not in result.output


def test_main_exits_0_when_its_context_is_shut_down_from_outside():
    result = run_process(external_shutdown_command("stag_glove.glove_driver_node"))
    assert result.returncode == 0, result.output
    assert "[glove_driver]: " in result.output and "Traceback" not in result.output
