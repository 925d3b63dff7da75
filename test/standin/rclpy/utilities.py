"""rclpy.utilities: the default context and ROS argument helpers."""
from __future__ import annotations

from ros_standin import arguments as _arguments

from .context import Context

_DEFAULT_CONTEXT = Context()


def get_default_context(*, shutting_down: bool = False) -> Context:
    return _DEFAULT_CONTEXT


def ok(*, context: Context | None = None) -> bool:
    return (context or _DEFAULT_CONTEXT).ok()


def shutdown(*, context: Context | None = None) -> None:
    (context or _DEFAULT_CONTEXT).shutdown()


def try_shutdown(*, context: Context | None = None) -> None:
    (context or _DEFAULT_CONTEXT).try_shutdown()


def remove_ros_args(args=None) -> list[str]:
    return _arguments.parse_ros_args(args or [])[1]


def get_rmw_implementation_identifier() -> str:
    return "rmw_standin"
