"""ROS name validation and expansion (relative names, '~', namespaces), as rcl does it."""
from __future__ import annotations

import re

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def validate_node_name(name: str) -> str | None:
    if not name:
        return "node name must not be empty"
    if not re.fullmatch(r"[A-Za-z0-9_]+", name):
        return "node name must not contain characters other than alphanumerics or '_'"
    if name[0].isdigit():
        return "node name must not start with a number"
    return None


def normalize_namespace(namespace: str | None) -> str:
    if not namespace:
        return "/"
    if not namespace.startswith("/"):
        namespace = "/" + namespace
    if len(namespace) > 1 and namespace.endswith("/"):
        namespace = namespace.rstrip("/")
    return namespace


def validate_namespace(namespace: str) -> str | None:
    if namespace == "/":
        return None
    for token in namespace[1:].split("/"):
        if not _TOKEN.match(token):
            return f"namespace token {token!r} is invalid"
    return None


def expand_topic_name(name: str, node_name: str, namespace: str) -> str:
    """Fully qualified name: '/abs' stays, '~' and '~/x' are below the node, 'x' below the namespace."""
    if not name:
        raise ValueError("topic name must not be empty")
    if name.startswith("/"):
        expanded = name
    elif name == "~" or name.startswith("~/"):
        base = namespace.rstrip("/") + "/" + node_name
        expanded = base + name[1:]
    else:
        expanded = namespace.rstrip("/") + "/" + name
    return expanded


def validate_full_topic_name(name: str) -> str | None:
    if not name.startswith("/"):
        return "topic name must be absolute"
    if name != "/" and name.endswith("/"):
        return "topic name must not end with a forward slash"
    if "//" in name:
        return "topic name must not contain repeated forward slashes"
    for token in name[1:].split("/"):
        if not re.fullmatch(r"[A-Za-z0-9_]+", token):
            return f"topic name token {token!r} contains characters other than alphanumerics or '_'"
        if token[0].isdigit():
            return f"topic name token {token!r} must not start with a number"
    return None
