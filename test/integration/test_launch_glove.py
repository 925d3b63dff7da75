"""launch_testing: `glove.launch.py` (backend sim) over DDS, as `ros2 launch` starts it.

- /stag/frame and /stag/image at 7.3 Hz: stamps 1/7.3 s apart (to 0.2 ms), image and frame of one
  reading with one stamp, and as many arriving per second of wall time (6.5-8.0 Hz over a 4 s
  window: the driver keeps up), the newest stamp close to now;
- glove_perception publishes /stag/hand_pose, /stag/weight and /stag/object, each stamped with the
  frame it was computed from; the object estimate is one of its labels with probabilities summing to 1;
- /diagnostics carries the driver's readout status, OK;
- every node exits 0 on SIGINT, no traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import math
import time
import unittest

from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, launch_test
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

import launch_testing  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from prisma_msgs.msg import GloveFrame, ObjectEstimate, WeightEstimate  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402

FRAME_RATE_HZ = 7.3  # config/glove_driver.yaml frame_rate_hz
ARRIVAL_HZ = (6.5, 8.0)
WINDOW_S = 4.0


generate_test_description = launch_test("glove.launch.py")


class TestGloveSim(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.frames = ros.collect(GloveFrame, "/stag/frame")
        cls.images = ros.collect(Image, "/stag/image")
        cls.objects = ros.collect(ObjectEstimate, "/stag/object")
        cls.poses = ros.collect(ObjectEstimate, "/stag/hand_pose")
        cls.weights = ros.collect(WeightEstimate, "/stag/weight")
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        if not ros.spin_until(lambda: cls.frames and cls.poses, 60.0):
            raise AssertionError("no /stag/frame or /stag/hand_pose within 60 s")
        before = len(cls.frames)
        start = time.monotonic()
        ros.spin_for(WINDOW_S)
        cls.arrival_hz = (len(cls.frames) - before) / (time.monotonic() - start)
        cls.lag_s = time.time() - stamp_ns(cls.frames[-1]) * 1e-9
        ros.spin_until(lambda: cls.objects and cls.weights, 30.0)

    def test_frames_and_images_at_7_3_hz(self):
        print(f"/stag/frame: {self.arrival_hz:.2f} frames per wall second, newest stamp {self.lag_s * 1e3:.0f} ms old")
        self.assertTrue(ARRIVAL_HZ[0] <= self.arrival_hz <= ARRIVAL_HZ[1], f"{self.arrival_hz:.2f} Hz")
        self.assertLess(self.lag_s, 0.5)
        # stamps one frame period apart (a sample lost on a starved machine leaves a gap of two)
        stamps = [stamp_ns(m) for m in self.frames]
        periods = [(b - a) * 1e-9 * FRAME_RATE_HZ for a, b in zip(stamps, stamps[1:])]
        self.assertEqual([p for p in periods if abs(p - round(p)) > 1e-3 or round(p) < 1], [])
        self.assertGreaterEqual(sum(round(p) == 1 for p in periods), 0.9 * len(periods))
        image_stamps = [stamp_ns(m) for m in self.images]
        common = sorted(set(stamps) & set(image_stamps))
        self.assertGreater(len(common), 20)  # the two streams started at slightly different frames
        self.assertEqual(image_stamps[image_stamps.index(common[0]):image_stamps.index(common[-1]) + 1], common)
        self.assertEqual(stamps[stamps.index(common[0]):stamps.index(common[-1]) + 1], common)
        image = self.images[-1]
        frame = self.frames[-1]
        self.assertEqual((image.encoding, image.height, image.width), ("32FC1", frame.rows, frame.cols))

    def test_perception_publishes_object_hand_pose_and_weight(self):
        frame_stamps = {stamp_ns(m) for m in self.frames}
        for name, msgs in (("/stag/object", self.objects), ("/stag/hand_pose", self.poses),
                           ("/stag/weight", self.weights)):
            self.assertTrue(msgs, f"nothing on {name}")
            self.assertLessEqual({stamp_ns(m) for m in msgs}, frame_stamps, name)
        for estimate in self.objects + self.poses:
            self.assertIn(estimate.label, list(estimate.labels))
            self.assertAlmostEqual(math.fsum(estimate.probabilities), 1.0, places=4)
        self.assertTrue(all(math.isfinite(w.grams) and math.isfinite(w.baseline_grams) for w in self.weights))

    def test_driver_diagnostics(self):
        levels = {s.name: s.level for m in self.diagnostics for s in m.status}
        self.assertEqual(levels, {"glove_driver: readout": DiagnosticStatus.OK})


@launch_testing.post_shutdown_test()
class TestGloveShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
        self.assertEqual(len(proc_info.process_names()), 2)
