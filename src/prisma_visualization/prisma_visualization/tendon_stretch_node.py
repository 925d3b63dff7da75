"""tendon_stretch: the hand's full joint state with the fingers where they are under load, for
robot_state_publisher (tendon_stretch_core.py says how).

    ros2 run prisma_visualization tendon_stretch --ros-args --params-file config/tendon_stretch.yaml

Reads joint_states (the motor angles, unchanged for everyone else), prisma/hand/wrench (or the
per-finger wrenches until that speaks: the force estimator's Fz in each pad frame) and
robot_description (robot_state_publisher's, latched: the couplings are read from it). Publishes
prisma/model_joint_states at the display's rate, once per publish_period (0.04 s: robot_state_publisher
draws at most 20 Hz): at each tick the newest joint_states message and the newest wrench are taken
(display_gate.py) and one full joint state goes out with that joint_states message's stamp, the motors
and every coupled joint. The samples between two ticks are dropped unread (DDS keeps the newest of
each); a wrench taken after the joint state at the same tick counts from the next one.
hand.launch.py remaps robot_state_publisher's joint_states to it, so one publisher sets every joint it
draws and a mimic joint is never computed from the motors by one message and given by the next
(robot_state_publisher takes a joint named in a message over its mimic rule).
Until the description arrives nothing is published.
"""
from __future__ import annotations

from geometry_msgs.msg import WrenchStamped
from prisma_msgs.msg import HandWrench
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from prisma_common.hand import FINGERS
from prisma_common.kinematics import DescriptionError, RobotModel
from prisma_common.messages import ns_from_stamp
from prisma_common.parameters import ParameterError
from prisma_force_estimator.ros_conversions import hand_wrench_samples
from prisma_hand_sim.hand_world import HandWorldParams
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import FingerAndHandInput, stream_publisher, stream_subscription

from .display_gate import DISPLAY_DEPTH, DisplayGate
from .node_config import TendonStretchConfig
from .tendon_stretch_core import TendonStretch, forces_at

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TendonStretchNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("tendon_stretch", **kwargs)
        # fails here, at start, with the parameter's name and value when one is invalid
        self.config = declare_config(self, TendonStretchConfig)
        accept_live_changes(self, TendonStretchConfig, self._reconfigure)
        self.stretch: TendonStretch | None = None
        self._forces: dict[str, tuple[int, float]] = {}
        self._publisher = stream_publisher(self, JointState, "prisma/model_joint_states")
        self._description_sub = self.create_subscription(String, "robot_description", self._on_description, LATCHED)
        # the inputs run once per display tick (the timer opens the gate), the wrenches created first:
        # at a tick where both are ready the executor takes them in this order
        self._gate = DisplayGate()
        self._wrenches = FingerAndHandInput(self, WrenchStamped, HandWrench, "wrench", FINGERS, hand_wrench_samples,
                                            self._on_wrench, depth=DISPLAY_DEPTH, callback_group=self._gate)
        self._joint_sub = stream_subscription(self, JointState, "joint_states", self._on_joints,
                                              depth=DISPLAY_DEPTH, callback_group=self._gate)
        self._display_timer = self.create_timer(self.config.publish_period, self._gate.open)
        self.get_logger().info(f"waiting for robot_description; prisma/model_joint_states every "
                               f"{self.config.publish_period * 1e3:.0f} ms from the newest joint_states and "
                               f"pads' wrenches (older than {self.config.force_timeout:g} s: none)")

    def _reconfigure(self, config: TendonStretchConfig) -> None:
        self.config = config

    def _on_description(self, msg: String) -> None:
        try:
            params = HandWorldParams(tendon_stiffness_n_per_mm=self.config.tendon_stiffness_n_per_mm)
            self.stretch = TendonStretch.from_model(RobotModel.from_urdf(msg.data), params)
        except DescriptionError as exc:
            self.get_logger().error(f"robot_description: {exc}; the fingers are not drawn until a readable one")
            return
        joints = {f: [c.joint for c in couplings] for f, couplings in self.stretch.loaded.items()}
        self.get_logger().info(f"robot_description read: loaded joints {joints}")

    def _on_wrench(self, finger: str, msg: WrenchStamped) -> None:
        self._forces[finger] = (ns_from_stamp(msg.header.stamp), float(msg.wrench.force.z))

    def _on_joints(self, msg: JointState) -> None:
        if self.stretch is None or len(msg.name) != len(msg.position):
            return
        stamp_ns = ns_from_stamp(msg.header.stamp)
        forces = forces_at(self._forces, stamp_ns, int(self.config.force_timeout * 1e9))
        positions = self.stretch.joint_positions(dict(zip(msg.name, msg.position)), forces)
        out = JointState(header=msg.header)
        out.name = list(positions)
        out.position = [float(v) for v in positions.values()]
        self._publisher.publish(out)


def main(args=None) -> None:
    run_node(TendonStretchNode, "tendon_stretch", (ParameterError,), args)


if __name__ == "__main__":
    main()
