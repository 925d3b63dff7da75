"""glove_perception: subscribes /stag/frame and publishes /stag/object (N-frame classifier over
buffered contact frames), /stag/hand_pose and /stag/weight, from the model bundles in config.
Shorted frames are ignored.

    ros2 run stag_glove glove_perception --ros-args --params-file config/glove_perception.yaml

release_frames can be changed at run time; the other parameters are read-only (node_config.py says why).
"""
from __future__ import annotations

import functools

from prisma_msgs.msg import GloveFrame, ObjectEstimate, WeightEstimate
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_message

from prisma_common.parameters import ParameterError
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node

from .bundle import BundleError, load_bundle
from .glove_perception_core import GlovePerception, PerceptionConfig, limit_threads
from .node_config import GlovePerceptionConfig
from .ros_conversions import estimate_to_msg, glove_frame_from_msg, weight_to_msg


class GlovePerceptionNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("glove_perception", **kwargs)
        self.types = functools.cache(get_message)  # rosidl imports the class on every call
        # fails here, at start, with the parameter's name and value when one is invalid
        cfg = self.config = declare_config(self, GlovePerceptionConfig)
        limit_threads(cfg.threads)  # torch and BLAS threads, before any inference
        bundles = {}
        for kind in ("object", "pose", "weight"):
            path = getattr(cfg, f"{kind}_bundle")
            try:
                bundles[kind] = load_bundle(path, kind) if path else None
            except BundleError as exc:  # missing or mismatched model: fail at start with the path
                raise ParameterError(f"{kind}_bundle", path, str(exc)) from None
        self.perception = GlovePerception(bundles["object"], bundles["pose"], bundles["weight"],
                                          PerceptionConfig(cfg.selection, cfg.buffer_size, cfg.release_frames,
                                                           cfg.kmeans_restarts, cfg.seed))
        self._object_pub = self.create_publisher(ObjectEstimate, "stag/object", 10)
        self._pose_pub = self.create_publisher(ObjectEstimate, "stag/hand_pose", 10)
        self._weight_pub = self.create_publisher(WeightEstimate, "stag/weight", 10)
        self._frame_sub = self.create_subscription(GloveFrame, "stag/frame", self._on_frame, 10)
        loaded = ", ".join(f"{k}: {b.path} ({b.n_frames if k == 'object' else 1} frame)"
                           for k, b in bundles.items() if b is not None) or "no models"
        self.get_logger().info(f"{loaded}; selection {cfg.selection}")
        accept_live_changes(self, GlovePerceptionConfig, self._reconfigure)

    def _reconfigure(self, config: GlovePerceptionConfig) -> None:
        self.config = config
        self.perception.reconfigure(config.release_frames)

    def _on_frame(self, msg: GloveFrame) -> None:
        frame = glove_frame_from_msg(msg)
        out = self.perception.update(frame)
        stamp, frame_id = frame.stamp_ns, self.config.frame_id
        if out.object is not None:
            self._object_pub.publish(estimate_to_msg(self.types, out.object, stamp, frame_id))
        if out.pose is not None:
            self._pose_pub.publish(estimate_to_msg(self.types, out.pose, stamp, frame_id))
        if out.weight is not None:
            self._weight_pub.publish(weight_to_msg(self.types, out.weight, stamp, frame_id))


def main(args=None) -> None:
    run_node(GlovePerceptionNode, "glove_perception", (BundleError, ParameterError), args)


if __name__ == "__main__":
    main()
