"""Test-only stand-in for rclpy (ROS 2 Jazzy API subset), see test/standin/README.md.

Only put on sys.path by test/conftest.py when the real rclpy is not importable.
"""
from __future__ import annotations

from .context import Context
from .utilities import get_default_context, ok, remove_ros_args, shutdown, try_shutdown

__all__ = [
    "init", "shutdown", "try_shutdown", "ok", "create_node", "spin", "spin_once",
    "spin_until_future_complete", "get_global_executor", "get_default_context",
]

_GLOBAL_EXECUTOR = None


def init(*, args=None, context: Context | None = None, domain_id=None, signal_handler_options=None) -> None:
    """Initialise the context; `args` may hold `--ros-args -p name:=value` / `--params-file FILE`."""
    (context or get_default_context()).init(args, domain_id=domain_id)


def get_global_executor():
    global _GLOBAL_EXECUTOR
    if _GLOBAL_EXECUTOR is None:
        from .executors import SingleThreadedExecutor

        _GLOBAL_EXECUTOR = SingleThreadedExecutor()
    return _GLOBAL_EXECUTOR


def _reset_global_executor() -> None:
    global _GLOBAL_EXECUTOR
    _GLOBAL_EXECUTOR = None


def create_node(node_name: str, *, context=None, cli_args=None, namespace=None, use_global_arguments=True,
                enable_rosout=True, start_parameter_services=True, parameter_overrides=None,
                allow_undeclared_parameters=False, automatically_declare_parameters_from_overrides=False,
                enable_logger_service=False):
    from .node import Node

    return Node(node_name, context=context, cli_args=cli_args, namespace=namespace,
                use_global_arguments=use_global_arguments, enable_rosout=enable_rosout,
                start_parameter_services=start_parameter_services, parameter_overrides=parameter_overrides,
                allow_undeclared_parameters=allow_undeclared_parameters,
                automatically_declare_parameters_from_overrides=automatically_declare_parameters_from_overrides,
                enable_logger_service=enable_logger_service)


def _with_node(node, executor):
    executor = get_global_executor() if executor is None else executor
    previous = node.executor
    executor.add_node(node)
    return executor, previous


def _restore(node, executor, previous) -> None:
    if previous is not executor:
        executor.remove_node(node)
        if previous is not None:
            previous.add_node(node)


def spin_once(node, *, executor=None, timeout_sec: float | None = None) -> None:
    executor, previous = _with_node(node, executor)
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        _restore(node, executor, previous)


def spin(node, executor=None) -> None:
    executor, previous = _with_node(node, executor)
    try:
        executor.spin()
    finally:
        _restore(node, executor, previous)


def spin_until_future_complete(node, future, executor=None, timeout_sec: float | None = None) -> None:
    executor, previous = _with_node(node, executor)
    try:
        executor.spin_until_future_complete(future, timeout_sec)
    finally:
        _restore(node, executor, previous)
