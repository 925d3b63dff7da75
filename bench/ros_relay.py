"""Bare rclpy relays with the hand graph's message types, rates, QoS and hop count (needs ROS 2).

The yardstick of bench_ros_graph.py: each role stands in for one node of `hand.launch.py` or
`glove.launch.py`, in its own process, on rclpy's default SingleThreadedExecutor, with the same
topics, message types, rates and QoS depth (10) as the node it replaces, and no computation beyond
building the outgoing message from the incoming one (stamp and frame id copied):

    role                 stands in for     in                                    out
    sensor               tactile_driver    /joint_states                         5 TaxelArray per scan (rate_hz)
    force                force_estimator   5 x taxels                            5 x wrench (WrenchStamped)
    manipulation         manipulation      5 x taxels, 5 x wrench, /joint_states 5 x contact (ContactState),
                                                                                 MoveMotors goals (client)
    motor                motor_driver      MoveMotors goals (server)             /joint_states at 100 Hz,
                                                                                 goal feedback per tick
    glove_driver         glove_driver      -                                     /stag/frame, /stag/image
                                                                                 (frame_rate_hz)
    glove_perception     glove_perception  /stag/frame                           /stag/object, /stag/hand_pose,
                                                                                 /stag/weight per frame
    markers              tactile_markers   /prisma/hand/contact, /prisma/hand/   /prisma/relay_markers
                                           wrench (the real graph's)             (MarkerArray, rate_hz 30)
    stretch              tendon_stretch    /joint_states, /prisma/hand/wrench    /prisma/relay_model_joint_states
                                           (the real graph's)                    (a JointState per /joint_states)
    watch                a display         --topic (MarkerArray)                 -

`stretch` is tendon_stretch's relay in the display bench (graph_bench/display.py): beside the real
graph it takes the same two 100 Hz streams tendon_stretch reads and sends one JointState per
/joint_states message (its stamp, names and positions copied), nothing computed and nothing dropped.
`markers`, watched by `watch`, is the display bench's bare relay (issue 42's unit).
`markers` runs beside the real hand graph, as tactile_markers does, and sends the same MarkerArray
(per finger a 9-cell CUBE_LIST, a SPHERE, an ARROW and a TEXT marker) with the newest ContactState's
frame id and voltages copied in, nothing computed. `watch` subscribes to a MarkerArray topic as RViz
does (which is what wakes tactile_markers) and prints how many it received when stopped.

The MoveMotors hop: `manipulation` sends one velocity goal per `goal_every` index wrenches (10: the
real node's 0.1 s goal refresh at 100 Hz) and writes the stamp of the wrench that triggered it into
the goal's targets (sec, nanosec); `motor` echoes a goal's targets as its feedback positions, so a
recording of the action's status (acceptance stamp) and feedback topics gives, per goal, the
latency from the taxel stamp to the goal's acceptance at the motor driver.

Once built, a role takes the scheduling rung PRISMA_RT_PRIORITY / PRISMA_NICE ask for, as the nodes
do (prisma_common.scheduling); the benchmarks start the hand's roles on the control path's rung.

    python3 bench/ros_relay.py sensor --rate-hz 100
"""
from __future__ import annotations

import argparse
import sys

import rclpy
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3, WrenchStamped
from prisma_msgs.action import Grasp, Manipulate, MoveMotors
from prisma_msgs.msg import (
    ContactState,
    GloveFrame,
    HandContact,
    HandWrench,
    ObjectEstimate,
    TaxelArray,
    WeightEstimate,
)
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from prisma_common.hand import FINGERS
from prisma_common.scheduling import apply_priority_from_env
from prisma_common.topics import GRASP_ACTION, MANIPULATE_ACTION, MOVE_MOTORS_ACTION
from prisma_node_wiring.executor import SingleWaitExecutor

MOTORS = ("fingers", "thumb_flexion", "thumb_rotation")
DEPTH = 10  # every publisher and subscription of the nodes uses a keep-last depth of 10


class Sensor(Node):
    """tactile_driver (sim backend): a timer at rate_hz publishes one TaxelArray per finger, all
    stamped with the scan's read time; /joint_states is taken in (the hand_world contact source)."""

    def __init__(self, rate_hz: float) -> None:
        super().__init__("relay_sensor")
        self._pubs = [self.create_publisher(TaxelArray, f"prisma/{f}/taxels", DEPTH) for f in FINGERS]
        self._joints = None
        self.create_subscription(JointState, "joint_states", self._on_joints, DEPTH)
        self.create_timer(1.0 / rate_hz, self._on_scan)
        self._counts = [1300, 1420, 1180, 1370, 1250, 1510, 1330, 1160, 1400]
        self._voltages = [c * 3.3 / 4096 for c in self._counts]

    def _on_joints(self, msg: JointState) -> None:
        self._joints = msg

    def _on_scan(self) -> None:
        stamp = self.get_clock().now().to_msg()
        for finger, pub in zip(FINGERS, self._pubs):
            pub.publish(TaxelArray(header=Header(stamp=stamp, frame_id=f"prisma_{finger}_pad"), finger=finger,
                                   counts=self._counts, voltages=self._voltages))


class Force(Node):
    """force_estimator: every TaxelArray -> one WrenchStamped with its header (zero wrench)."""

    def __init__(self) -> None:
        super().__init__("relay_force")
        self._pubs = {f: self.create_publisher(WrenchStamped, f"prisma/{f}/wrench", DEPTH) for f in FINGERS}
        for f in FINGERS:
            self.create_subscription(TaxelArray, f"prisma/{f}/taxels", lambda m, f=f: self._on_taxels(f, m), DEPTH)

    def _on_taxels(self, finger: str, msg: TaxelArray) -> None:
        self._pubs[finger].publish(WrenchStamped(header=msg.header))


class Manipulation(Node):
    """manipulation: every TaxelArray -> one ContactState with its header and voltages; wrenches and
    /joint_states are kept; every `goal_every`-th index wrench sends a MoveMotors velocity goal."""

    def __init__(self, goal_every: int, like_node: bool = False) -> None:
        super().__init__("relay_manipulation")
        self._pubs = {f: self.create_publisher(ContactState, f"prisma/{f}/contact", DEPTH) for f in FINGERS}
        self._wrench: dict[str, WrenchStamped] = {}
        self._joints = None
        for f in FINGERS:
            self.create_subscription(TaxelArray, f"prisma/{f}/taxels", lambda m, f=f: self._on_taxels(f, m), DEPTH)
            self.create_subscription(WrenchStamped, f"prisma/{f}/wrench", lambda m, f=f: self._on_wrench(f, m), DEPTH)
        self.create_subscription(JointState, "joint_states", self._on_joints, DEPTH)
        self._client = ActionClient(self, MoveMotors, MOVE_MOTORS_ACTION)
        self._goal_every = goal_every
        self._index_wrenches = 0
        if like_node:
            # the rest of the node's wait set (2 action servers, the 50 Hz watchdog timer), doing
            # nothing: what the executor costs for entities that are idle
            reject = lambda request: GoalResponse.REJECT  # noqa: E731
            self._servers = [ActionServer(self, action, name, lambda handle: None, goal_callback=reject)
                             for action, name in ((Grasp, GRASP_ACTION), (Manipulate, MANIPULATE_ACTION))]
            self.create_timer(0.02, lambda: None)

    def _on_taxels(self, finger: str, msg: TaxelArray) -> None:
        self._pubs[finger].publish(ContactState(header=msg.header, finger=finger, voltages=msg.voltages))

    def _on_wrench(self, finger: str, msg: WrenchStamped) -> None:
        self._wrench[finger] = msg
        if finger != "index" or self._goal_every <= 0:
            return
        self._index_wrenches += 1
        if self._index_wrenches % self._goal_every == 0 and self._client.server_is_ready():
            stamp = msg.header.stamp
            self._client.send_goal_async(MoveMotors.Goal(
                motors=list(MOTORS), mode="velocity",
                targets=[float(stamp.sec), float(stamp.nanosec), 0.0], timeout=0.3))

    def _on_joints(self, msg: JointState) -> None:
        self._joints = msg


class Motor(Node):
    """motor_driver (sim): /joint_states at rate_hz; a MoveMotors goal runs until the next one
    preempts it, with feedback on every tick (positions = the goal's targets)."""

    def __init__(self, rate_hz: float) -> None:
        super().__init__("relay_motor")
        self._joint_pub = self.create_publisher(JointState, "joint_states", DEPTH)
        self._goal = None
        self._done: Future | None = None
        self._server = ActionServer(self, MoveMotors, MOVE_MOTORS_ACTION, self._execute,
                                    goal_callback=lambda request: GoalResponse.ACCEPT,
                                    cancel_callback=lambda handle: CancelResponse.ACCEPT, result_timeout=10)
        self.create_timer(1.0 / rate_hz, self._on_tick)

    async def _execute(self, handle):
        if self._goal is not None:  # preempted by this goal, as motor_driver does
            self._end()
        self._goal, self._done = handle, Future()
        return await self._done

    def _end(self) -> None:
        handle, done = self._goal, self._done
        self._goal, self._done = None, None
        if handle.is_cancel_requested:
            handle.canceled()
        else:
            handle.succeed()
        done.set_result(MoveMotors.Result(success=True, final_positions=[0.0] * len(MOTORS), reason="preempted"))

    def _on_tick(self) -> None:
        now = self.get_clock().now().to_msg()
        self._joint_pub.publish(JointState(header=Header(stamp=now), name=list(MOTORS), position=[0.0] * 3,
                                           velocity=[0.0] * 3, effort=[0.0] * 3))
        if self._goal is not None:
            if self._goal.is_cancel_requested:
                self._end()
                return
            self._goal.publish_feedback(MoveMotors.Feedback(
                positions=self._goal.request.targets, velocities=[0.0] * 3, currents=[0.0] * 3))


class GloveDriver(Node):
    """glove_driver (sim): polled at poll_rate_hz, a 32x32 frame every 1/frame_rate_hz s as a
    GloveFrame and a 32FC1 Image."""

    def __init__(self, frame_rate_hz: float, poll_rate_hz: float, rows: int = 32, cols: int = 32) -> None:
        super().__init__("relay_glove_driver")
        self._frame_pub = self.create_publisher(GloveFrame, "stag/frame", DEPTH)
        self._image_pub = self.create_publisher(Image, "stag/image", DEPTH)
        self._period_ns = int(1e9 / frame_rate_hz)
        self._next_ns = self.get_clock().now().nanoseconds
        self._rows, self._cols = rows, cols
        self._raw = [520] * (rows * cols)
        self._pressure = [0.1] * (rows * cols)
        self._image = bytes(4 * rows * cols)
        self.create_timer(1.0 / poll_rate_hz, self._on_poll)

    def _on_poll(self) -> None:
        now = self.get_clock().now()
        if now.nanoseconds < self._next_ns:
            return
        self._next_ns += self._period_ns
        header = Header(stamp=now.to_msg(), frame_id="stag_glove")
        self._frame_pub.publish(GloveFrame(header=header, rows=self._rows, cols=self._cols, raw=self._raw,
                                           pressure=self._pressure, shorted=False, contact=True))
        self._image_pub.publish(Image(header=header, height=self._rows, width=self._cols, encoding="32FC1",
                                      is_bigendian=0, step=4 * self._cols, data=self._image))


class GlovePerception(Node):
    """glove_perception: every GloveFrame -> an object estimate (27 labels, as the shipped object
    model), a hand-pose estimate and a weight (what the node publishes per frame of the sim glove)."""

    def __init__(self) -> None:
        super().__init__("relay_glove_perception")
        self._object_pub = self.create_publisher(ObjectEstimate, "stag/object", DEPTH)
        self._pose_pub = self.create_publisher(ObjectEstimate, "stag/hand_pose", DEPTH)
        self._weight_pub = self.create_publisher(WeightEstimate, "stag/weight", DEPTH)
        self.create_subscription(GloveFrame, "stag/frame", self._on_frame, DEPTH)
        self._labels = [f"object_{i}" for i in range(27)]
        self._probabilities = [1.0 / 27] * 27

    def _on_frame(self, msg: GloveFrame) -> None:
        self._object_pub.publish(ObjectEstimate(header=msg.header, label=self._labels[0], confidence=0.5,
                                                labels=self._labels, probabilities=self._probabilities,
                                                frames_used=8))
        self._pose_pub.publish(ObjectEstimate(header=msg.header, label=self._labels[0], confidence=0.5,
                                              labels=self._labels, probabilities=self._probabilities,
                                              frames_used=1))
        self._weight_pub.publish(WeightEstimate(header=msg.header, grams=100.0, baseline_grams=0.0))


class Markers(Node):
    """tactile_markers: keeps the newest ContactState and wrench per finger; a timer at rate_hz
    publishes one MarkerArray of the same markers the node sends (nothing computed)."""

    def __init__(self, rate_hz: float) -> None:
        super().__init__("relay_markers")
        self._pub = self.create_publisher(MarkerArray, "prisma/relay_markers", DEPTH)
        self._contacts: dict[str, ContactState] = {}
        self._wrenches: dict[str, WrenchStamped] = {}
        self.create_subscription(HandContact, "prisma/hand/contact", self._on_contact, DEPTH)
        self.create_subscription(HandWrench, "prisma/hand/wrench", self._on_wrench, DEPTH)
        self.create_timer(1.0 / rate_hz, self._on_display)

    def _on_contact(self, msg: HandContact) -> None:
        for contact in msg.contacts:
            self._contacts[contact.finger] = contact

    def _on_wrench(self, msg: HandWrench) -> None:
        self._wrenches.update(zip(msg.fingers, msg.wrenches))

    def _on_display(self) -> None:
        markers = []
        for finger, contact in self._contacts.items():
            header = Header(frame_id=contact.header.frame_id)
            cells = [Point(x=(i % 3 - 1) * 0.004, y=(i // 3 - 1) * 0.004, z=0.0005) for i in range(9)]
            colours = [ColorRGBA(r=1.0, g=float(v) / 3.3, b=0.1, a=1.0) for v in contact.voltages]
            force = self._wrenches[finger].wrench.force.z if finger in self._wrenches else 0.0
            pose = Pose(orientation=Quaternion(w=1.0))
            markers += [
                Marker(header=header, ns=finger, id=0, type=Marker.CUBE_LIST, pose=pose, frame_locked=True,
                       scale=Vector3(x=0.0036, y=0.0036, z=0.001), points=cells, colors=colours,
                       text=f"{contact.header.stamp.sec} {contact.safe}"),
                Marker(header=header, ns=finger, id=1, type=Marker.SPHERE, pose=pose, frame_locked=True,
                       scale=Vector3(x=0.0024, y=0.0024, z=0.0024), color=ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)),
                Marker(header=header, ns=finger, id=2, type=Marker.ARROW, pose=pose, frame_locked=True,
                       points=[Point(z=0.02 * force), Point()], scale=Vector3(x=0.002, y=0.004, z=0.004),
                       color=ColorRGBA(g=1.0, a=1.0)),
                Marker(header=header, ns=finger, id=3, type=Marker.TEXT_VIEW_FACING, pose=pose, frame_locked=True,
                       scale=Vector3(z=0.005), color=ColorRGBA(g=1.0, a=1.0), text=f"{force:.2f} N"),
            ]
        if markers:
            self._pub.publish(MarkerArray(markers=markers))


class Stretch(Node):
    """tendon_stretch: the newest hand wrench kept, each /joint_states copied out at once."""

    def __init__(self) -> None:
        super().__init__("relay_stretch")
        self._pub = self.create_publisher(JointState, "prisma/relay_model_joint_states", DEPTH)
        self._wrench: HandWrench | None = None
        self.create_subscription(HandWrench, "prisma/hand/wrench", self._on_wrench, DEPTH)
        self.create_subscription(JointState, "joint_states", self._on_joints, DEPTH)

    def _on_wrench(self, msg: HandWrench) -> None:
        self._wrench = msg

    def _on_joints(self, msg: JointState) -> None:
        self._pub.publish(JointState(header=msg.header, name=list(msg.name), position=list(msg.position)))


class Watch(Node):
    """A display's subscription to a MarkerArray topic; says how many arrived when stopped."""

    def __init__(self, topic: str) -> None:
        super().__init__("relay_watch")
        self.received = 0
        self.create_subscription(MarkerArray, topic, self._on_markers, DEPTH)

    def _on_markers(self, msg: MarkerArray) -> None:
        self.received += 1


def build(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("role", choices=["sensor", "force", "manipulation", "motor", "glove_driver",
                                         "glove_perception", "markers", "stretch", "watch"])
    parser.add_argument("--rate-hz", type=float, default=None,
                        help="sensor: scan rate; motor: /joint_states rate (default 100); markers: display rate "
                             "(default 30)")
    parser.add_argument("--topic", default="/prisma/tactile_markers", help="watch: the MarkerArray topic")
    parser.add_argument("--goal-every", type=int, default=10,
                        help="manipulation: one MoveMotors goal per this many index wrenches (0 = none)")
    parser.add_argument("--like-node", action="store_true",
                        help="manipulation: also the node's idle entities (Grasp and Manipulate action servers, "
                             "50 Hz timer)")
    parser.add_argument("--executor", choices=["rclpy", "single_wait"], default="rclpy",
                        help="rclpy's SingleThreadedExecutor (the yardstick) or the nodes' own "
                             "(prisma_node_wiring.executor; bench_executor.py compares them)")
    parser.add_argument("--frame-rate-hz", type=float, default=7.3, help="glove_driver: frames/s")
    parser.add_argument("--poll-rate-hz", type=float, default=50.0, help="glove_driver: poll timer rate")
    return parser.parse_known_args(argv)


def main(argv: list[str] | None = None) -> int:
    args, ros_args = build(sys.argv[1:] if argv is None else argv)
    if args.rate_hz is None:
        args.rate_hz = 30.0 if args.role == "markers" else 100.0
    if args.rate_hz <= 0 or args.frame_rate_hz <= 0 or args.poll_rate_hz <= 0:
        print(f"rates must be > 0 (got --rate-hz {args.rate_hz}, --frame-rate-hz {args.frame_rate_hz}, "
              f"--poll-rate-hz {args.poll_rate_hz})", file=sys.stderr)
        return 2
    rclpy.init(args=ros_args)
    node = started = None
    try:
        node = {
            "sensor": lambda: Sensor(args.rate_hz),
            "force": Force,
            "manipulation": lambda: Manipulation(args.goal_every, args.like_node),
            "motor": lambda: Motor(args.rate_hz),
            "glove_driver": lambda: GloveDriver(args.frame_rate_hz, args.poll_rate_hz),
            "glove_perception": GlovePerception,
            "markers": lambda: Markers(args.rate_hz),
            "stretch": Stretch,
            "watch": lambda: Watch(args.topic),
        }[args.role]()
        # onto the rung the benchmark asks for (PRISMA_RT_PRIORITY, PRISMA_NICE) once built, as a node does
        scheduling = apply_priority_from_env()
        if scheduling:
            node.get_logger().info(f"scheduling: {scheduling}")
        started = node.get_clock().now()
        rclpy.spin(node, executor=SingleWaitExecutor() if args.executor == "single_wait" else None)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # SIGINT / SIGTERM from the benchmark: a normal stop
    finally:
        if isinstance(node, Watch) and started is not None:
            seconds = (node.get_clock().now() - started).nanoseconds / 1e9
            print(f"watch: {node.received} messages in {seconds:.1f} s", flush=True)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
