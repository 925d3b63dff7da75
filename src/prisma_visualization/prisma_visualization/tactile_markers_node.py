"""tactile_markers: the fingertip pads drawn in RViz. Publishes prisma/tactile_markers
(visualization_msgs/MarkerArray) at the display rate: per pad the nine taxels coloured by Algorithm
1's decision in the ContactState (red: v_i >= v_t, blue: below), the contact point and the
estimated normal force as an arrow (tactile_markers_core.py).

    ros2 run prisma_visualization tactile_markers --ros-args --params-file config/tactile_markers.yaml

Reads prisma/hand/contact and prisma/hand/wrench (or the per-finger forms until those speak), but
only while someone subscribes to the markers: with no display open the node holds no subscription,
so the manipulation node builds no ContactState for it and nothing here runs. While watched it takes
them at the display rate, not the sensors' (display_gate.py): each display tick publishes what the
last tick took and lets each input's newest message in once more; the samples between are dropped
unread, and a drawing is at most one display period (33 ms at 30 Hz) older than its input.
"""
from __future__ import annotations

from geometry_msgs.msg import WrenchStamped
from prisma_msgs.msg import ContactState, HandContact, HandWrench
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_action, get_message
from visualization_msgs.msg import MarkerArray

from prisma_common.messages import robot_types
from prisma_common.parameters import ParameterError
from prisma_force_estimator.ros_conversions import hand_wrench_samples, wrench_from_msg
from prisma_manipulation.ros_conversions import contact_state_from_msg, hand_contact_samples
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import FingerAndHandInput

from .display_gate import DISPLAY_DEPTH, DisplayGate
from .node_config import TactileMarkersConfig
from .ros_conversions import tactile_markers_to_msg
from .tactile_markers_core import TactileMarkers


class TactileMarkersNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("tactile_markers", **kwargs)
        # fails here, at start, with the parameter's name and value when one is invalid
        self.config = declare_config(self, TactileMarkersConfig)
        self.types = robot_types(get_message, get_action)
        self.markers = TactileMarkers(self.config)
        accept_live_changes(self, TactileMarkersConfig, self._reconfigure)
        self._inputs: list[FingerAndHandInput] = []
        self._gate = DisplayGate()  # the inputs run once per display tick
        self._display_timer = None
        self._publisher = self.create_publisher(
            MarkerArray, "prisma/tactile_markers", 10,
            event_callbacks=PublisherEventCallbacks(matched=lambda _: self._follow_subscribers()))
        self.get_logger().info(f"{1.0 / self.config.rate_hz * 1e3:.0f} ms display period, "
                               f"fingers {', '.join(self.config.fingers)}; idle until a display subscribes")

    def _reconfigure(self, config: TactileMarkersConfig) -> None:
        """A live change (display rate, cell height, arrow scale, contact force): from the next drawing."""
        rate_changed = config.rate_hz != self.config.rate_hz
        self.config = self.markers.config = config
        if rate_changed and self._display_timer is not None:
            self.destroy_timer(self._display_timer)
            self._display_timer = self.create_timer(1.0 / config.rate_hz, self._on_display)

    def _follow_subscribers(self) -> None:
        """Take the contact and wrench streams while the markers have a subscriber, and only then."""
        watched = self._publisher.get_subscription_count() > 0
        if watched and not self._inputs:
            fingers = self.config.fingers
            self._inputs = [
                FingerAndHandInput(self, ContactState, HandContact, "contact", fingers, hand_contact_samples,
                                   self._on_contact, depth=DISPLAY_DEPTH, callback_group=self._gate),
                FingerAndHandInput(self, WrenchStamped, HandWrench, "wrench", fingers, hand_wrench_samples,
                                   self._on_wrench, depth=DISPLAY_DEPTH, callback_group=self._gate)]
            self._display_timer = self.create_timer(1.0 / self.config.rate_hz, self._on_display)
        elif not watched and self._inputs:
            for stream in self._inputs:
                stream.close()
            self._inputs = []
            self.destroy_timer(self._display_timer)
            self._display_timer = None

    def _on_contact(self, finger: str, msg: ContactState) -> None:
        self.markers.on_contact(contact_state_from_msg(msg), msg.header.frame_id)

    def _on_wrench(self, finger: str, msg: WrenchStamped) -> None:
        self.markers.on_wrench(finger, wrench_from_msg(msg))

    def _on_display(self) -> None:
        drawings = self.markers.take_drawings()
        if drawings:
            self._publisher.publish(tactile_markers_to_msg(self.types, drawings, self.config))
        self._gate.open()


def main(args=None) -> None:
    run_node(TactileMarkersNode, "tactile_markers", (ParameterError,), args)


if __name__ == "__main__":
    main()
