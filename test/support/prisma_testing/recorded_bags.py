"""Bags as rosbag2 records them where they differ from what the project's BagWriter writes.

`action_goals_bag`: docs/recording.md's action-topics bag (`ros2 bag record --include-hidden-topics
/prisma/<action>/_action/feedback /prisma/<action>/_action/status`). rosbag2 (Jazzy) finds no message
definition for action feedback types (`*_FeedbackMessage`) and stores their MCAP schema with encoding
'unknown' and no text, which rosbags cannot open. Written here with BagWriter, then the schemas'
encoding set to what rosbag2 wrote (the same number of bytes, so the MCAP's offsets hold).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from prisma_common.bag import BagWriter
from prisma_common.typestore import types

FEEDBACK_TOPIC = "/prisma/grasp/_action/feedback"
STATUS_TOPIC = "/prisma/grasp/_action/status"


def action_goals_bag(path: Path) -> Path:
    """A bag directory at `path` with one Grasp feedback and one goal status message, its schemas
    stored as rosbag2 stores the feedback's: encoding 'unknown'."""
    feedback = types("prisma_msgs/action/Grasp_FeedbackMessage")(
        goal_id=types("unique_identifier_msgs/msg/UUID")(uuid=np.zeros(16, np.uint8)),
        feedback=types("prisma_msgs/action/Grasp_Feedback")(phase="closing", finger_force=0.5, thumb_force=0.4))
    with BagWriter(path) as bag:
        bag.write(FEEDBACK_TOPIC, feedback, timestamp_ns=1_000)
        bag.write(STATUS_TOPIC, types("action_msgs/msg/GoalStatusArray")(status_list=[]), timestamp_ns=2_000)
    [mcap] = path.glob("*.mcap")
    recorded = mcap.read_bytes()
    assert recorded.count(b"ros2msg") >= 2, "BagWriter no longer writes ros2msg schemas: update this helper"
    mcap.write_bytes(recorded.replace(b"ros2msg", b"unknown"))
    return path
