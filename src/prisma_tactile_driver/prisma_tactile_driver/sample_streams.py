"""Publishers and subscriptions of the per-finger sample streams (100-350 messages/s each).

rclpy gives every publisher and subscription two QoS-event handlers (incompatible QoS, incompatible
type) whose only job is a warning when a mismatched peer appears. They are Python waitables the
executor walks before and after every wait, on every message: in the manipulation node (10 stream
subscriptions, 5 stream publishers) they were the largest single cost of the 100 Hz graph
(docs/performance.md). The streams are created without them; `ros2 topic info -v <topic>` shows a
QoS mismatch, and every other endpoint (diagnostics, services, actions) keeps rclpy's warnings.
"""
from __future__ import annotations

from typing import Any, Callable

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

DEPTH = 10  # keep-last depth of every stream: a slow subscriber loses the oldest samples, never blocks


def stream_publisher(node: Node, msg_type: Any, topic: str) -> Publisher:
    return node.create_publisher(msg_type, topic, DEPTH,
                                 event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))


def stream_subscription(node: Node, msg_type: Any, topic: str, callback: Callable[[Any], None],
                        **kwargs: Any) -> Subscription:
    return node.create_subscription(msg_type, topic, callback, DEPTH,
                                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
                                    **kwargs)
