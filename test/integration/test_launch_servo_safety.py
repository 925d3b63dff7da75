"""launch_testing: the servos' own safety on `hand.launch.py hardware:=emulated home:=true`, the
emulated X-series servos as strict as the e-Manual (Bus Watchdog, power-up without the turn count,
Current Limit, end stops). Every stop is measured from the emulator's own state (its servos' Bus
Watchdog firings and positions, `prisma-hand-fault status`), not from /joint_states. In order, on
one launch:

0. a pinch Grasp sent every 50 ms from the moment /prisma/grasp exists, again only when refused
   `not_ready` (the contract's one resend), ends `not_ready` (the graph coming up, the homing at
   start: `not_ready: homing (fingers, thumb_flexion, thumb_rotation)`) until one runs, and that one
   ends force_reached: never motor_fault, never not_homed; the motor driver does not log the stop
   (canceled) that ends its MoveMotors goal;
1. homing at start: every motor homed; each servo stalled at its open end stop pulling the homing
   current (the emulator's log), never more than its Current Limit;
2. a power cycle with the fingers closed past one turn: a MoveMotors close goal is refused
   `not_homed`, and a Grasp, a Teleoperate and a Manipulate end with the motor driver's `not_homed:
   ... home first` as their result's reason (GripperCommand: /diagnostics for each goal, the log once
   for three), nothing moved; the HomeMotors action finds the
   fingers' zero 7 rad away, the open hand then reads 0 +- 0.05 rad (on /joint_states and in the
   servo), and a pinch grasp ends force_reached;
3. the motor bus cut mid-goal (every servo off the bus): each servo stops itself within 0.3 s of the
   cut; with the bus back the driver reopens it and nothing moves until a new goal;
4. SIGSTOP of the motor driver mid-rotation: every servo stops within 0.3 s; after SIGCONT the goal
   ends `motor_fault` naming the bus watchdog and no servo moves until a new goal;
5. SIGKILL of the motor driver mid-rotation: every servo stops within 0.3 s.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import os
import re
import signal
import tempfile
import time
import unittest
from pathlib import Path

import pytest

from prisma_testing.emulated_launch import wait_until_homed
from prisma_testing.goals import goal_outcome, gripper_goal
from prisma_testing.launch_case import GraphTestCase, emulated_hand_launch
from prisma_testing.ros_harness import require_ros, stamped_after, stopped

require_ros()

import launch_testing  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import GripperCommand  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.action import Grasp, HomeMotors, Manipulate, MoveMotors, Teleoperate  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.control_socket import send  # noqa: E402
from prisma_common.goal_refusal import NOT_READY, refusal_code  # noqa: E402
from prisma_common.hand import MOTOR_NAMES  # noqa: E402

EMULATOR_DIR = Path(tempfile.gettempdir()) / f"prisma_servo_safety_{os.getpid()}"
STOP_LIMIT_S = 0.3  # the bound; the watchdog is armed at 0.1 s
HOMING_CURRENT_MA = 150.0  # config/motor_driver.yaml homing_current_ma
# the thumb turning slowly toward its 3 rad limit: seconds of motion for a fault to interrupt
ROTATE = dict(motors=["thumb_rotation"], mode="velocity", targets=[5.0], timeout=0.0)
# what the motor driver refuses a goal with after a power cycle, up to the motors it names: the why and what to do
NOT_HOMED = re.compile(r"^not_homed: fingers \(id 1\).* not homed since the servo powered up .*: home first")


@pytest.mark.launch_test
def generate_test_description():
    return emulated_hand_launch(EMULATOR_DIR)


def emulator(command: str, **args) -> dict:
    """A request to the emulator's control socket (prisma-hand-fault's protocol), from this process:
    the instant a fault takes effect is known to a few milliseconds, not a CLI's start-up time."""
    reply = send(EMULATOR_DIR / "control.sock", command, args)
    assert reply.get("ok"), f"{command} {args}: {reply}"
    return reply


def servos() -> dict:
    return emulator("status")["status"]["servos"]


def firings_since(t0: float) -> dict[str, list[float]]:
    """Each servo's Bus Watchdog firings after t0 (monotonic seconds, the emulator's clock)."""
    return {name: [f["at_s"] for f in s["watchdog_firings"] if f["at_s"] >= t0] for name, s in servos().items()}


class TestServoSafety(GraphTestCase):
    @classmethod
    def subscribe(cls, ros):
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        # not waited for: test_0 sends its first Grasp the moment the server exists
        cls.grasp = ros.action_client(Grasp, "/prisma/grasp", wait_sec=None)
        cls.move = ros.action_client(MoveMotors, "/prisma/motors/move", wait_sec=None)
        cls.home = ros.action_client(HomeMotors, "/prisma/motors/home", wait_sec=None)
        cls.manipulate = ros.action_client(Manipulate, "/prisma/manipulate", wait_sec=None)
        cls.teleoperate = ros.action_client(Teleoperate, "/prisma/teleoperate", wait_sec=None)
        cls.gripper = ros.action_client(GripperCommand, "/prisma/gripper_cmd", wait_sec=None)

    def move_goal(self, **fields) -> MoveMotors.Goal:
        goal = MoveMotors.Goal(**fields)
        goal.stamp = self.ros.probe.get_clock().now().to_msg()
        return goal

    def joint(self, name: str) -> float:
        """`name`'s position in the first /joint_states published from now on: the newest this process
        has received may still be from before what the test just did (a homing's new zero)."""
        msg = self.ros.message_at(self.joints, 0.0)
        return msg.position[list(msg.name).index(name)]

    def start_rotation(self):
        """A MoveMotors goal turning the thumb at 5 rpm (seconds from its limit), seen moving in the servo."""
        ros = self.ros
        handle = ros.send_goal(self.move, self.move_goal(**ROTATE))
        self.assertTrue(handle.accepted)
        result = handle.get_result_async()
        ros.spin_until(lambda: result.done() or abs(servos()["thumb_rotation"]["velocity_rpm"]) > 4.0, 10.0)
        self.assertFalse(result.done(), f"the rotation ended before the fault: {result.result()}")
        return result

    def assert_each_stopped_itself(self, fault_s: float, what: str) -> None:
        """Every servo's watchdog fired within STOP_LIMIT_S of the fault, and each stands still."""
        self.assertTrue(self.ros.spin_until(lambda: all(firings_since(fault_s).values()), 2.0),
                        f"{what}: not every servo's watchdog fired: {firings_since(fault_s)}")
        delays = {name: at[0] - fault_s for name, at in firings_since(fault_s).items()}
        print(f"{what}: each servo stopped itself " + ", ".join(f"{n} {d * 1e3:.0f} ms" for n, d in delays.items())
              + " after the fault")
        for name, delay in delays.items():
            self.assertLess(delay, STOP_LIMIT_S, f"{what}: {name}")
        self.assertEqual({n: s["velocity_rpm"] for n, s in servos().items()}, dict.fromkeys(MOTOR_NAMES, 0.0))

    def assert_nothing_moves(self, seconds: float) -> None:
        before = {n: s["mechanical_ticks"] for n, s in servos().items()}
        self.ros.spin_for(seconds)
        self.assertEqual({n: s["mechanical_ticks"] for n, s in servos().items()}, before)

    def test_0_grasps_from_the_first_moment_end_only_not_ready_until_one_runs(self):
        ros = self.ros
        self.assertTrue(ros.spin_until(self.grasp.server_is_ready, 90.0), "no /prisma/grasp server")
        refused: dict[str, int] = {}  # each not_ready reason (numbers aside) and how often
        deadline = time.monotonic() + 150.0  # the force estimator loads its model for up to a minute
        while True:
            result = ros.result(ros.send_goal(self.grasp, Grasp.Goal(grasp="pinch")), timeout_sec=30.0)
            if refusal_code(result.result.reason) != NOT_READY:
                break
            why = re.sub(r"\d+", "#", result.result.reason)
            refused[why] = refused.get(why, 0) + 1
            self.assertLess(time.monotonic(), deadline, f"still refused not_ready after 150 s: {refused}")
            ros.spin_for(0.05)
        print(f"{sum(refused.values())} Grasps refused not_ready before one ran: {refused}")
        self.assertEqual(goal_outcome(result), ("SUCCEEDED", "force_reached"), f"after not_ready {refused}")
        ros.spin_for(0.5)  # the motor driver's log lines of the goal's end
        self.assertEqual(ros.logs(name="motor_driver", contains="MoveMotors goal ended: canceled"), [])
        # the hand stays closed on the ball: test_2 poses it anew (the emulator's world)

    def test_1_homed_at_start_pulling_no_more_than_the_homing_current(self, proc_output):
        wait_until_homed(self.ros, self.diagnostics, MOTOR_NAMES, timeout_sec=90.0)
        stalls = re.findall(r"servo (\d): stalled at its lo end stop .* pulling (\d+) mA", "".join(
            event.text.decode() for event in proc_output if event.process_name.startswith("hand_emulator")))
        self.assertEqual(sorted({int(servo) for servo, _ in stalls}), [1, 2, 3], stalls)
        self.assertTrue(all(float(ma) <= HOMING_CURRENT_MA for _, ma in stalls), stalls)
        for name, s in servos().items():
            self.assertLessEqual(s["peak_current_ma"], s["current_limit_ma"], name)
        # every servo lit (homed) and its watchdog armed: a driver held up while the graph starts (torch
        # loading beside it) may see a watchdog fire, and re-arms it on its next tick
        self.assertTrue(self.ros.spin_until(
            lambda: all((s["led"], s["bus_watchdog"]) == (1, 5) for s in servos().values()), 5.0), servos())

    def test_2_power_cycle_with_the_fingers_closed_past_one_turn(self):
        ros = self.ros
        # a power cycle while the hand holds an object (each motor within its first turn, the pads in
        # contact): a manipulation of it ends with the driver's refusal
        wait_diag = lambda: all(  # noqa: E731 - read now, in spin_until
            (self.latest_motor_diag(m) or {}).get("homed") == "False" for m in MOTOR_NAMES)
        emulator("world", name="horizontal")
        emulator("power-cycle")
        self.assertTrue(ros.spin_until(wait_diag, 10.0), "the driver did not see the power cycle")
        manipulate = ros.result(ros.send_until_started(self.manipulate, Manipulate.Goal(motion="horizontal"),
                                                       timeout_sec=30.0))
        self.assertEqual(manipulate.status, GoalStatus.STATUS_ABORTED)
        self.assertRegex(manipulate.result.stop_reason, NOT_HOMED)
        # the object taken away (a Grasp on it would end force_reached on its first scan, moving nothing)
        emulator("world", name="none")
        emulator("servo-place", motor="fingers", rad=7.0)
        emulator("power-cycle")
        self.assertLess(servos()["fingers"]["present_position_ticks"], 4096)  # the turn count is lost
        close = ros.result(ros.send_goal(self.move, self.move_goal(motors=["fingers"], mode="velocity",
                                                                    targets=[30.0], timeout=0.3)))
        self.assertEqual(close.status, GoalStatus.STATUS_ABORTED)
        self.assertTrue(close.result.reason.startswith("not_homed: fingers (id 1) not homed"), close.result.reason)
        # manipulation's first MoveMotors is refused: each kind's goal ends with the driver's refusal
        grasp = ros.result(ros.send_until_started(self.grasp, Grasp.Goal(grasp="pinch"), timeout_sec=60.0))
        self.assertEqual(grasp.status, GoalStatus.STATUS_ABORTED)
        self.assertRegex(grasp.result.reason, NOT_HOMED)
        closing = JointState(name=list(MOTOR_NAMES), position=[8.0, 1.0, 0.0])  # a glove closing the hand
        with ros.publishing(JointState, "/prisma/teleop/motor_targets", lambda _: closing, 50.0,
                            wait_for_subscribers=1):
            teleop = ros.result(ros.send_until_started(self.teleoperate, Teleoperate.Goal(), timeout_sec=30.0))
        self.assertEqual(teleop.status, GoalStatus.STATUS_ABORTED)
        self.assertRegex(teleop.result.reason, NOT_HOMED)
        # GripperCommand's result has no text: /diagnostics says why for each goal, the log once for them all
        for _ in range(3):
            handle = ros.send_until_started(self.gripper, gripper_goal(3.0), timeout_sec=30.0)
            self.assertEqual(ros.result(handle).status, GoalStatus.STATUS_ABORTED)
            self.assertRegex(ros.goal_end_reason(handle) or "no manipulation: goals status for it", NOT_HOMED)
        ros.spin_for(0.5)  # the log's lines
        self.assertEqual(len(ros.logs(name="manipulation", contains="gripper goal ended: not_homed: fingers")), 1)
        self.assertAlmostEqual(servos()["fingers"]["position_rad"], 7.0, delta=0.05)  # nothing moved

        homing = ros.result(ros.send_goal(self.home, HomeMotors.Goal()), timeout_sec=60.0)
        self.assertEqual((homing.status, homing.result.reason), (GoalStatus.STATUS_SUCCEEDED, "homed"))
        travel = dict(zip(homing.result.motors, homing.result.travel_rad))
        self.assertAlmostEqual(travel["fingers"], 7.0, delta=0.05)
        self.assertTrue(all(ma <= HOMING_CURRENT_MA for ma in homing.result.stall_current_ma))
        ros.spin_for(0.3)
        self.assertAlmostEqual(self.joint("fingers"), 0.0, delta=0.05)
        self.assertAlmostEqual(servos()["fingers"]["position_rad"], 0.0, delta=0.05)
        emulator("world", name="pinch_grasp")
        pinch = ros.result(ros.send_until_started(self.grasp, Grasp.Goal(grasp="pinch")), timeout_sec=30.0)
        self.assertEqual((pinch.status, pinch.result.reason), (GoalStatus.STATUS_SUCCEEDED, "force_reached"))
        ros.result(ros.send_goal(self.move, self.move_goal(motors=list(MOTOR_NAMES), mode="position",
                                                           targets=[0.0, 0.0, 0.0])), timeout_sec=30.0)

    def latest_motor_diag(self, motor: str) -> dict | None:
        from prisma_testing.emulated_launch import diagnostic_values

        return diagnostic_values(self.diagnostics, f"motor_driver: {motor}")

    def test_3_motor_bus_cut_mid_goal(self):
        rotation = self.start_rotation()
        cut_s = time.monotonic()
        for motor in MOTOR_NAMES:
            emulator("servo-silent", motor=motor)
        self.assert_each_stopped_itself(cut_s, "motor bus cut mid-goal")
        self.assertTrue(self.ros.spin_until(rotation.done, 5.0))
        self.assertTrue(rotation.result().result.reason.startswith("motor_fault: communication"),
                        rotation.result().result.reason)
        emulator("servo-clear")
        # the driver reopens the bus (its backoff: 0.5 s, doubling) and clears the fired watchdogs
        self.assertTrue(self.ros.spin_until(lambda: all(s["bus_watchdog"] == 5 for s in servos().values()), 20.0))
        self.assert_nothing_moves(1.0)

    def test_4_motor_driver_stopped_and_continued(self, proc_info):
        pid = proc_info["motor_driver"].pid
        rotation = self.start_rotation()
        stop_s = time.monotonic()
        os.kill(pid, signal.SIGSTOP)
        try:
            self.assert_each_stopped_itself(stop_s, "SIGSTOP of motor_driver mid-rotation")
            self.assert_nothing_moves(0.5)
        finally:
            os.kill(pid, signal.SIGCONT)
            thawed_ns = self.ros.now_ns()
        self.assertTrue(self.ros.spin_until(rotation.done, 5.0))
        self.assertEqual(rotation.result().status, GoalStatus.STATUS_ABORTED)
        self.assertIn("bus watchdog", rotation.result().result.reason)
        self.assert_nothing_moves(1.0)  # after SIGCONT, no servo moves until a new goal
        # nor does the driver report motion: its first /joint_states after the thaw already stand still
        after = stamped_after(self.joints, thawed_ns)
        self.assertGreater(len(after), 10)
        self.assertEqual([m for m in after if not stopped(m)], [], "moving after the thaw")
        self.assertEqual([s["bus_watchdog"] for s in servos().values()], [5, 5, 5])  # re-armed

    def test_5_motor_driver_killed(self, proc_info):
        self.start_rotation()
        kill_s = time.monotonic()
        os.kill(proc_info["motor_driver"].pid, signal.SIGKILL)
        proc_info.assertWaitForShutdown(process="motor_driver", timeout=10)
        self.assert_each_stopped_itself(kill_s, "SIGKILL of motor_driver mid-rotation")
        self.assert_nothing_moves(0.5)


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_only_the_killed_driver_exited_unclean(self, proc_info):
        codes = {info.process_name: info.returncode for info in proc_info}
        killed = [name for name in codes if name.startswith("motor_driver")]
        self.assertEqual([codes.pop(name) for name in killed], [-signal.SIGKILL])
        self.assertEqual({name: code for name, code in codes.items() if code != 0}, {})
