"""launch_testing: `hand.launch.py hardware:=emulated`, the drivers' hardware paths on emulated hardware.

prisma-hand-emulator holds the servos and the fingertip hub behind pseudo-terminals, driven by one
hand/world model; motor_driver talks Dynamixel Protocol 2.0 to it through dynamixel-sdk and
tactile_driver reads the hub's frames through pyserial. The tests run in order, on one launch:

1. the drivers are on the emulator's devices (their /diagnostics name the ports) and bytes flow both
   ways; a pinch Grasp SUCCEEDED force_reached, then a horizontal Manipulate SUCCEEDED edge_lost;
2. CRC-corrupted frames and garbage bytes on the hub link are counted in /diagnostics, and no intact
   frame is lost (the dropped-frame count is exactly the corrupted frames);
3. the hub unplugged for 1 s during a horizontal Manipulate: the goal ends ABORTED sensor_stale
   naming the thumb's taxels and the motors stop, while the servos answer every transaction of the
   motor driver (no failed transaction in /diagnostics, any status read late read again by a retry;
   /joint_states goes on);
   the hub comes back, the driver reconnects, and the next horizontal goal succeeds;
4. a servo overload mid-grasp: the goal ends ABORTED naming the motor and the bit, and that motor's
   torque is off in the servo; once cleared, the next Grasp succeeds;
5. a servo off the bus mid-grasp: the goal is aborted (sensor_stale or motor_fault, whichever safety
   net fires first), the other servos stop, and once it answers again the next Grasp succeeds;
6. the paper's scenarios, each from its own world (the emulator's `world` command poses the hand as
   prisma-sim's scenario starts; the holds' pushes come through the `push` command once the goal
   runs, at the scenario's time from the goal's start): pinch and lateral grasps, horizontal,
   vertical, disturbance and combined manipulation, each ending for the paper's reason;
7. the ball a pinch held, let go by its stand, falls once GripperCommand opens the hand;
   /tactile_driver/replace_object (the emulator's world through its control socket) puts it back,
   refused while the pads touch it, and the next pinch Grasp SUCCEEDED force_reached again.
Faults go in through the emulator's control socket from this process, with `prisma-hand-fault`'s own
parser and request (`hand_fault`).

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import json
import os
import tempfile
import time
import unittest
from pathlib import Path

import pytest

from prisma_testing.emulated_launch import diagnostic_values, hand_fault, wait_until_homed
from prisma_testing.goals import goal_outcome, gripper_goal
from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, emulated_hand_launch
from prisma_testing.ros_harness import require_ros, stamp_ns, stopped

require_ros()

import launch_testing  # noqa: E402
from control_msgs.action import GripperCommand  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.action import Grasp, Manipulate  # noqa: E402
from prisma_msgs.msg import TaxelArray  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from prisma_common.hand import MOTOR_NAMES  # noqa: E402
from prisma_hand_sim.scenario_worlds import scenario_world  # noqa: E402
from prisma_sim.hand_session import HAND_SCENARIOS  # noqa: E402
from prisma_sim.sim_runner import EXPECTED_REASONS  # noqa: E402

# the same path in both imports of this module (launch_testing imports it twice)
EMULATOR_DIR = Path(tempfile.gettempdir()) / f"prisma_emulated_hand_{os.getpid()}"
# its own time limit well beyond the grasp's 10 s default: on a loaded machine the fault CLI takes
# seconds to start, and the fault must come while the grasp still runs
SLOW_PINCH = Grasp.Goal(grasp="pinch", finger_force=3.0, thumb_force=3.0, speed_rpm=10.0, timeout=60.0)
# the thumb rotates at 0.46 rpm (2 velocity units): edge_lost after ~10 s, time for a fault mid-goal
# on a loaded machine (the fault CLI took 1.6 s to unplug the hub on a quiet one)
SLOW_HORIZONTAL = Manipulate.Goal(motion="horizontal", speed_rpm=0.5)
# the motor driver's bus counters that a servo not answering moves
BUS_MISSES = ("dropped_status", "corrupt_status", "retries", "comm_failures")


@pytest.mark.launch_test
def generate_test_description():
    return emulated_hand_launch(EMULATOR_DIR)


def fault(*args: str) -> str:
    return hand_fault(EMULATOR_DIR, *args)


def emulator_status() -> dict:
    return json.loads(fault("status"))


class TestHandEmulated(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.taxels = ros.collect(TaxelArray, "/prisma/thumb/taxels")
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        cls.grasp = ros.action_client(Grasp, "/prisma/grasp", wait_sec=None)
        cls.manipulate = ros.action_client(Manipulate, "/prisma/manipulate", wait_sec=None)
        cls.gripper = ros.action_client(GripperCommand, "/prisma/gripper_cmd", wait_sec=None)

    def diagnostic(self, name_end: str, since_ns: int = 0) -> dict[str, str] | None:
        return diagnostic_values(self.diagnostics, name_end, since_ns)

    def start_goal(self, goal, ready_within_s: float = 30.0):
        """The goal's handle once it runs (Grasp or Manipulate, by its type), sent again while it is
        refused not_ready for up to `ready_within_s`."""
        client = self.grasp if isinstance(goal, Grasp.Goal) else self.manipulate
        return self.ros.send_until_started(client, goal, timeout_sec=ready_within_s)

    def run_goal(self, goal, timeout_sec: float = 40.0, ready_within_s: float = 30.0):
        return self.ros.result(self.start_goal(goal, ready_within_s), timeout_sec=timeout_sec)

    def start_slow_grasp(self):
        """A grasp that closes at 10 rpm toward 3 N: still running when the fault comes."""
        ros = self.ros
        fault("world", "pinch_grasp")
        handle = ros.send_until_started(self.grasp, SLOW_PINCH, timeout_sec=30.0)
        result = handle.get_result_async()
        accepted = len(self.joints)

        def closing() -> bool:
            recent = self.joints[accepted:][-5:]
            return len(recent) == 5 and all(0.9 < m.velocity[list(m.name).index("fingers")] < 1.2 for m in recent)

        ros.spin_until(lambda: result.done() or closing(), 15.0)
        self.assertFalse(result.done(), f"the grasp ended before the fault: {result.result()}")
        return result

    def test_1_drivers_on_the_emulated_devices(self):
        ros = self.ros
        # home:=true: the servos came up with their turn count lost; goals wait for the homing at start
        wait_until_homed(ros, self.diagnostics, MOTOR_NAMES)
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("tactile_driver: hub") is not None
                                       and self.diagnostic("motor_driver: bus") is not None, 60.0),
                        "no /diagnostics from both drivers")
        hub, bus = self.diagnostic("tactile_driver: hub"), self.diagnostic("motor_driver: bus")
        self.assertEqual(hub["port"], str(EMULATOR_DIR / "hub"))
        self.assertEqual(bus["port"], str(EMULATOR_DIR / "servos"))
        before = emulator_status()
        self.assertEqual(before["world"], "pinch_ball")  # hand.launch.py's sim_object default
        self.assertTrue(ros.spin_until(lambda: self.grasp.server_is_ready() and self.manipulate.server_is_ready(),
                                       60.0), "no /prisma/grasp and /prisma/manipulate servers")

        # the first goal waits for the graph to come up: beside the load harness the force estimator
        # (torch and its model, loaded at nice -5 before it goes real-time) took 26-54 s after the others
        result = self.run_goal(Grasp.Goal(grasp="pinch"), ready_within_s=120.0)
        self.assertEqual(goal_outcome(result), ("SUCCEEDED", "force_reached"))
        result = self.run_goal(Manipulate.Goal(motion="horizontal"))
        self.assertEqual(goal_outcome(result), ("SUCCEEDED", "edge_lost"))

        after = emulator_status()
        self.assertGreater(after["hub"]["frames_sent"], before["hub"]["frames_sent"])
        self.assertEqual(after["hub"]["frames_unread"], before["hub"]["frames_unread"],
                         "the tactile driver fell behind the hub during the goals")
        self.assertGreater(after["forces_n"]["thumb"], 0.5, "the ball is not held after the pinch")
        hub = self.diagnostic("tactile_driver: hub")
        self.assertGreater(int(hub["frames"]), 100)

    def test_2_crc_errors_and_garbage_counted_no_intact_frame_lost(self):
        ros = self.ros
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("tactile_driver: hub") is not None, 30.0))
        start_ns = ros.now_ns()
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("tactile_driver: hub", start_ns) is not None, 5.0))
        before = self.diagnostic("tactile_driver: hub")
        sent_before = emulator_status()["hub"]
        fault("hub-crc", "--frames", "5")
        fault("hub-garbage", "--bytes", "300")
        ros.spin_for(1.0)
        sent_after = emulator_status()["hub"]
        self.assertEqual(sent_after["frames_corrupted"] - sent_before["frames_corrupted"], 5)
        self.assertEqual(sent_after["garbage_bytes"] - sent_before["garbage_bytes"], 300)
        mark_ns = ros.now_ns()
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("tactile_driver: hub", mark_ns) is not None, 5.0))
        after = self.diagnostic("tactile_driver: hub")
        delta = {k: int(after[k]) - int(before[k]) for k in ("crc_errors", "missed_frames", "garbage_bytes")}
        print(f"hub link after 5 corrupted frames and 300 garbage bytes: {delta}")
        self.assertEqual(delta["crc_errors"], 5)
        self.assertEqual(delta["missed_frames"], 5, "an intact frame was lost (or a corrupted one passed)")
        # the garbage, and each corrupted frame but the byte its sync was found at... all skipped
        self.assertGreaterEqual(delta["garbage_bytes"], 300)

    def test_3_hub_unplugged_mid_horizontal_goal_leaves_the_motor_bus_answering(self):
        ros = self.ros
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("motor_driver: bus") is not None, 30.0))
        fault("world", "horizontal")
        handle = ros.send_until_started(self.manipulate, SLOW_HORIZONTAL, timeout_sec=30.0)
        result = handle.get_result_async()
        accepted = len(self.joints)

        def rotation(m: JointState) -> float:
            return m.position[list(m.name).index("thumb_rotation")]

        def rotating() -> bool:
            # by how far it turned: a test of five samples' velocity missed, in two runs of four, the
            # turn that ended the goal edge_lost
            moved = self.joints[accepted:]
            return len(moved) > 1 and abs(rotation(moved[-1]) - rotation(moved[0])) > 0.03

        self.assertTrue(ros.spin_until(lambda: result.done() or rotating(), 15.0), "the thumb never rotated")
        self.assertFalse(result.done(), f"the goal ended before the fault: {result.result()}")
        since = ros.now_ns()
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("motor_driver: bus", since) is not None, 5.0))
        bus_before = self.diagnostic("motor_driver: bus")
        unplugged = len(self.joints)
        fault("hub-unplug", "--seconds", "1")
        unplugged_ns = ros.now_ns()
        self.assertTrue(ros.spin_until(result, 5.0), "the goal went on without its sensors")
        self.assertEqual(goal_outcome(result.result()), ("ABORTED", "sensor_stale"))
        # 'taxels/thumb silent for N ms' or 'taxels/thumb N ms older than /joint_states': whichever
        # the watchdog sees first, a timer tick or a /joint_states message
        self.assertTrue(ros.wait_for_log(name="manipulation",
                                         contains="manipulate goal ended: sensor_stale (taxels/thumb "),
                        "the abort does not name the thumb's taxels")
        # what the motor driver published 0.5 s after the abort came here (this process may receive
        # /joint_states late on a loaded machine: wait for that message, not for 0.5 s)
        at_stop_by = ros.message_at(self.joints, 0.5)
        self.assertTrue(stopped(at_stop_by), f"still moving: {list(at_stop_by.velocity)}")
        self.assertTrue(ros.wait_for_log(name="tactile_driver", contains=f"serial port {EMULATOR_DIR / 'hub'} lost"))

        plugged_ns = unplugged_ns + int(1.0e9)
        self.assertTrue(ros.spin_until(lambda: self.taxels and stamp_ns(self.taxels[-1]) > plugged_ns, 15.0),
                        "no /prisma/thumb/taxels after the hub came back")
        self.assertTrue(ros.spin_until(lambda: int((self.diagnostic("tactile_driver: hub") or {})
                                                   .get("reconnects", 0)) >= 1, 5.0), "/diagnostics shows no reconnect")
        # the servos answered throughout: the motor driver read them at its rate and missed nothing.
        # Counted once this process holds a /joint_states stamped after the window: the taxels came
        # back first while the second of /joint_states queued behind them was still being taken
        ros.message_stamped(self.joints, plugged_ns)
        during = [stamp_ns(m) for m in self.joints[unplugged:] if unplugged_ns <= stamp_ns(m) <= plugged_ns]
        self.assertGreater(len(during), 50, "/joint_states stalled while the hub was unplugged")
        since = ros.now_ns()
        self.assertTrue(ros.spin_until(lambda: self.diagnostic("motor_driver: bus", since) is not None, 5.0))
        bus_after = self.diagnostic("motor_driver: bus")
        # not a transaction failed: a status a busy machine read late was read again (retries count each)
        moved = {k: int(bus_after[k]) - int(bus_before[k]) for k in BUS_MISSES}
        self.assertEqual(moved["comm_failures"], 0, f"motor bus transactions failed with the hub unplugged: {moved}")
        self.assertEqual(moved["retries"], moved["dropped_status"] + moved["corrupt_status"], moved)
        status = emulator_status()
        self.assertEqual((status["hub"]["unplugs"], status["hub"]["plugged"]), (1, True))

        fault("world", "horizontal")
        self.assertEqual(goal_outcome(self.run_goal(Manipulate.Goal(motion="horizontal"))), ("SUCCEEDED", "edge_lost"))

    def test_4_servo_overload_mid_grasp(self):
        ros = self.ros
        result = self.start_slow_grasp()
        fault("servo-error", "--motor", "fingers", "--bit", "overload")
        self.addCleanup(fault, "servo-clear")  # the tests after this one need the servo back
        self.assertTrue(ros.spin_until(result, 5.0), "the grasp went on with an overloaded servo")
        fault_reason = "motor_fault: fingers (id 1) hardware error bit 5 overload"
        self.assertEqual(goal_outcome(result.result()), ("ABORTED", fault_reason))  # the driver's words
        self.assertTrue(ros.wait_for_log(name="manipulation", contains=f"grasp goal ended: {fault_reason}"))
        self.assertTrue(ros.spin_until(lambda: not emulator_status()["servos"]["fingers"]["torque_on"], 2.0),
                        "the overloaded servo's torque is still on")
        cleared_ns = ros.now_ns()
        fault("servo-clear")
        # the motor driver takes the servo back once it reads the cleared status (torque on again) and
        # refuses a move before that, motor_fault, as it should: a CI run's Grasp sent 15 ms after the
        # clear ended so. Its /diagnostics say when it holds no fault for the servo any more
        self.assertTrue(ros.spin_until(lambda: (self.diagnostic("motor_driver: fingers", cleared_ns) or {})
                                       .get("hardware_error") == "0", 5.0),
                        "the motor driver still holds the fingers' overload after servo-clear")
        fault("world", "pinch_grasp")
        self.assertEqual(goal_outcome(self.run_goal(Grasp.Goal(grasp="pinch"))), ("SUCCEEDED", "force_reached"))

    def test_5_servo_off_the_bus_mid_grasp(self):
        """A servo that stops answering: the goal is aborted, by whichever safety net fires first
        (manipulation's watchdog when /joint_states stall while the driver retries: sensor_stale;
        the driver's failed transaction: motor_fault communication), and the servos still on the
        bus stop within 0.5 s. Once the servo answers again the driver has the bus back (reopened
        after a failure) and the next Grasp succeeds."""
        ros = self.ros
        result = self.start_slow_grasp()
        fault("servo-silent", "--motor", "thumb_flexion", "--seconds", "1.0")
        self.assertTrue(ros.spin_until(result, 5.0), "the grasp went on with a servo off the bus")
        status, reason = goal_outcome(result.result())
        self.assertIn((status, reason.partition(":")[0]), {("ABORTED", "sensor_stale"), ("ABORTED", "motor_fault")})
        ros.spin_for(0.5)
        fingers = emulator_status()["servos"]["fingers"]
        self.assertTrue(fingers["velocity_rpm"] == 0 or not fingers["torque_on"], f"fingers still driven: {fingers}")
        ros.spin_for(1.0)  # the servo is back
        fault("world", "pinch_grasp")
        self.assertEqual(goal_outcome(self.run_goal(Grasp.Goal(grasp="pinch"))), ("SUCCEEDED", "force_reached"))

    def test_6_paper_scenarios(self):
        ends, rotations, forces = {}, {}, {}
        for name, spec in HAND_SCENARIOS.items():
            # the scenario's pushes count from its goal's start, as in prisma-sim: here pushed by the
            # `push` command once the goal runs (the world's own clock starts at `world`, and a goal
            # that a busy machine started 0.8 s later held the hand as it found it after the push)
            pushes = scenario_world(name).disturbances
            fault("world", name, "--pushes", "off")
            goal = (Grasp.Goal if spec.action == "grasp" else Manipulate.Goal)(**spec.goal)
            start = emulator_status()
            handle = self.start_goal(goal)
            started = time.monotonic()
            for push in pushes:
                self.ros.spin_for(max(0.0, started + push.start_s - time.monotonic()))
                fault("push", "--dx-mm", str(push.dx_mm), "--dy-mm", str(push.dy_mm),
                      "--dwidth-mm", str(push.dwidth_mm), "--duration-s", str(push.duration_s))
            ends[name] = goal_outcome(self.ros.result(handle, timeout_sec=40.0))
            end = emulator_status()
            rotations[name] = (end["servos"]["thumb_rotation"]["position_rad"]
                               - start["servos"]["thumb_rotation"]["position_rad"])
            forces[name] = end["forces_n"]
            print(f"{name}: {ends[name]}, thumb rotation {rotations[name]:+.3f} rad, forces {forces[name]}")
        # the holds restore the contact side by rotating the thumb (pushed 0.5 s into the goal),
        # and the combined one the thumb's 1 N
        self.assertGreater(rotations["disturbance"], 0.2)
        self.assertGreater(rotations["combined"], 0.2)
        self.assertAlmostEqual(forces["combined"]["thumb"], 1.0, delta=0.15)
        # a hold runs until its time is up: that is its success
        self.assertEqual(ends, {name: ("SUCCEEDED", EXPECTED_REASONS[name]) for name in HAND_SCENARIOS})

    def test_7_the_ball_let_go_is_put_back_by_replace_object(self):
        """As on the sim hand: the ball a pinch held, once its stand has let go of it, falls when the
        hand opens (without replace_object the next pinch ended joint_limit at 0 N), and
        /tactile_driver/replace_object puts it back between the open fingers (the emulator's world,
        through its control socket), refused while a finger touches it."""
        ros = self.ros

        def open_hand() -> None:
            opened = ros.result(ros.send_until_started(self.gripper, gripper_goal(0.0)), timeout_sec=30.0)
            self.assertEqual(goal_outcome(opened), ("SUCCEEDED", "reached_goal"))

        # after the scenarios `world` left the thumb as they ended (seen: flexion 5.3 rad, rotation
        # 1.1 rad; the ball then met the pad's edge and a pinch could end joint_limit): opened, the
        # pinch ball on its stand, and put back where the thumb pad meets it in its middle
        open_hand()
        fault("world", "pinch_ball")
        self.assertTrue(ros.call(Trigger, "/tactile_driver/replace_object", Trigger.Request()).success)
        self.assertEqual(goal_outcome(self.run_goal(Grasp.Goal(grasp="pinch"))), ("SUCCEEDED", "force_reached"))
        # the stand lets go 0.5 s after the pads hold the ball (its support fading with 0.2 s to 0.01 N/mm)
        self.assertTrue(ros.spin_until(lambda: emulator_status()["object"]["support_n_per_mm"] < 0.02, 5.0),
                        f"the stand still holds the ball: {emulator_status()['object']}")
        held = ros.call(Trigger, "/tactile_driver/replace_object", Trigger.Request())
        # the pads that touch it named (the thumb, and the index while it still presses)
        self.assertFalse(held.success)
        self.assertRegex(held.message, r"^the object cannot be re-placed while (index, )?thumb touch it: open the "
                                       r"hand first \(GripperCommand position 0\)$")
        open_hand()
        replaced = ros.call(Trigger, "/tactile_driver/replace_object", Trigger.Request())
        self.assertTrue(replaced.success, replaced.message)
        self.assertTrue(replaced.message.startswith("pinch_ball re-placed at the thumb pad's middle"), replaced.message)
        self.assertEqual(emulator_status()["object"], {"name": "pinch_ball", "support_n_per_mm": 1.0})
        self.assertEqual(goal_outcome(self.run_goal(Grasp.Goal(grasp="pinch"))), ("SUCCEEDED", "force_reached"))


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_clean_exit(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
        leftovers = sorted(p.name for p in EMULATOR_DIR.iterdir())
        self.assertEqual(leftovers, [], "the emulator left devices behind")
        EMULATOR_DIR.rmdir()
