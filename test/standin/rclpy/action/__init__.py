"""rclpy.action of the stand-in: ActionServer, ActionClient, GoalResponse, CancelResponse and graph queries."""
from __future__ import annotations

from .client import ActionClient, ClientGoalHandle
from .server import ActionServer, CancelResponse, GoalResponse, ServerGoalHandle

__all__ = [
    "ActionClient", "ActionServer", "CancelResponse", "ClientGoalHandle", "GoalResponse", "ServerGoalHandle",
    "get_action_client_names_and_types_by_node", "get_action_server_names_and_types_by_node",
    "get_action_names_and_types",
]


def _names_and_types(endpoints) -> list[tuple[str, list[str]]]:
    found: dict[str, list[str]] = {}
    for endpoint in endpoints:
        type_name = endpoint._action_type.__actiontype__
        types = found.setdefault(endpoint._action_name, [])
        if type_name not in types:
            types.append(type_name)
    return sorted(found.items())


def get_action_server_names_and_types_by_node(node, remote_node_name: str, remote_node_namespace: str):
    remote = node._node_by_name(remote_node_name, remote_node_namespace)
    return _names_and_types(w for w in remote.waitables if isinstance(w, ActionServer))


def get_action_client_names_and_types_by_node(node, remote_node_name: str, remote_node_namespace: str):
    remote = node._node_by_name(remote_node_name, remote_node_namespace)
    return _names_and_types(w for w in remote.waitables if isinstance(w, ActionClient))


def get_action_names_and_types(node):
    graph = node.context.graph
    return _names_and_types(list(graph.action_servers) + list(graph.action_clients))
