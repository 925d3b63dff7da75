"""The parameter part of `--ros-args`: `-p name:=value`, `--param name:=value`, `--params-file FILE`.

Values are YAML, as rcl reads them (`1` is an integer, `1.0` a double, `[a, b]` a string array).
A params file has the ros__parameters form; its top keys are node names ('/**' for every node,
'name' is the node 'name' in the root namespace, '/ns/name', '*' and '**' wildcards).
Other ROS arguments (remapping, log level, enclave) are accepted and ignored.
"""
from __future__ import annotations

import re
from typing import Any

import yaml

ALL_NODES = "/**"


def _flatten(prefix: str, values: dict, out: dict) -> None:
    for key, value in values.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            _flatten(name, value, out)
        else:
            out[name] = value


def read_params_file(path) -> list[tuple[str, dict[str, Any]]]:
    with open(path) as handle:
        document = yaml.safe_load(handle) or {}
    entries = []
    for node_key, body in document.items():
        if not isinstance(body, dict) or "ros__parameters" not in body:
            raise ValueError(f"{path}: '{node_key}' has no 'ros__parameters' mapping")
        params: dict[str, Any] = {}
        _flatten("", body["ros__parameters"] or {}, params)
        entries.append((str(node_key), params))
    return entries


def parse_value(text: str) -> Any:
    return yaml.safe_load(text)


def parse_ros_args(args) -> tuple[list[tuple[str, dict[str, Any]]], list[str]]:
    """(override entries in order, the arguments outside --ros-args)."""
    entries: list[tuple[str, dict[str, Any]]] = []
    remaining: list[str] = []
    if not args:
        return entries, remaining
    args = list(args)
    i = 0
    in_ros_args = False
    while i < len(args):
        arg = args[i]
        if arg == "--ros-args":
            in_ros_args = True
        elif arg == "--" and in_ros_args:
            in_ros_args = False
        elif not in_ros_args:
            remaining.append(arg)
        elif arg in ("-p", "--param"):
            i += 1
            assignment = args[i]
            name, sep, value = assignment.partition(":=")
            if not sep:
                raise ValueError(f"Couldn't parse parameter override rule: '{assignment}'")
            node = ALL_NODES
            if ":" in name:  # node_name:param form
                node, name = name.split(":", 1)
            entries.append((node, {name: parse_value(value)}))
        elif arg == "--params-file":
            i += 1
            entries.extend(read_params_file(args[i]))
        elif arg in ("-r", "--remap", "-e", "--enclave", "--log-level", "--log-config-file"):
            i += 1
        i += 1
    return entries, remaining


def _pattern_regex(pattern: str) -> re.Pattern:
    if not pattern.startswith("/"):
        pattern = "/" + pattern
    if pattern == ALL_NODES:
        return re.compile(".*")
    out = ""
    for part in re.split(r"(/\*\*|\*)", pattern):
        if part == "/**":
            out += r"(?:/[^/]+)*"
        elif part == "*":
            out += r"[^/]*"
        else:
            out += re.escape(part)
    return re.compile(out)


def overrides_for(entries, fully_qualified_name: str) -> dict[str, Any]:
    values: dict[str, Any] = {}
    for pattern, params in entries:
        if _pattern_regex(pattern).fullmatch(fully_qualified_name):
            values.update(params)
    return values
