"""One node of a kind per hand: a node that commands the motors (manipulation, motor_driver) refuses
to start beside another of its fully qualified name or beside another server of the actions it
would offer.

Two controllers of one hand each take every goal (`ros2 action info` shows 2 servers, both start a
Grasp) and each send MoveMotors for it; two motor drivers open one bus. ROS allows both: node names
need not be unique and an action may have many servers. So the node looks before it serves:

    super().__init__("manipulation", **kwargs)
    refuse_if_running(self, ("prisma/grasp", "prisma/manipulate", "prisma/gripper_cmd"))

destroys the node and raises AlreadyRunning (the node's main() passes it to run_node with the
configuration errors: logged as fatal, exit 1) naming the node already there and how to stop it.
It must be called before the node creates its own action servers and before it opens any device.

Discovery takes time: a node that has just joined sees the others once DDS has matched their
participants and their ros_discovery_info (the graph's node names) and service endpoints have
arrived. There is no sign that the graph is complete, so the node keeps looking, every POLL_S, for
DISCOVERY_WAIT_S: a duplicate is refused as soon as it is seen; a node alone starts DISCOVERY_WAIT_S
later than it would. Measured on the project's 2-core machine (CycloneDDS, one host, 12 starts):
the running node's name and its action's send_goal service were already in the graph when the new
node's constructor returned (0.3-0.45 s after rclpy.init: CycloneDDS discovers the local peers while
it creates the participant). The wait is for what that does not cover: a peer on another host of
the domain (docs/architecture.md, two hosts), a loaded machine. Graphs are per ROS_DOMAIN_ID (each
launch test has its own) and names per namespace (bimanual.launch.py's /left/manipulation and
/right/manipulation are two names, /left/prisma/grasp and /right/prisma/grasp two actions), so
neither meets the other. A process killed with SIGKILL stays in the graph until its DDS lease
expires (CycloneDDS: 10 s): the refusal says so.
"""
from __future__ import annotations

import time
from collections.abc import Iterable

from rclpy.node import Node

DISCOVERY_WAIT_S = 0.5  # how long a starting node looks for another of its kind (the module says why)
POLL_S = 0.02


class AlreadyRunning(Exception):
    """Another node of this node's name, or another server of its actions, is in the graph."""


def _action_holder(node: Node, action: str) -> str | None:
    """The fully qualified name of a node serving `action` (resolved in `node`'s namespace, with its
    remappings), 'another node' when one serves it but its name is not known yet, else None."""
    if node.count_services(node.resolve_service_name(f"{action}/_action/send_goal")) == 0:
        return None  # a service: a bag played back can publish an action's topics, never serve it
    # named by the endpoint of its status topic (an action server publishes it): the lookup of a
    # node's services by its name mixes up two nodes of one name, the case this module is for
    for info in node.get_publishers_info_by_topic(node.resolve_topic_name(f"{action}/_action/status")):
        if not info.node_name.startswith("_NODE_NAME_UNKNOWN"):  # its node's name not discovered yet
            return f"{info.node_namespace.rstrip('/')}/{info.node_name}"
    return "another node"


def duplicate_of(node: Node, actions: Iterable[str] = ()) -> str | None:
    """Why `node` must not start: another node of its fully qualified name, or a server of one of
    `actions` (which `node` has not created yet), is in the graph; else None."""
    name, namespace = node.get_name(), node.get_namespace()
    fqn = node.get_fully_qualified_name()
    stop = ("stop it first (ctrl-C its launch, or `kill <pid>` of its process: `ps -ef | grep` its "
            "name; a `ros2 run` wrapper killed alone leaves its node running); a process killed with "
            "SIGKILL leaves the graph within 10 s")
    same = sum(1 for n, ns in node.get_node_names_and_namespaces() if n == name and ns == namespace)
    if same > 1:  # the graph lists this node too
        return f"{fqn} is already running in this ROS domain: not starting a second one. To restart it, {stop}"
    for action in actions:
        holder = _action_holder(node, action)
        if holder is not None:
            return (f"{node.resolve_service_name(action)} is already served by {holder}: {fqn} would be a second "
                    f"server of it, not starting. To restart it, {stop}")
    return None


def refuse_if_running(node: Node, actions: Iterable[str] = (), wait_s: float | None = None) -> None:
    """Raise AlreadyRunning when another node of `node`'s kind appears in the graph within `wait_s`
    (default DISCOVERY_WAIT_S, read at the call: nodes of one process share one DDS participant and
    see each other at once, so a test process that builds its nodes itself sets it to 0)."""
    actions = tuple(actions)
    deadline = time.monotonic() + (DISCOVERY_WAIT_S if wait_s is None else wait_s)
    while True:
        reason = duplicate_of(node, actions)
        if reason is not None:
            # out of the graph now: a node object the caller never gets would stay listed until the
            # garbage collector or the process end, and another node of this name would see it
            Node.destroy_node(node)
            raise AlreadyRunning(reason)
        if time.monotonic() >= deadline:
            return
        time.sleep(POLL_S)
