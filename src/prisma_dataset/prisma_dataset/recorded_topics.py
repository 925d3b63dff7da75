"""The topics an export reads, named once: record.launch.py records `record_topics(namespace)`,
`prisma-dataset topics` prints it, bag_export reads them. No import beyond prisma_common.topics,
so that a launch file takes the list without loading the export."""
from __future__ import annotations

from prisma_common import topics

TARGETS_TOPIC = topics.TELEOP_TARGETS  # the teleop node's prisma/teleop/motor_targets
GLOVE_TOPIC = "/glove/joint_states"  # a hand-pose glove's (the synthetic_glove node's) glove/joint_states
STAG_FRAME_TOPIC = "/stag/frame"  # the STAG glove's glove_driver: prisma_msgs/msg/GloveFrame
EPISODE_TOPIC = "/prisma/teleop/episode"  # the teleop node's episode markers (prisma_msgs/msg/EpisodeMarker)


def in_namespace(topic: str, namespace: str) -> str:
    """An absolute default topic as a node in `namespace` publishes it: /left + /joint_states."""
    ns = namespace.strip("/")
    return f"/{ns}{topic}" if ns else topic


def record_topics(namespace: str = "") -> list[str]:
    """Every topic an export reads, in the hand's `namespace` (the teleop node and the glove in it
    too, as teleop.launch.py starts them): the per-hand fingertip topics (one message per scan, the
    same samples as the 15 per-finger ones), the motor targets, both gloves' inputs (a topic nobody
    publishes is not recorded) and the episode markers."""
    return [in_namespace(t, namespace) for t in (
        topics.JOINT_STATES, topics.HAND_TAXELS, topics.HAND_WRENCH, topics.HAND_CONTACT, TARGETS_TOPIC,
        GLOVE_TOPIC, STAG_FRAME_TOPIC, EPISODE_TOPIC)]
