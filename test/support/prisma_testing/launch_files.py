"""The nodes a launch file starts, read from its source (no launch runs): what the static checks
(test_static_consistency.py) and the launched parameters' check (test_launch_parameters.py) both walk."""
from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

NOT_LITERAL = object()  # an inline parameter value given by a substitution (LaunchConfiguration...)


@dataclass(frozen=True)
class LaunchedNode:
    launch_file: str
    line: int
    package: str | None
    executable: str | None
    name: str | None
    parameter_files: tuple[str, ...]
    inline_parameters: tuple[tuple[str, object], ...] = ()  # (name, literal value or NOT_LITERAL)


def string_literal(node: ast.AST) -> str | None:
    """The text of a string constant, None for anything else."""
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


# prisma_bringup.launch_nodes' helper: a Node of the control path, named as its executable
CONTROL_PATH_NODE = "control_path_node"


def launched_nodes(launch_file: Path) -> list[LaunchedNode]:
    """Every Node, LifecycleNode and control_path_node call of `launch_file`, in source order."""
    tree = ast.parse(launch_file.read_text(), filename=str(launch_file))
    found = []
    for call in ast.walk(tree):
        if not isinstance(call, ast.Call):
            continue
        func = getattr(call.func, "id", getattr(call.func, "attr", None))
        if func not in ("Node", "LifecycleNode", CONTROL_PATH_NODE):
            continue
        keywords = {k.arg: k.value for k in call.keywords}
        files = tuple(
            c.value for c in ast.walk(keywords["parameters"])
            if isinstance(c, ast.Constant) and isinstance(c.value, str) and c.value.endswith((".yaml", ".yml"))
        ) if "parameters" in keywords else ()
        inline = []
        for mapping in (ast.walk(keywords["parameters"]) if "parameters" in keywords else ()):
            if isinstance(mapping, ast.Dict):
                for key, value in zip(mapping.keys, mapping.values):
                    try:
                        literal = ast.literal_eval(value)
                    except ValueError:
                        literal = NOT_LITERAL
                    inline.append((string_literal(key) or f"<not a literal at line {key.lineno}>", literal))
        executable = string_literal(keywords.get("executable"))
        name = executable if func == CONTROL_PATH_NODE else string_literal(keywords.get("name"))
        package = string_literal(keywords.get("package"))
        found.append(LaunchedNode(launch_file.name, call.lineno, package, executable, name, files, tuple(inline)))
    return found


def declared_arguments(launch_file: Path) -> dict[str, tuple[str, ...] | None]:
    """A launch file's DeclareLaunchArgument names -> their choices (None: any value, or choices
    computed, such as list(FINGERS): launch itself checks those)."""
    declared: dict[str, tuple[str, ...] | None] = {}
    for node in ast.walk(ast.parse(launch_file.read_text(), filename=str(launch_file))):
        called = getattr(node.func, "id", getattr(node.func, "attr", None)) if isinstance(node, ast.Call) else None
        if called == "DeclareLaunchArgument" and node.args:
            name = string_literal(node.args[0])
            if name is None:
                continue
            choices = next((k.value for k in node.keywords if k.arg == "choices"), None)
            try:
                declared[name] = tuple(ast.literal_eval(choices)) if choices is not None else None
            except ValueError:
                declared[name] = None
    return declared
