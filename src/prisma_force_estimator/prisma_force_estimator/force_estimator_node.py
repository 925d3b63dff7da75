"""force_estimator: /prisma/<finger>/taxels -> /prisma/<finger>/wrench with a neural network.

Each WrenchStamped carries its input's header stamp. Samples with non-finite voltages get no
wrench; they are counted per finger on /diagnostics (as are received and estimated samples).
A missing or mismatched model bundle stops the node at start with the path and the problem.

    ros2 run prisma_force_estimator force_estimator --ros-args --params-file config/force_estimator.yaml
"""
from __future__ import annotations

import functools
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from prisma_msgs.msg import TaxelArray
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_message

from prisma_tactile_driver.ros_conversions import diagnostics_to_msg, taxel_frame_from_msg
from prisma_tactile_driver.node_process import run_node
from prisma_tactile_driver.sample_streams import stream_publisher, stream_subscription

from .bundle import BundleError, resolve_bundle_path
from .diagnostics import pipeline_diagnostics
from .node_config import EstimatorConfig, ParameterError
from .pipeline import TaxelSample, WrenchPipeline, build_estimators
from .ros_conversions import wrench_to_msg


class ForceEstimatorNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("force_estimator", **kwargs)
        self.types = functools.cache(get_message)  # rosidl imports the class on every call
        defaults = EstimatorConfig().as_parameters()
        self.declare_parameters("", list(defaults.items()))
        # fails here, at start, naming the parameter and value when one is invalid
        self.config = EstimatorConfig.from_parameters(
            {name: self.get_parameter(name).value for name in defaults})
        cfg = self.config
        self.bundle_paths = {finger: str(resolve_bundle_path(path)) for finger, path in cfg.bundles().items()}
        # BundleError (path + mismatch) propagates: the node does not start without its network
        estimators = build_estimators(self.bundle_paths, threads=cfg.torch_threads)
        self.pipeline = WrenchPipeline(estimators, cfg.frame_id_format, int(round(cfg.batch_window * 1e9)))

        self._wrench_pubs = {f: stream_publisher(self, WrenchStamped, f"prisma/{f}/wrench") for f in cfg.fingers}
        self._taxel_subs = [
            stream_subscription(self, TaxelArray, f"prisma/{f}/taxels",
                                lambda msg, finger=f: self._on_taxels(finger, msg))
            for f in cfg.fingers
        ]
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._diag_timer = self.create_timer(cfg.diagnostics_period, self._on_diagnostics)
        kinds = sorted({f"{e.model_kind} ({self.bundle_paths[f]})" for f, e in estimators.items()})
        self.get_logger().info(f"fingers {', '.join(cfg.fingers)}; model {'; '.join(kinds)}")

    def _on_taxels(self, finger: str, msg: TaxelArray) -> None:
        frame = taxel_frame_from_msg(msg)
        self._publish(self.pipeline.add(TaxelSample(finger, frame.stamp_ns, frame.voltages, msg.header.frame_id)))

    def _publish(self, results) -> None:
        for finger, sample in results:
            self._wrench_pubs[finger].publish(wrench_to_msg(self.types, sample))

    def _on_diagnostics(self) -> None:
        stamp_ns = self.get_clock().now().nanoseconds
        statuses = pipeline_diagnostics(self.pipeline, self.get_name(), self.bundle_paths)
        self._diag_pub.publish(diagnostics_to_msg(self.types, stamp_ns, statuses))


def main(args=None) -> None:
    run_node(ForceEstimatorNode, "force_estimator", (BundleError, ParameterError), args)


if __name__ == "__main__":
    main()
