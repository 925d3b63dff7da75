"""force_estimator: /prisma/<finger>/taxels -> /prisma/<finger>/wrench with a neural network.

Input: /prisma/hand/taxels once the tactile driver publishes it, the per-finger topics until then
(a bag of only those replays as well). Output: every wrench on its finger's topic and the wrenches
of each scan together on /prisma/hand/wrench. Each WrenchStamped carries its input's header stamp.
Samples with non-finite voltages get no wrench; they are counted per finger on /diagnostics (as are
received and estimated samples). The ~/bias service (std_srvs/Trigger) zeroes each finger's no-load
wrench: the mean of its last `bias_samples` estimates is subtracted from then on (bias.py), refused
with the reason while a pad is in contact; the offsets are in /diagnostics. With `hand_config` (the
hand's directory, prisma_common.hand_config) the bundles and the bias saved there are loaded at start
and ~/bias saves the offsets it took there (hand_directory.py decides what applies).
A missing or mismatched model bundle stops the node at start with the path and the problem.

    ros2 run prisma_force_estimator force_estimator --ros-args --params-file config/force_estimator.yaml
"""
from __future__ import annotations

import functools

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from prisma_msgs.msg import HandTaxels, HandWrench, TaxelArray
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_message
from std_srvs.srv import Trigger

from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.hand_config import HandConfigError
from prisma_node_wiring.node_parameters import declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import FingerAndHandInput, publish_if_subscribed, stream_publisher
from prisma_tactile_driver.ros_conversions import hand_taxels_samples, taxel_frame_from_msg

from .bias import WrenchBias
from .bundle import BundleError
from .diagnostics import pipeline_diagnostics
from .force_estimator_core import TaxelSample, WrenchPipeline, build_estimators
from .hand_directory import open_hand_config, plan_start, save_bias
from .node_config import ForceEstimatorConfig, ParameterError
from .ros_conversions import hand_wrench_to_msg, wrench_to_msg


class ForceEstimatorNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("force_estimator", **kwargs)
        self.types = functools.cache(get_message)  # rosidl imports the class on every call
        # fails here, at start, naming the parameter and value when one is invalid (all read-only)
        cfg = self.config = declare_config(self, ForceEstimatorConfig)
        # HandConfigError (file + bad value) propagates like BundleError
        self.hand = open_hand_config(cfg.hand_config)
        plan = plan_start(cfg.fingers, cfg.finger_bundles, cfg.model_bundle, self.hand)
        self.bundle_paths = plan.bundles
        # BundleError (path + mismatch) propagates: the node does not start without its network
        estimators = build_estimators(self.bundle_paths, threads=cfg.torch_threads, precision=cfg.network_precision)
        bias = WrenchBias(cfg.fingers, cfg.bias_samples, cfg.bias_contact_voltage)
        bias.restore(plan.offsets)
        self.pipeline = WrenchPipeline(estimators, cfg.frame_id_format, int(round(cfg.batch_window * 1e9)), bias=bias)

        self._wrench_pubs = {f: stream_publisher(self, WrenchStamped, f"prisma/{f}/wrench") for f in cfg.fingers}
        self._hand_pub = stream_publisher(self, HandWrench, "prisma/hand/wrench")
        self._results: list = []  # (finger, WrenchSample) of the message being handled
        self._taxels = FingerAndHandInput(self, TaxelArray, HandTaxels, "taxels", cfg.fingers,
                                          hand_taxels_samples, self._on_taxels, self._publish)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._diag_timer = self.create_timer(cfg.diagnostics_period, self._on_diagnostics)
        self._bias_service = self.create_service(Trigger, "~/bias", self._on_bias)
        kinds = sorted({f"{e.model_kind} ({self.bundle_paths[f]})" for f, e in estimators.items()})
        precisions = sorted({f"{e.model_kind} {e.precision}" for e in estimators.values()})
        self.get_logger().info(f"fingers {', '.join(cfg.fingers)}; model {'; '.join(kinds)}; "
                               f"network {', '.join(precisions)}")
        if self.hand is not None:
            self.get_logger().info(f"hand directory {self.hand.root}: {'; '.join(plan.notes) or 'nothing saved yet'}")

    def _on_taxels(self, finger: str, msg: TaxelArray) -> None:
        frame = taxel_frame_from_msg(msg)
        self._results += self.pipeline.add(TaxelSample(finger, frame.stamp_ns, frame.voltages, msg.header.frame_id))

    def _publish(self) -> None:
        """The wrenches of the scans the last message completed: per finger, then per hand."""
        if not self._results:
            return
        fingers, msgs = [], []
        for finger, sample in self._results:
            msg = wrench_to_msg(self.types, sample)
            publish_if_subscribed(self._wrench_pubs[finger], msg)
            fingers.append(finger)
            msgs.append(msg)
        self._results = []
        publish_if_subscribed(self._hand_pub, hand_wrench_to_msg(self.types, fingers, msgs))

    def _on_bias(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        assert self.pipeline.bias is not None  # made with one above
        result = save_bias(self.hand, self.pipeline.bias, self.pipeline.bias.take(), self.bundle_paths)
        response.success, response.message = result.success, result.message
        # rclpy fixes a call site's severity at its first call: one call site per severity
        if result.success and not result.warning:
            self.get_logger().info(result.message)
        else:
            self.get_logger().warning(f"bias {result.message}")
        return response

    def _on_diagnostics(self) -> None:
        stamp_ns = self.get_clock().now().nanoseconds
        statuses = in_namespace(pipeline_diagnostics(self.pipeline, self.get_name(), self.bundle_paths),
                                self.get_namespace())  # which hand says it
        self._diag_pub.publish(diagnostics_to_msg(self.types, stamp_ns, statuses))


def main(args=None) -> None:
    run_node(ForceEstimatorNode, "force_estimator", (BundleError, ParameterError, HandConfigError), args)


if __name__ == "__main__":
    main()
