"""The teleoperation hops as bare rclpy relays, and the step glove both graphs are driven by (needs ROS 2).

The yardstick of bench_teleop.py, as bench/ros_relay.py is bench_ros_graph.py's: each role stands in
for one node of `teleop.launch.py`, in its own process, on rclpy's default executor, with the same
topics, message types and QoS depth (10), and no computation beyond building the outgoing message:

    role           stands in for       in                                  out
    glove          a hand-pose glove   -                                   /glove/joint_states (60 Hz)
    teleop         teleop              /glove/joint_states, the            /prisma/teleop/motor_targets (stamp copied),
                                       Teleoperate goal's feedback         one Teleoperate goal (client)
    manipulation   manipulation        /prisma/teleop/motor_targets        a MoveMotors velocity goal on the next
                                                                           100 Hz step after a changed target (the
                                                                           real node steps once per tactile scan);
                                                                           Teleoperate server: feedback every step

(`motor`, the motor driver's MoveMotors server, is bench/ros_relay.py's.) `glove` is used by both
runs: the operator's nominal hand (prisma_teleop.synthetic_glove_core), the fingers stepping
between open and `--level` of a fist every `--step-s`; it prints `step <stamp_ns> <level>` for each
step's first sample. The relay manipulation writes the stamp of the target that triggered a goal
into the goal's targets (sec, nanosec), which the motor relay echoes as its feedback positions.

    python3 bench/teleop_relay.py glove --step-s 1.5
"""
from __future__ import annotations

import argparse
import sys

import rclpy
from prisma_msgs.action import MoveMotors, Teleoperate
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from prisma_common.hand import MOTOR_NAMES
from prisma_common.topics import MOVE_MOTORS_ACTION, TELEOPERATE_ACTION, TELEOP_TARGETS, relative
from prisma_teleop.retargeting import nominal_calibration
from prisma_teleop.synthetic_glove_core import Synergies, hand_pose

DEPTH = 10
GLOVE_HZ = 60.0
TICK_HZ = 100.0


class Glove(Node):
    def __init__(self, step_s: float, level: float) -> None:
        super().__init__("bench_glove")
        self._pub = self.create_publisher(JointState, "glove/joint_states", DEPTH)
        calibration = nominal_calibration()
        self._poses = [hand_pose(Synergies(f, f, 0.0), calibration) for f in (0.0, level)]
        self._levels = (0.0, level)
        self._samples_per_step = max(1, round(step_s * GLOVE_HZ))
        self._n = 0
        self.create_timer(1.0 / GLOVE_HZ, self._on_timer)

    def _on_timer(self) -> None:
        which = (self._n // self._samples_per_step) % 2
        stamp = self.get_clock().now()
        pose = self._poses[which]
        self._pub.publish(JointState(header=Header(stamp=stamp.to_msg(), frame_id="glove"), name=list(pose),
                                     position=list(pose.values())))
        if self._n % self._samples_per_step == 0:
            print(f"step {stamp.nanoseconds} {self._levels[which]}", flush=True)
        self._n += 1


class Teleop(Node):
    def __init__(self) -> None:
        super().__init__("bench_relay_teleop")
        self._pub = self.create_publisher(JointState, relative(TELEOP_TARGETS), DEPTH)
        self.create_subscription(JointState, "glove/joint_states", self._on_glove, DEPTH)
        self._positions = [0.0] * len(MOTOR_NAMES)
        # the node keeps a Teleoperate goal: its client takes the goal's feedback (every manipulation step)
        self._client = ActionClient(self, Teleoperate, TELEOPERATE_ACTION)
        self._sent = False

    def _on_glove(self, msg: JointState) -> None:
        # the message the node sends: the three motors, the glove sample's header (the first joint's
        # angle as the fingers target: it changes when the glove steps, as the node's targets do)
        self._positions[0] = msg.position[0]
        self._pub.publish(JointState(header=msg.header, name=list(MOTOR_NAMES), position=self._positions))
        if not self._sent and self._client.server_is_ready():
            self._sent = True
            self._client.send_goal_async(Teleoperate.Goal(), feedback_callback=lambda feedback: None)


class Manipulation(Node):
    def __init__(self) -> None:
        super().__init__("bench_relay_manipulation")
        self.create_subscription(JointState, relative(TELEOP_TARGETS), self._on_target, DEPTH)
        self._client = ActionClient(self, MoveMotors, MOVE_MOTORS_ACTION)
        self._latest: JointState | None = None
        self._last_sent: list[float] | None = None
        self._teleop = None  # the running Teleoperate goal's handle
        self._server = ActionServer(self, Teleoperate, TELEOPERATE_ACTION, self._execute,
                                    goal_callback=lambda request: GoalResponse.ACCEPT,
                                    cancel_callback=lambda handle: CancelResponse.ACCEPT)
        self.create_timer(1.0 / TICK_HZ, self._on_tick)

    async def _execute(self, handle):
        self._teleop = handle
        return await Future()  # follows until the bench stops it

    def _on_target(self, msg: JointState) -> None:
        self._latest = msg

    def _on_tick(self) -> None:
        msg = self._latest
        if self._teleop is not None and msg is not None:  # the node's feedback of every step
            self._teleop.publish_feedback(Teleoperate.Feedback(
                phase="following", motors=list(MOTOR_NAMES), targets=list(msg.position), positions=[0.0] * 3,
                pad_forces=[0.0] * 5, force_limited=[]))
        if msg is None or list(msg.position) == self._last_sent or not self._client.server_is_ready():
            return
        self._last_sent = list(msg.position)
        stamp = msg.header.stamp
        self._client.send_goal_async(MoveMotors.Goal(motors=list(MOTOR_NAMES), mode="velocity",
                                                     targets=[float(stamp.sec), float(stamp.nanosec), 0.0],
                                                     timeout=0.3))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("role", choices=["glove", "teleop", "manipulation"])
    parser.add_argument("--step-s", type=float, default=1.5, help="glove: seconds between steps")
    parser.add_argument("--level", type=float, default=0.5, help="glove: the closed step's share of a fist")
    args, ros_args = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    if args.step_s <= 0 or not 0 < args.level <= 1:
        print(f"--step-s must be > 0 and --level in (0, 1] (got {args.step_s}, {args.level})", file=sys.stderr)
        return 2
    rclpy.init(args=ros_args)
    node = None
    try:
        node = {"glove": lambda: Glove(args.step_s, args.level), "teleop": Teleop,
                "manipulation": Manipulation}[args.role]()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # SIGINT / SIGTERM from the benchmark: a normal stop
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
