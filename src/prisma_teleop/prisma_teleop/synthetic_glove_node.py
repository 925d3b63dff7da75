"""synthetic_glove: a hand-pose glove worn by a scripted operator (synthetic_glove_core.py), for
teleoperation without a glove.

    ros2 run prisma_teleop synthetic_glove --ros-args --params-file config/synthetic_glove.yaml

Publishes glove/joint_states (sensor_msgs/JointState: the default joint set of retargeting.py, rad)
at rate_hz, stamped with the node clock: the operator closes around the ball, holds it, opens, then
sweeps the thumb through its opposition; again and again with loop true.
"""
from __future__ import annotations

from rclpy.node import Node
from rosidl_runtime_py.utilities import get_action, get_message
from sensor_msgs.msg import JointState

from prisma_common.messages import robot_types
from prisma_common.parameters import ParameterError
from prisma_node_wiring.node_parameters import declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import stream_publisher

from .node_config import SyntheticGloveConfig
from .ros_conversions import hand_pose_to_msg
from .synthetic_glove_core import OperatorScript, SyntheticGlove

NS = 1_000_000_000


class SyntheticGloveNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("synthetic_glove", **kwargs)
        # fails here, at start, with the parameter's name and value when one is invalid
        c = self.config = declare_config(self, SyntheticGloveConfig)
        self.types = robot_types(get_message, get_action)
        script = OperatorScript(c.rest_s, c.close_s, c.hold_s, c.open_s, c.sweep_s, c.closure)
        self.glove = SyntheticGlove(script, noise_rad=c.noise_rad, seed=c.seed, loop=c.loop)
        self._publisher = stream_publisher(self, JointState, "glove/joint_states")
        self._start_ns: int | None = None
        self._timer = self.create_timer(1.0 / c.rate_hz, self._on_timer)
        self.get_logger().info(f"glove/joint_states at {c.rate_hz:g} Hz: the operator's {script.duration_s:g} s "
                               f"script{' in a loop' if c.loop else ' once'}")

    def _on_timer(self) -> None:
        now_ns = self.get_clock().now().nanoseconds
        if self._start_ns is None:
            self._start_ns = now_ns
        angles = self.glove.sample((now_ns - self._start_ns) / NS)
        if angles is None:
            self.get_logger().info("the operator's script is over: glove/joint_states stops")
            self._timer.cancel()
            return
        self._publisher.publish(hand_pose_to_msg(self.types, now_ns, angles, self.config.frame_id))


def main(args=None) -> None:
    run_node(SyntheticGloveNode, "synthetic_glove", (ParameterError,), args)


if __name__ == "__main__":
    main()
