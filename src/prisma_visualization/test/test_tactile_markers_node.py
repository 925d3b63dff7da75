"""tactile_markers on real rclpy over DDS: idle (no subscription) until a display subscribes, then a
MarkerArray at the display rate whose taxel cells carry the ContactState's per-taxel decision of the
same sample, and idle again once the display leaves."""
from __future__ import annotations

import time

import numpy as np
import pytest

from prisma_testing.repo_paths import CONFIG
from prisma_testing.ros_harness import require_ros

require_ros()

from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import Vector3, Wrench, WrenchStamped  # noqa: E402
from prisma_msgs.msg import ContactState, HandContact, HandWrench  # noqa: E402
from prisma_visualization.ros_conversions import ARROW, CELLS, CUBE_LIST, DELETE, FORCE, taxel_decisions  # noqa: E402
from rosidl_runtime_py.utilities import get_action, get_message  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402
from prisma_common.messages import robot_types  # noqa: E402
from prisma_manipulation.contact_monitor import ContactMonitor  # noqa: E402
from prisma_manipulation.ros_conversions import contact_state_to_msg, hand_contact_to_msg  # noqa: E402

PARAMS = CONFIG / "tactile_markers.yaml"
LEFT_PRESS = np.array([0.40, 1.10, 2.00, 0.45, 1.30, 2.40, 0.42, 1.05, 1.90], dtype=np.float32)
REST = np.array([0.42, 0.47, 0.39, 0.45, 0.41, 0.50, 0.44, 0.38, 0.46], dtype=np.float32)
NODE = "tactile_markers"
INPUTS = {"/prisma/hand/contact", "/prisma/hand/wrench"} | {f"/prisma/{f}/{kind}" for f in FINGERS
                                                            for kind in ("contact", "wrench")}


@pytest.fixture
def node_cls():
    from prisma_visualization.tactile_markers_node import TactileMarkersNode
    return TactileMarkersNode


def subscribed_topics(ros) -> set[str]:
    return {name for name, _ in ros.probe.get_subscriber_names_and_types_by_node(NODE, "/")}


def hand_wrench(stamp_ns: int, forces: dict[str, float]) -> HandWrench:
    stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    wrenches = [WrenchStamped(header=Header(stamp=stamp, frame_id=f"prisma_{f}_pad"),
                              wrench=Wrench(force=Vector3(z=fz), torque=Vector3()))
                for f, fz in forces.items()]
    return HandWrench(header=Header(stamp=stamp), fingers=list(forces), wrenches=wrenches)


def hand_contact(stamp_ns: int, k: float = 0.8) -> tuple[HandContact, dict[str, ContactState]]:
    types = robot_types(get_message, get_action)
    monitor = ContactMonitor(k=k)
    contacts = {f: contact_state_to_msg(types, monitor.evaluate(f, stamp_ns, v), f"prisma_{f}_pad")
                for f, v in (("thumb", LEFT_PRESS), ("index", REST))}
    return hand_contact_to_msg(types, list(contacts.values())), contacts


def test_idle_until_a_display_subscribes_and_idle_again_after(ros, node_cls):
    ros.node(node_cls, params_files=[PARAMS])
    ros.spin_for(1.0)
    assert not subscribed_topics(ros) & INPUTS  # nobody watches: the node reads nothing
    watcher = ros.probe.create_subscription(MarkerArray, "/prisma/tactile_markers", lambda _: None, 10)
    assert ros.spin_until(lambda: INPUTS <= subscribed_topics(ros), 10.0), subscribed_topics(ros)
    ros.probe.destroy_subscription(watcher)
    assert ros.spin_until(lambda: not subscribed_topics(ros) & INPUTS, 10.0), subscribed_topics(ros)


def test_markers_carry_the_contact_states_decision_of_the_same_sample(ros, node_cls):
    node = ros.node(node_cls, params_files=[PARAMS])
    arrays = ros.collect(MarkerArray, "/prisma/tactile_markers")
    assert ros.spin_until(lambda: "/prisma/hand/contact" in subscribed_topics(ros), 10.0)
    stamp = ros.now_ns()
    hand, sent = hand_contact(stamp)
    ros.publish("/prisma/hand/wrench", hand_wrench(stamp, {"thumb": 0.9, "index": 0.02}))
    ros.publish("/prisma/hand/contact", hand)
    assert ros.spin_until(lambda: any(set(taxel_decisions(a)) == {"thumb", "index"} for a in arrays), 10.0)
    (array,) = [a for a in arrays if set(taxel_decisions(a)) == {"thumb", "index"}][-1:]
    decisions = taxel_decisions(array)
    for finger, contact in sent.items():
        assert decisions[finger] == (stamp, tuple(contact.safe)), finger
    assert decisions["thumb"][1] == (False, True, True, False, True, True, False, True, True)
    markers = {(m.ns, m.id): m for m in array.markers}
    cells = markers[("thumb", CELLS)]
    assert (cells.type, cells.header.frame_id, cells.frame_locked, len(cells.points)) == (
        CUBE_LIST, "prisma_thumb_pad", True, 9)
    assert [c.r > c.b for c in cells.colors] == list(sent["thumb"].safe)  # the colour says it too
    arrow = markers[("thumb", FORCE)]
    assert arrow.type == ARROW and arrow.points[0].z - arrow.points[1].z == pytest.approx(0.9 * 0.02)
    assert markers[("index", FORCE)].action == DELETE  # 0.02 N: below contact_force_n, no arrow
    # k changed on the manipulation node shows in its next ContactState, and so on the pads
    later, sent = hand_contact(stamp + 10_000_000, k=1.2)
    ros.publish("/prisma/hand/contact", later)
    assert ros.spin_until(lambda: taxel_decisions(arrays[-1]).get("thumb", (0,))[0] == stamp + 10_000_000, 10.0)
    assert taxel_decisions(arrays[-1])["thumb"][1] == tuple(sent["thumb"].safe)
    assert node.markers.take_drawings() == []


def test_published_at_the_display_rate_not_per_sample(ros, node_cls):
    ros.node(node_cls, params_files=[PARAMS], params={"rate_hz": 10.0})
    arrays = ros.collect(MarkerArray, "/prisma/tactile_markers")
    assert ros.spin_until(lambda: "/prisma/hand/contact" in subscribed_topics(ros), 10.0)
    # 100 scans/s for 2 s from a thread of their own: the node takes the newest once per display tick
    # (the rest are dropped unread), so nothing of theirs wakes this process's executor to send the next
    with ros.publishing(HandContact, "/prisma/hand/contact", lambda _: hand_contact(time.time_ns())[0], 100.0,
                        wait_for_subscribers=1) as sent:
        ros.spin_for(2.0)
    ros.spin_for(0.3)
    assert len(sent) > 150
    assert 15 <= len(arrays) <= 22  # 10 Hz for 2 s, however many samples came
    ros.spin_for(0.5)
    count = len(arrays)
    ros.spin_for(0.5)
    assert len(arrays) == count  # nothing new: nothing published
