"""tactile_driver: publishes /prisma/<finger>/taxels from the fingertip hub (serial, I2C or sim),
the same samples once per poll on /prisma/hand/taxels (for the nodes that take all five fingers),
and /diagnostics at 1 Hz with the link counters. With the simulated hand (contact_source
hand_world), ~/replace_object (std_srvs/Trigger) puts the object back between the open fingers for
the next trial (on the emulated hand, hand.launch.py hardware:=emulated, the same service asks the
emulator's world through its control socket, `emulator_control`), and prisma/sim/object
(visualization_msgs/Marker, 10 Hz while someone subscribes) draws the object where the simulated
world has it, in object_frame_id (the hand's base), placed from the description on
robot_description (none for sim_object none). Zeroing the fingertip forces is the force
estimator's ~/bias: the taxel voltages stay raw (Algorithm 1 needs them).

    ros2 run prisma_tactile_driver tactile_driver --ros-args --params-file config/tactile_driver.yaml

stale_timeout can be changed at run time; the other parameters are read-only (node_config.py says why).
"""
from __future__ import annotations

import functools
import threading

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from prisma_msgs.msg import HandTaxels, TaxelArray
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosidl_runtime_py.utilities import get_message
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker

from prisma_common.control_socket import REPLACE_OBJECT, reply_text, send
from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.kinematics import DescriptionError, RobotModel
from prisma_common.messages import ns_from_stamp
from prisma_common.os_errors import describe_os_error
from prisma_common.parameters import ParameterError
from prisma_hand_sim.contact_source import HandWorldContactSource
from prisma_hand_sim.hand_world import HandWorld
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import publish_if_subscribed, stream_publisher, stream_subscription

from .node_config import TactileDriverConfig, make_backend
from .ros_conversions import hand_taxels_to_msg, object_marker_to_msg, taxel_frame_to_msg
from .tactile_driver_core import TactileHub

OBJECT_MARKER_HZ = 10.0  # a display's rate: the object moves with the grasp, at most a few mm/s
EMULATOR_REPLY_TIMEOUT_S = 1.0  # the emulator answers a request in milliseconds
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TactileDriverNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("tactile_driver", **kwargs)
        self.types = functools.cache(get_message)  # rosidl imports the class on every call
        # fails here, at start, with the parameter's name and value when one is invalid
        cfg = self.config = declare_config(self, TactileDriverConfig)

        source = None
        self._object_anchor: np.ndarray | None = None  # where the object was presented, once the description came
        if cfg.backend == "sim" and cfg.contact_source == "hand_world":
            source = HandWorldContactSource(HandWorld(obj=cfg.sim_object))
            self._joint_sub = stream_subscription(self, JointState, "joint_states", self._on_joints)
            self._replace_service = self.create_service(Trigger, "~/replace_object", self._on_replace_object)
            if source.world.object_pose() is not None:
                self._object_pub = self.create_publisher(Marker, "prisma/sim/object", 10)
                self._description_sub = self.create_subscription(String, "robot_description",
                                                                 self._on_description, LATCHED)
                self._object_timer = self.create_timer(1.0 / OBJECT_MARKER_HZ, self._on_object_marker)
        elif cfg.emulator_control:  # the emulated hand: its world, and its object, are the emulator's
            self._replace_service = self.create_service(Trigger, "~/replace_object", self._on_replace_emulated)
        self._source = source
        self.hub = TactileHub(make_backend(cfg, source), cfg.fingers, vref=cfg.vref,
                              stale_timeout_ns=int(cfg.stale_timeout * 1e9),
                              name=self.get_name(), hardware_id=self._hardware_id())

        self._taxel_pubs = {f: stream_publisher(self, TaxelArray, f"prisma/{f}/taxels") for f in cfg.fingers}
        self._hand_pub = stream_publisher(self, HandTaxels, "prisma/hand/taxels")
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._stop_reading = threading.Event()
        self._reader: threading.Thread | None = None
        if cfg.backend == "serial":
            # the hub's bytes read as they come, on a thread of its own: a timer draining the port at
            # 500 Hz woke the executor 500 times a second for a hub that sends 100 scans (43% of a core
            # in the emulated graph, most of it the executor's wake-ups)
            self._reader = threading.Thread(target=self._read_serial, name="hub_reader", daemon=True)
            self._reader.start()
            reading = f"reading as the bytes come (looking again every {1e3 / cfg.serial_poll_hz:g} ms when none do)"
        else:
            self._poll_timer = self.create_timer(1.0 / cfg.rate_hz, self._on_poll)
            reading = f"polling at {cfg.rate_hz:g} Hz"
        self._diag_timer = self.create_timer(cfg.diagnostics_period, self._on_diagnostics)
        self.get_logger().info(
            f"{cfg.backend} backend ({self._hardware_id()}), fingers {', '.join(cfg.fingers)}, {reading}")
        accept_live_changes(self, TactileDriverConfig, self._reconfigure)

    def _reconfigure(self, config: TactileDriverConfig) -> None:
        self.config = config
        self.hub.stale_timeout_ns = int(config.stale_timeout * 1e9)

    def _hardware_id(self) -> str:
        cfg = self.config
        if cfg.backend == "serial":
            return f"{cfg.port}@{cfg.baud}"
        if cfg.backend == "i2c":
            bus = f"i2c-socket:{cfg.i2c_socket}" if cfg.i2c_socket else f"i2c-{cfg.i2c_bus}"
            return f"{bus}/0x{cfg.mux_address:02x}"
        if cfg.contact_source == "hand_world":
            return f"sim/hand_world/{cfg.sim_object}"
        return f"sim/{cfg.contact_source}"

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _read_serial(self) -> None:
        """The serial backend's reads wait up to 1/serial_poll_hz for a byte, and as long on a port
        that is not open (lost, or not there yet; reopened as its back-off allows)."""
        while not self._stop_reading.is_set():
            try:
                self._on_poll()
            except Exception:
                if self.context.ok():
                    raise
                return  # a stop request shut the context down before destroy_node stops this thread

    def _on_poll(self) -> None:
        samples = [taxel_frame_to_msg(self.types, frame, self.config.frame_id(frame.finger))
                   for frame in self.hub.poll(self._now_ns())]
        for msg in samples:
            publish_if_subscribed(self._taxel_pubs[msg.finger], msg)
        if samples:
            publish_if_subscribed(self._hand_pub, hand_taxels_to_msg(self.types, samples))
        for error in self.hub.take_errors():  # each new link error once, with the port and OS reason
            self.get_logger().error(error)

    def _on_diagnostics(self) -> None:
        stamp_ns = self._now_ns()
        statuses = in_namespace(self.hub.diagnostics(stamp_ns), self.get_namespace())  # which hand says it
        self._diag_pub.publish(diagnostics_to_msg(self.types, stamp_ns, statuses))

    def _on_joints(self, msg: JointState) -> None:
        assert self._source is not None  # subscribed only with the hand_world contact source
        self._source.update_joints(list(msg.name), [float(p) for p in msg.position],
                                   ns_from_stamp(msg.header.stamp))

    def _on_description(self, msg: String) -> None:
        """Where the object is presented: the thumb pad's pose at the object's thumb contact angle
        (the world's coordinates start there, hand_world.ObjectPose)."""
        assert self._source is not None
        obj = self._source.world.obj
        try:
            self._object_anchor = RobotModel.from_urdf(msg.data).link_pose(
                "prisma_thumb_pad", {"thumb_flexion": obj.thumb_contact_rad or 0.0, "thumb_rotation": 0.0})
        except DescriptionError as exc:
            self.get_logger().error(f"robot_description: {exc}; the object is not drawn until a readable one")

    def _on_object_marker(self) -> None:
        assert self._source is not None
        pose = self._source.world.object_pose()
        if self._object_anchor is not None and pose is not None:
            publish_if_subscribed(self._object_pub, object_marker_to_msg(
                self.types, self.config.object_frame_id, self._object_anchor, pose))

    def _on_replace_object(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        assert self._source is not None  # offered only with the hand_world contact source
        try:
            response.message = self._source.world.replace_object()
            response.success = True
        except ValueError as exc:
            response.message = str(exc)
        self.get_logger().info(f"replace_object: {response.message}")
        return response

    def _on_replace_emulated(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """The same service on the emulated hand, carried out by the emulator's world: its control
        socket's replace-object request, answered in a few ms (the wait is bounded: the executor
        serves the I2C poll timer too)."""
        path = self.config.emulator_control
        try:
            response.success, response.message = reply_text(
                send(path, REPLACE_OBJECT, timeout_s=EMULATOR_REPLY_TIMEOUT_S))
        except ConnectionError as exc:
            response.message = (f"{exc}: is the emulator this hand was launched with running? "
                                f"(emulator_control {path})")
        except TimeoutError:
            response.message = f"the emulator at {path} did not answer within {EMULATOR_REPLY_TIMEOUT_S:g} s"
        except OSError as exc:
            response.message = f"the emulator at {path} cannot be asked: {describe_os_error(exc)}"
        self.get_logger().info(f"replace_object: {response.message}")
        return response

    def destroy_node(self) -> None:
        reader = getattr(self, "_reader", None)
        if reader is not None:
            self._stop_reading.set()
            reader.join(timeout=2.0)  # its read waits at most 1/serial_poll_hz
        hub = getattr(self, "hub", None)  # absent when the parameters were rejected at start
        if hub is not None:
            hub.close()
        super().destroy_node()


def main(args=None) -> None:
    run_node(TactileDriverNode, "tactile_driver", (ParameterError,), args)


if __name__ == "__main__":
    main()
