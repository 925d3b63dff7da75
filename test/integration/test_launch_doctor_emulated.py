"""launch_testing: prisma-doctor on `hand.launch.py hardware:=emulated`, one launch, faults one after another.

1. the emulated hand (home:=true: homed at start) passes every line and prisma-doctor exits 0;
2. a second node named /manipulation: exactly `node manipulation` fails;
3. each fault, injected with prisma-hand-fault, fails exactly its own line (the others OK, WARN or SKIP)
   and the hand is brought back before the next: the hub unplugged (`hub`), a servo off the bus (`servo
   thumb_flexion`: the driver's reconnect ping names it), a hardware error bit (`servo fingers`), that
   servo power-cycled (`servo fingers`: not homed, then homed again through HomeMotors), a servo's baud
   changed (`servo thumb_rotation`), the servos' port not writable (`port servos`, not as root: root
   writes any port; the check's own test covers it with plain data).

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
import unittest
from pathlib import Path

import pytest

from prisma_testing.emulated_launch import diagnostic_values, hand_fault, wait_until_homed
from prisma_testing.launch_case import GraphTestCase, emulated_hand_launch
from prisma_testing.node_process import NodeProcess, console_script, run_process
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.action import HomeMotors  # noqa: E402
from prisma_msgs.msg import TaxelArray  # noqa: E402

from prisma_common.hand import FINGERS, MOTOR_NAMES  # noqa: E402

EMULATOR_DIR = Path(tempfile.gettempdir()) / f"prisma_doctor_hand_{os.getpid()}"
DUPLICATE = ("import rclpy, sys; rclpy.init(); node = rclpy.create_node('manipulation'); "
             "print('spinning', flush=True); rclpy.spin(node)")


@pytest.mark.launch_test
def generate_test_description():
    return emulated_hand_launch(EMULATOR_DIR)


def fault(*args: str) -> str:
    return hand_fault(EMULATOR_DIR, *args)


class TestDoctorEmulated(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        cls.taxels = ros.collect(TaxelArray, "/prisma/thumb/taxels")
        cls.home_client = ros.action_client(HomeMotors, "/prisma/motors/home", wait_sec=60.0)

    # ---- helpers ------------------------------------------------------------------------------
    def bus_message(self) -> str | None:
        for msg in reversed(self.diagnostics):
            for status in msg.status:
                if status.name == "motor_driver: bus":
                    return status.message
        return None

    def wait_for_bus(self, contains: str = "", timeout_sec: float = 20.0) -> None:
        """Until motor_driver's bus status says `contains` ("": until it is connected)."""
        def said() -> bool:
            message = self.bus_message() or "disconnected"
            return contains in message if contains else not message.startswith("disconnected")

        self.assertTrue(self.ros.spin_until(said, timeout_sec),
                        f"motor_driver: bus never said {contains or 'connected'!r}; last: {self.bus_message()!r}")

    def home(self) -> None:
        """Home every motor through HomeMotors, where the driver serves it."""
        client = type(self).home_client
        if client is None or not client.wait_for_server(timeout_sec=5.0):
            print("no /prisma/motors/home server: 'not homed' failures are left out of the comparisons")
            return
        from prisma_msgs.action import HomeMotors

        handle = self.ros.send_goal(client, HomeMotors.Goal(motors=[]), timeout_sec=10.0)
        result = self.ros.result(handle, timeout_sec=60.0)
        self.assertTrue(result.result.success, f"homing failed: {result.result.reason}")
        type(self).homed = True

    def doctor(self, *args: str) -> tuple[int, dict[str, tuple[str, str]], str]:
        """prisma-doctor's exit status, its lines by check name (status, text) and its whole output."""
        start = time.monotonic()
        result = run_process([console_script("prisma-doctor"), *args], timeout_sec=60.0)
        print(f"prisma-doctor {' '.join(args)}: exit {result.returncode} in {time.monotonic() - start:.1f} s\n"
              f"{result.output}")
        lines = {}
        for line in result.output.splitlines():
            status, _, rest = line.partition(" ")
            if status in ("OK", "WARN", "FAIL", "SKIP"):
                name, _, text = rest.partition(": ")
                lines[name] = (status, text)
        return result.returncode, lines, result.output

    def assert_fails_exactly(self, expected: set[str], contains: str = "") -> dict[str, tuple[str, str]]:
        code, lines, output = self.doctor()
        self.assertGreaterEqual(len(lines), 20, output)
        fails = {name for name, (status, _) in lines.items() if status == "FAIL"}
        self.assertEqual(fails, expected, output)
        self.assertEqual(code, 1 if expected else 0, output)
        for name in expected:
            self.assertIn(" -> ", lines[name][1], f"{name}: no fix\n{output}")
            self.assertIn(contains, lines[name][1], output)
        return lines

    def wait_for_taxels(self, timeout_sec: float = 15.0) -> None:
        since = len(self.taxels)
        self.assertTrue(self.ros.spin_until(lambda: len(self.taxels) > since + 50, timeout_sec),
                        "/prisma/thumb/taxels did not stream")

    # ---- the tests, in order, on one launch -----------------------------------------------------
    def test_1_the_emulated_hand_passes(self):
        self.assertTrue(self.ros.spin_until(lambda: self.bus_message() is not None, 60.0),
                        "no motor_driver /diagnostics")
        self.wait_for_taxels(30.0)
        wait_until_homed(self.ros, self.diagnostics, MOTOR_NAMES, timeout_sec=90.0)
        # the estimator reports once its bundles loaded (torch: tens of seconds on a busy machine); the
        # doctor rightly says "not answering" before
        self.assertTrue(self.ros.spin_until(
            lambda: all(diagnostic_values(self.diagnostics, f"force_estimator: {f}") for f in FINGERS), 120.0),
            "force_estimator never reported on /diagnostics")
        lines = self.assert_fails_exactly(set())
        self.assertEqual(lines["port servos"], ("OK", f"{EMULATOR_DIR / 'servos'} present and writable"))
        self.assertTrue(lines["hub"][1].startswith(f"serial {EMULATOR_DIR / 'hub'}, "), lines["hub"])
        self.assertNotIn("SKIP", {status for status, _ in lines.values()})

    def test_2_a_duplicate_node_is_flagged(self):
        with NodeProcess([sys.executable, "-c", DUPLICATE]) as duplicate:
            self.assertTrue(duplicate.wait_for_output("spinning", 60.0), duplicate.output)
            lines = self.assert_fails_exactly({"node manipulation"})
            self.assertTrue(lines["node manipulation"][1].startswith("2 nodes named /manipulation"))
            duplicate.interrupt()

    def test_3_hub_unplugged(self):
        fault("hub-unplug")
        try:
            self.ros.spin_for(1.5)  # the driver's next /diagnostics says the link is lost
            self.assert_fails_exactly({"hub"}, "plug the hub's USB cable in")
        finally:
            fault("hub-replug")
        self.wait_for_taxels()

    def test_4_a_servo_off_the_bus(self):
        fault("servo-silent", "--motor", "thumb_flexion")
        try:
            self.wait_for_bus("ping thumb_flexion (id 2)")
            lines = self.assert_fails_exactly({"servo thumb_flexion"}, "set its ID to 2 and its baud to 1000000")
            self.assertEqual(lines["motor bus"][0], "SKIP")
        finally:
            fault("servo-clear", "--motor", "thumb_flexion")
        self.wait_for_bus()  # reopened: its LED (homed since power-up) and its zero still hold
        wait_until_homed(self.ros, self.diagnostics, MOTOR_NAMES)

    def test_5_a_hardware_error_then_unhomed(self):
        fault("servo-error", "--motor", "fingers", "--bit", "overload")
        try:
            self.ros.spin_for(1.5)
            lines = self.assert_fails_exactly({"servo fingers"}, "power-cycle the servo")
            self.assertTrue(lines["servo fingers"][1].startswith("hardware error bit 5 overload"))
        finally:
            fault("servo-clear", "--motor", "fingers")
        fault("power-cycle", "--motor", "fingers")  # the servo's RAM (its homed marker) is reset
        self.ros.spin_for(1.5)
        lines = self.assert_fails_exactly({"servo fingers"}, "HomeMotors")
        self.assertTrue(lines["servo fingers"][1].startswith("not homed"))
        self.home()

    def test_6_wrong_baud(self):
        fault("servo-baud", "--motor", "thumb_rotation", "--rate", "57600")
        try:
            self.wait_for_bus("ping thumb_rotation (id 3)")
            self.assert_fails_exactly({"servo thumb_rotation"}, "its baud to 1000000")
        finally:
            fault("servo-baud", "--motor", "thumb_rotation", "--rate", "1000000")
        self.wait_for_bus()

    def test_7_port_without_write_permission(self):
        if os.geteuid() == 0:
            self.skipTest("running as root, who writes every port whatever its mode")
        device = Path(os.path.realpath(EMULATOR_DIR / "servos"))
        mode = device.stat().st_mode & 0o777
        device.chmod(0o444)
        try:
            self.assert_fails_exactly({"port servos"})
        finally:
            device.chmod(mode)


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_devices_removed(self):
        leftovers = sorted(p.name for p in EMULATOR_DIR.iterdir())
        self.assertEqual(leftovers, [], "the emulator left devices behind")
        EMULATOR_DIR.rmdir()
