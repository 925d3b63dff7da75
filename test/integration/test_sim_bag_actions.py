"""Action topics in bags: `<action>/_action/feedback` (prisma_msgs/action/<Action>_FeedbackMessage)
and `<action>/_action/status` (action_msgs/msg/GoalStatusArray), written with BagWriter and read
back with rosbags in both storages. rosbags cannot generate the definition of action-derived types
itself; `typestore.message_definition` writes their nested types as plain `pkg/Name` messages."""
from __future__ import annotations

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from prisma_common.bag import BagWriter, read_bag
from prisma_common.typestore import get_typestore, message_definition, types


def feedback(phase: str, force: float, goal: int):
    uuid = types("unique_identifier_msgs/msg/UUID")(uuid=np.full(16, goal, dtype=np.uint8))
    inner = types("prisma_msgs/action/Grasp_Feedback")(phase=phase, finger_force=force, thumb_force=2 * force)
    return types("prisma_msgs/action/Grasp_FeedbackMessage")(goal_id=uuid, feedback=inner)


def status(goal: int, code: int):
    info = types("action_msgs/msg/GoalInfo")(
        goal_id=types("unique_identifier_msgs/msg/UUID")(uuid=np.full(16, goal, dtype=np.uint8)),
        stamp=types("builtin_interfaces/msg/Time")(sec=1, nanosec=0))
    return types("action_msgs/msg/GoalStatusArray")(status_list=[types("action_msgs/msg/GoalStatus")(goal_info=info,
                                                                                                 status=code)])


def test_definition_of_an_action_feedback_type_names_nested_types_as_messages():
    text, digest = message_definition("prisma_msgs/action/Grasp_FeedbackMessage")
    assert text.splitlines()[:2] == ["unique_identifier_msgs/UUID goal_id", "prisma_msgs/Grasp_Feedback feedback"]
    assert "MSG: prisma_msgs/Grasp_Feedback\nstring phase\nfloat32 finger_force\nfloat32 thumb_force" in text
    assert digest.startswith("RIHS01_")
    # plain messages keep rosbags' own definition and hash
    store = get_typestore()
    assert message_definition("prisma_msgs/msg/ContactState") == (
        store.generate_msgdef("prisma_msgs/msg/ContactState", ros_version=2)[0],
        store.hash_rihs01("prisma_msgs/msg/ContactState"))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_feedback_and_status_topics_round_trip(tmp_path, storage):
    bag = tmp_path / "actions"
    with BagWriter(bag, storage=storage) as writer:
        writer.write("/prisma/grasp/_action/status", status(7, 2), timestamp_ns=1_000_000_000)
        for i in range(5):
            writer.write("/prisma/grasp/_action/feedback", feedback("close_fingers", 0.1 * i, 7),
                         timestamp_ns=1_000_000_000 + i * 10_000_000)
        writer.write("/prisma/grasp/_action/status", status(7, 4), timestamp_ns=1_050_000_000)
    with AnyReader([bag], default_typestore=get_typestore()) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
    assert topics == {"/prisma/grasp/_action/feedback": "prisma_msgs/action/Grasp_FeedbackMessage",
                      "/prisma/grasp/_action/status": "action_msgs/msg/GoalStatusArray"}
    messages = list(read_bag(bag))
    fb = [m.message for m in messages if m.topic.endswith("feedback")]
    assert [round(m.feedback.finger_force, 6) for m in fb] == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert fb[2].feedback.phase == "close_fingers" and fb[2].feedback.thumb_force == pytest.approx(0.4)
    assert list(fb[0].goal_id.uuid) == [7] * 16
    codes = [m.message.status_list[0].status for m in messages if m.topic.endswith("status")]
    assert codes == [2, 4]
