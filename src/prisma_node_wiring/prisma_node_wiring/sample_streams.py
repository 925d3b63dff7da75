"""Publishers and subscriptions of the per-finger sample streams (100-350 messages/s each).

rclpy gives every publisher and subscription two QoS-event handlers (incompatible QoS, incompatible
type) whose only job is a warning when a mismatched peer appears. They are Python waitables the
executor walks before and after every wait, on every message: in the manipulation node (10 stream
subscriptions, 5 stream publishers) they were the largest single cost of the 100 Hz graph
(docs/performance.md). The streams are created without them; `ros2 topic info -v <topic>` shows a
QoS mismatch, and every other endpoint (diagnostics, services, actions) keeps rclpy's warnings.

`FingerAndHandInput` is the input side of a node that takes all five fingers of a stream: the
per-finger topics until the per-hand one speaks, then that one only (hand_input.py). On the output
side the per-finger topics are published only while someone subscribes (`publish_if_subscribed`):
on the launched graph nobody does until rqt_plot or a recorder starts.
"""
from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from typing import Any

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

from prisma_common.hand_input import HandInput
from prisma_common.messages import ns_from_stamp

DEPTH = 10  # keep-last depth of every stream: a slow subscriber loses the oldest samples, never blocks


def stream_publisher(node: Node, msg_type: Any, topic: str) -> Publisher:
    return node.create_publisher(msg_type, topic, DEPTH,
                                 event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))


def stream_subscription(node: Node, msg_type: Any, topic: str, callback: Callable[[Any], None],
                        depth: int = DEPTH, **kwargs: Any) -> Subscription:
    """depth: a display that takes only the newest sample at its own rate keeps 1."""
    return node.create_subscription(msg_type, topic, callback, depth,
                                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
                                    **kwargs)


def publish_if_subscribed(publisher: Publisher, msg: Any) -> None:
    """Publish unless no subscription is matched: rclpy converts and serialises a message even for
    nobody, which for five per-finger streams at 100-350 Hz is a large share of a node's CPU. A
    subscriber that appears gets the next message, as it would anyway (the streams keep no history
    for late joiners)."""
    if publisher.get_subscription_count():
        publisher.publish(msg)


class FingerAndHandInput:
    """Subscriptions to prisma/<finger>/<kind> for each finger and to prisma/hand/<kind>.

    `on_sample(finger, sample)` gets every sample once, as a per-finger message (TaxelArray,
    WrenchStamped); `split(hand_msg)` yields the (finger, sample) pairs of a per-hand message.
    `on_message_end()`, if given, runs after each received message's samples. From the first
    per-hand message on, the per-finger subscriptions are closed.
    """

    def __init__(self, node: Node, finger_type: Any, hand_type: Any, kind: str, fingers: Iterable[str],
                 split: Callable[[Any], Iterable[tuple[str, Any]]], on_sample: Callable[[str, Any], None],
                 on_message_end: Callable[[], None] | None = None, **kwargs: Any) -> None:
        self.state = HandInput()
        self.hand_topic = f"prisma/hand/{kind}"
        self._node = node
        self._fingers = frozenset(fingers)
        self._split = split
        self._on_sample = on_sample
        self._on_message_end = on_message_end or (lambda: None)
        self._finger_subs = [
            stream_subscription(node, finger_type, f"prisma/{f}/{kind}", functools.partial(self._on_finger, f),
                                **kwargs)
            for f in sorted(self._fingers)]
        self._hand_sub: Subscription | None = stream_subscription(node, hand_type, self.hand_topic,
                                                                  self._on_hand, **kwargs)

    def close(self) -> None:
        """Destroy every subscription (a node that reads the streams only while it is watched)."""
        for sub in self._finger_subs + ([self._hand_sub] if self._hand_sub is not None else []):
            self._node.destroy_subscription(sub)
        self._finger_subs, self._hand_sub = [], None

    def _on_finger(self, finger: str, msg: Any) -> None:
        if self.state.take_finger(finger, ns_from_stamp(msg.header.stamp)):
            self._on_sample(finger, msg)
            self._on_message_end()

    def _on_hand(self, msg: Any) -> None:
        first = not self.state.switched
        for finger, sample in self._split(msg):
            if finger in self._fingers and self.state.take_hand(finger, ns_from_stamp(sample.header.stamp)):
                self._on_sample(finger, sample)
        if first and self.state.switched:
            for sub in self._finger_subs:
                self._node.destroy_subscription(sub)
            self._finger_subs = []
            self._node.get_logger().info(f"taking {self._node.resolve_topic_name(self.hand_topic)}; "
                                         "per-finger subscriptions closed")
        self._on_message_end()
