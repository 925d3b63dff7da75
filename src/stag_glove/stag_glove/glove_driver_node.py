"""glove_driver: reads the STAG glove (serial readout board, synthetic glove, or a dataset file)
and publishes /stag/frame (GloveFrame), /stag/image (sensor_msgs/Image 32FC1, the pressures),
/stag/pressure_map (rgb8: the pressures drawn on the hand's layout, for rqt_image_view or RViz's
Image display; drawn only while someone watches), /diagnostics, and the ~/capture_empty_hand service.

    ros2 run stag_glove glove_driver --ros-args --params-file config/glove_driver.yaml

short_threshold, contact_margin and stale_timeout can be changed at run time; the other parameters
are read-only (node_config.py says why).
"""
from __future__ import annotations

import functools

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from prisma_msgs.msg import GloveFrame
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_message
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.parameters import ParameterError
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node

from .glove_driver_core import GloveDriver
from .layout import load_layout
from .node_config import GloveDriverConfig
from .pressure_map import PressureMap
from .processing import FrameProcessor
from .ros_conversions import glove_frame_to_msg, pressure_image_msg, pressure_map_to_msg
from .sim_backend import NO_LOAD_NOTE


class GloveDriverNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("glove_driver", **kwargs)
        self.types = functools.cache(get_message)  # rosidl imports the class on every call
        # fails here, at start, with the parameter's name and value when one is invalid
        cfg = self.config = declare_config(self, GloveDriverConfig)
        mask = regions = None
        if cfg.layout_file:
            try:
                layout = load_layout(cfg.layout_file)
            except (OSError, ValueError) as exc:
                raise ParameterError("layout_file", cfg.layout_file, str(exc)) from None
            mask, regions = layout.mask, layout.region_index
            if mask.shape != (cfg.rows, cfg.cols):
                raise ParameterError("layout_file", cfg.layout_file,
                                     f"layout is {mask.shape[0]}x{mask.shape[1]}, glove is {cfg.rows}x{cfg.cols}")
        self.pressure_map = PressureMap(mask if mask is not None else np.ones((cfg.rows, cfg.cols), bool), regions)
        processor = FrameProcessor(cfg.normalisation(), mask=mask)
        hardware_id = {"serial": f"{cfg.port}@{cfg.baudrate}", "sim": f"sim/seed{cfg.sim_seed}",
                       "replay": f"replay/{cfg.replay_file}"}[cfg.backend]
        # outside the try below: its ParameterError names the backend's own parameter (replay_file)
        backend = cfg.make_backend()
        try:
            self.driver = GloveDriver(backend, processor, cfg.empty_hand_frames, cfg.stale_timeout,
                                      cfg.calibration_file or None, self.get_name(), hardware_id)
        except ValueError as exc:
            backend.close()
            raise ParameterError("calibration_file", cfg.calibration_file, str(exc)) from None

        self._frame_pub = self.create_publisher(GloveFrame, "stag/frame", 10)
        self._image_pub = self.create_publisher(Image, "stag/image", 10)
        self._map_pub = self.create_publisher(Image, "stag/pressure_map", 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._capture_service = self.create_service(Trigger, "~/capture_empty_hand", self._on_capture)
        self._poll_timer = self.create_timer(1.0 / cfg.poll_rate_hz, self._on_poll)
        self._diag_timer = self.create_timer(cfg.diagnostics_period, self._on_diagnostics)
        self.get_logger().info(f"{cfg.backend} backend ({hardware_id}), polling at {cfg.poll_rate_hz:g} Hz")
        if cfg.backend == "sim":
            self.get_logger().info(NO_LOAD_NOTE)
        accept_live_changes(self, GloveDriverConfig, self._reconfigure)

    def _reconfigure(self, config: GloveDriverConfig) -> None:
        self.config = config
        self.driver.reconfigure(config.normalisation(), config.stale_timeout)

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_poll(self) -> None:
        for frame in self.driver.poll(self._now_ns()):
            self._frame_pub.publish(glove_frame_to_msg(self.types, frame, self.config.frame_id))
            self._image_pub.publish(pressure_image_msg(frame, self.types, self.config.frame_id))
            if self._map_pub.get_subscription_count():  # drawing costs ~2 ms a frame: only for a viewer
                image = self.pressure_map.draw(frame.pressure, frame.shorted)
                self._map_pub.publish(pressure_map_to_msg(self.types, image, frame.stamp_ns, self.config.frame_id))
        for error in self.driver.backend.take_errors():  # each new one once, with port and OS reason
            self.get_logger().error(error)

    def _on_diagnostics(self) -> None:
        stamp_ns = self._now_ns()
        statuses = in_namespace(self.driver.diagnostics(stamp_ns), self.get_namespace())  # which glove says it
        self._diag_pub.publish(diagnostics_to_msg(self.types, stamp_ns, statuses))

    def _on_capture(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        result = self.driver.capture_empty_hand()
        response.success = result.success
        response.message = result.message
        # rclpy fixes a call site's severity at its first call: one call site per severity
        if result.success:
            self.get_logger().info(result.message)
        else:
            self.get_logger().warning(result.message)
        return response

    def destroy_node(self) -> None:
        driver = getattr(self, "driver", None)  # absent when the parameters were rejected at start
        if driver is not None:
            driver.close()
        super().destroy_node()


def main(args=None) -> None:
    run_node(GloveDriverNode, "glove_driver", (ParameterError,), args)


if __name__ == "__main__":
    main()
