"""policy: the behaviour-cloning policy drives the hand through the manipulation node, in an
operator's place (policy_core.py decides, this node carries it out).

    ros2 run prisma_policy policy --ros-args --params-file config/policy.yaml \
        -p model_path:=test/integration/data/policy_pinch_ball.pt

Subscribes what the policy observes, the topics a dataset export reads (prisma_dataset.recorded_topics):
prisma/hand/taxels and prisma/hand/wrench (or the per-finger prisma/<finger>/taxels and /wrench until
the per-hand ones speak) and joint_states. Every 1 / rate_hz (0: the model's dataset fps) it acts on
the newest samples when all are fresh (max_input_age) and publishes prisma/teleop/motor_targets
(sensor_msgs/JointState, rad, stamped now) and keeps a prisma/teleoperate goal running with the
teleop node's default fields, so the manipulation node's touch limit and stale-input stop apply to
it as to a glove. A missing or stale input publishes nothing, logged once when the policy stops
acting (and once when it acts again; each at most every 5 s). Without a model (model_path "")
nothing is published and no publisher is made. Letting go is the operator's: stop the node, and
the goal ends input_stale. /diagnostics every second: status `policy` (ERROR without a model, WARN
while it publishes nothing and why, OK while it acts; targets published, goals sent, the last goal's
end).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from prisma_msgs.action import Teleoperate
from prisma_msgs.msg import HandTaxels, HandWrench, TaxelArray
from rclpy.action import ActionClient
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_action, get_message
from sensor_msgs.msg import JointState

from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.hand import FINGERS
from prisma_common.messages import robot_types
from prisma_common.parameters import ParameterError
from prisma_common.topics import TELEOPERATE_ACTION, TELEOP_TARGETS, relative
from prisma_node_wiring.node_parameters import declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import FingerAndHandInput, stream_publisher, stream_subscription

from .bc_policy import Policy, PolicyError, load
from .node_config import PolicyConfig
from .policy_core import Act, PolicyCore
from .ros_conversions import (
    hand_taxels_samples,
    hand_wrench_samples,
    joint_sample_from_msg,
    motor_targets_to_msg,
    policy_goal_to_msg,
    taxel_frame_from_msg,
    wrench_from_msg,
)

TARGETS_TOPIC = relative(TELEOP_TARGETS)
DIAGNOSTICS_PERIOD_S = 1.0  # as the other nodes: robot monitors show a status as stale after a few seconds


class PolicyNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("policy", **kwargs)
        self.config = config = declare_config(self, PolicyConfig)
        self.types = robot_types(get_message, get_action)
        policy: Policy | None = load(Path(config.model_path).expanduser()) if config.model_path else None
        self.core = PolicyCore(policy, config.max_input_age,
                               "no model: give model_path (a file prisma-policy train --out wrote)")
        self._handle: Any = None
        self._taxels = FingerAndHandInput(self, TaxelArray, HandTaxels, "taxels", FINGERS, hand_taxels_samples,
                                          self._on_taxels)
        self._wrenches = FingerAndHandInput(self, WrenchStamped, HandWrench, "wrench", FINGERS,
                                            hand_wrench_samples, self._on_wrench)
        stream_subscription(self, JointState, "joint_states", self._on_joints)
        self._targets = stream_publisher(self, JointState, TARGETS_TOPIC) if policy is not None else None
        self._client = ActionClient(self, Teleoperate, TELEOPERATE_ACTION) if policy is not None else None
        period = self.core.period_s(config.rate_hz)
        self.create_timer(period, self._on_tick)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._on_status)
        if policy is None:
            self.get_logger().warning(self.core.no_model_reason)
        else:
            self.get_logger().info(f"policy {config.model_path} ({policy.episodes} episodes at {policy.fps} fps) "
                                   f"acting at {1.0 / period:g} Hz -> {self.resolve_topic_name(TARGETS_TOPIC)}")

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    # ---- input ---------------------------------------------------------------------------------
    def _on_taxels(self, finger: str, msg: TaxelArray) -> None:
        frame = taxel_frame_from_msg(msg)
        self.core.on_taxels(finger, frame.stamp_ns, frame.voltages)

    def _on_wrench(self, finger: str, msg: WrenchStamped) -> None:
        sample = wrench_from_msg(msg)
        self.core.on_wrench(finger, sample.stamp_ns, sample.wrench)

    def _on_joints(self, msg: JointState) -> None:
        sample = joint_sample_from_msg(msg)
        self.core.on_joints(sample.stamp_ns, sample.positions, sample.velocities)

    # ---- carrying out the core's decisions ------------------------------------------------------
    def _on_tick(self) -> None:
        was_holding = self.core.holding is not None
        decision = self.core.tick(self._now_ns())
        if not isinstance(decision, Act):
            if not was_holding:  # once as it stops acting (at most every 5 s: a loaded machine flickers)
                self.get_logger().warning(f"publishing nothing: {decision.reason}", throttle_duration_sec=5.0)
            return
        if was_holding:
            self.get_logger().info("inputs fresh: the policy acts", throttle_duration_sec=5.0)
        assert self._targets is not None and self._client is not None
        self._targets.publish(motor_targets_to_msg(self.types, decision.stamp_ns, decision.targets))
        if decision.send_goal:
            self._send()

    def _send(self) -> None:
        assert self._client is not None
        if not self._client.server_is_ready():
            self.get_logger().warning(f"no action server {self.resolve_topic_name(TELEOPERATE_ACTION)} (is the "
                                      "manipulation node running?); trying again", throttle_duration_sec=5.0)
            self.core.on_goal_ended(self._now_ns(), "no action server")
            return
        self.get_logger().info("sending the Teleoperate goal")
        self._client.send_goal_async(policy_goal_to_msg(self.types)).add_done_callback(self._on_accepted)

    def _on_accepted(self, future) -> None:
        handle = future.result()
        if not handle.accepted:  # the manipulation node accepts every goal and aborts those it refuses
            self.core.on_goal_ended(self._now_ns(), "not accepted")
            return
        self._handle = handle
        handle.get_result_async().add_done_callback(self._on_result)

    def _on_result(self, future) -> None:
        wrapped = future.result()
        reason = ("canceled" if wrapped.status == GoalStatus.STATUS_CANCELED
                  else str(getattr(wrapped.result, "reason", "")) or "ended")
        self._handle = None
        self.get_logger().info(f"Teleoperate goal ended: {reason}")
        self.core.on_goal_ended(self._now_ns(), reason)

    def _on_status(self) -> None:
        statuses = in_namespace([self.core.diagnostics()], self.get_namespace())
        self._diag_pub.publish(diagnostics_to_msg(self.types, self._now_ns(), statuses))

    def destroy_node(self) -> None:
        # Node.destroy_node would leave the action client (and so the node) in the graph
        client = getattr(self, "_client", None)
        if client is not None:
            client.destroy()
        super().destroy_node()


def main(args=None) -> None:
    run_node(PolicyNode, "policy", (ParameterError, PolicyError), args)


if __name__ == "__main__":
    main()
