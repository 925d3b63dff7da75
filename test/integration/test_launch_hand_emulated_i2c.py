"""launch_testing: `hand.launch.py hardware:=emulated tactile_backend:=i2c`, the tactile driver on the
emulated TCA9548A + MAX11617 bus.

tactile_driver's I2C backend runs its smbus2 transactions (mux channel select, ADC setup and
configuration, 18-byte scan read) against prisma-hand-emulator's bus over its socket, the same pads
that drive the hub's serial frames; motor_driver is on the servo emulator as in the serial test.

1. a pinch Grasp SUCCEEDED force_reached with the taxels read over I2C;
2. the index pad's ADC stops acknowledging: its taxels stop while the other fingers' go on (the
   samples the driver counts on /diagnostics), and /diagnostics names the finger's mux channel and
   the NACK; cleared, the index taxels come back;
3. glitched reads (all-zero bytes, a high nibble other than 1111) are rejected and counted as bad
   reads, one per glitch;
4. the emulator serves the bus and no hub: a hub fault is refused in one line naming the link, and
   nothing changes.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os
import tempfile
import unittest
from pathlib import Path

import pytest

from prisma_testing.emulated_launch import diagnostic_values, hand_fault, run_hand_fault, wait_until_homed
from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, emulated_hand_launch
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.action import Grasp  # noqa: E402

from prisma_common.hand import MOTOR_NAMES  # noqa: E402

# the same path in both imports of this module (launch_testing imports it twice)
EMULATOR_DIR = Path(tempfile.gettempdir()) / f"prisma_emulated_i2c_{os.getpid()}"
HUB = "tactile_driver: hub"


@pytest.mark.launch_test
def generate_test_description():
    return emulated_hand_launch(EMULATOR_DIR, tactile_backend="i2c")


class TestHandEmulatedI2C(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        cls.grasp = ros.action_client(Grasp, "/prisma/grasp", wait_sec=None)

    def fresh_hub_diagnostic(self) -> dict[str, str]:
        """The hub's values from a /diagnostics message published from now on."""
        since = self.ros.now_ns()
        self.assertTrue(self.ros.spin_until(lambda: diagnostic_values(self.diagnostics, HUB, since), 5.0))
        return diagnostic_values(self.diagnostics, HUB, since)

    def samples(self, finger: str, since_ns: int) -> int:
        """How many samples of `finger` the tactile driver has published, by its /diagnostics from
        `since_ns` on (waited for). The driver's own count, not what reached this process: in four
        of seven runs this process stopped receiving /prisma/thumb/taxels at a fault CLI's call
        while the driver went on reading the thumb at 100 Hz and its /diagnostics kept arriving."""
        name = f"tactile_driver: {finger}"
        self.assertTrue(self.ros.spin_until(lambda: diagnostic_values(self.diagnostics, name, since_ns), 5.0),
                        f"no /diagnostics for {finger}")
        return int(diagnostic_values(self.diagnostics, name, since_ns)["samples"])

    def test_1_pinch_grasp_over_i2c(self):
        # home:=true: the servos came up with their turn count lost; goals wait for the homing at start
        wait_until_homed(self.ros, self.diagnostics, MOTOR_NAMES)
        ros = self.ros
        self.assertTrue(ros.spin_until(self.grasp.server_is_ready, 60.0), "no /prisma/grasp server")
        handle = ros.send_until_started(self.grasp, Grasp.Goal(grasp="pinch"), timeout_sec=60.0)
        result = ros.result(handle, timeout_sec=30.0)
        self.assertEqual((result.status, result.result.reason), (GoalStatus.STATUS_SUCCEEDED, "force_reached"))
        self.assertEqual(self.fresh_hub_diagnostic()["bus"], str(EMULATOR_DIR / "i2c.sock"))
        status = json_status()
        self.assertGreater(status["i2c"]["transfers"], 1000)

    def test_2_index_adc_not_acknowledging(self):
        ros = self.ros
        hand_fault(EMULATOR_DIR, "i2c-nack", "--finger", "index")
        self.addCleanup(hand_fault, EMULATOR_DIR, "i2c-clear")  # the tests after this one need the ADC back
        failed_from = ros.now_ns()
        thumb, index = self.samples("thumb", failed_from), self.samples("index", failed_from)
        ros.spin_for(1.0)
        later = ros.now_ns()
        self.assertGreater(self.samples("thumb", later) - thumb, 50, "the other fingers stopped too")
        self.assertEqual(self.samples("index", later), index, "index taxels went on while its ADC did not answer")
        hub = self.fresh_hub_diagnostic()
        self.assertIn("mux channel 1", hub["index_last_error"])
        self.assertIn("no ACK from 0x35", hub["index_last_error"])
        self.assertGreater(int(hub["index_failed_scans"]), 50)

        hand_fault(EMULATOR_DIR, "i2c-clear")
        index = self.samples("index", ros.now_ns())
        ros.spin_for(1.0)
        self.assertGreater(self.samples("index", ros.now_ns()) - index, 50,
                           "no index taxels after the ADC answered again")

    def test_3_glitched_reads_counted_as_bad_reads(self):
        before = int(self.fresh_hub_diagnostic()["index_bad_reads"])
        hand_fault(EMULATOR_DIR, "i2c-glitch", "--finger", "index", "--count", "3")
        self.ros.spin_for(0.5)
        after = int(self.fresh_hub_diagnostic()["index_bad_reads"])
        self.assertEqual(after - before, 3)


    def test_4_hub_faults_refused_on_the_i2c_link(self):
        before = json_status()
        self.assertEqual(before["tactile_link"], "i2c")
        self.assertNotIn("hub", before)
        self.assertFalse((EMULATOR_DIR / "hub").exists())
        done = run_hand_fault(EMULATOR_DIR, "hub-unplug", "--seconds", "1")
        lines = done.stderr.strip().splitlines()
        self.assertEqual((done.returncode, len(lines)), (2, 1), done.stderr)
        self.assertTrue(lines[0].startswith("prisma-hand-fault: error: hub-unplug: "), lines[0])
        self.assertIn("tactile link i2c", lines[0])
        self.assertIn("tactile_backend:=serial", lines[0])
        thumb = self.samples("thumb", self.ros.now_ns())
        self.ros.spin_for(1.0)
        self.assertGreater(self.samples("thumb", self.ros.now_ns()) - thumb, 50, "the thumb's taxels stopped")


def json_status() -> dict:
    import json

    return json.loads(hand_fault(EMULATOR_DIR, "status"))


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_clean_exit(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
        self.assertEqual(sorted(p.name for p in EMULATOR_DIR.iterdir()), [], "the emulator left devices behind")
        EMULATOR_DIR.rmdir()
