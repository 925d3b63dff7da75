"""Test stand-in for rosidl_runtime_py.utilities: get_message / get_service / get_action / get_interface."""
from __future__ import annotations

from ros_standin.messages import get_class, get_interface as _get_interface

_ACTION_PARTS = ("_Goal", "_Result", "_Feedback", "_FeedbackMessage", "_SendGoal_Request",
                 "_SendGoal_Response", "_GetResult_Request", "_GetResult_Response")


def _split(identifier: str, kind: str) -> tuple[str, str, str]:
    parts = identifier.split("/")
    if len(parts) == 2:
        parts.insert(1, kind)
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"Expected the full name of a {kind}, got: {identifier}")
    return parts[0], parts[1], parts[2]


def get_interface(identifier: str) -> type:
    package, kind, name = _split(identifier, "msg")
    return _get_interface(f"{package}/{kind}/{name}")


def get_message(identifier: str) -> type:
    """Class for 'pkg/msg/Name' (or 'pkg/Name'); action/service parts like rosbag2 records them."""
    package, kind, name = _split(identifier, "msg")
    typename = f"{package}/{kind}/{name}"
    if kind == "msg":
        try:
            return get_class(typename)
        except KeyError:
            raise AttributeError(f"module '{package}.msg' has no attribute '{name}'") from None
    if kind == "action" and name.endswith(_ACTION_PARTS):
        return get_class(typename)
    if kind == "srv" and name.endswith(("_Request", "_Response")):
        return get_class(typename)
    raise ValueError(f"Expected the full name of a message, got: {identifier}")


def get_service(identifier: str) -> type:
    package, kind, name = _split(identifier, "srv")
    if kind != "srv":
        raise ValueError(f"Expected the full name of a service, got: {identifier}")
    return _get_interface(f"{package}/srv/{name}")


def get_action(identifier: str) -> type:
    package, kind, name = _split(identifier, "action")
    if kind != "action":
        raise ValueError(f"Expected the full name of an action, got: {identifier}")
    return _get_interface(f"{package}/action/{name}")
