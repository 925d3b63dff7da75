"""The suite runs on rclpy's public API: no module reads, sets or imports a private name of rclpy
(`_name`: what rclpy assigns as `self._name`, defines as a private method or class member, or keeps
as a private module member or module), except prisma_node_wiring/executor.py, the one module that
guards its use of them behind a version check and a self-test (executor_choice.py).

The private names come from the installed rclpy's sources; the project's Python (src/, test/, bench/)
is read with ast for any attribute of those names on an object other than the file's own `self`
(or `cls`, where the file itself defines the name), for `getattr`/`setattr`/`monkeypatch.setattr`
with such a name, and for imports of private rclpy members. Some generic names are private to
both rclpy and the project's own classes (`_handle`, `_lock`, `_node`, ...): those count only on an
object the file reached from an rclpy import (`rclpy.x._handle`), since ast cannot tell whose object
`emu._handle` is; the names rclpy's executor and action server keep their state in always count.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import ast
import functools
import importlib.util
import re
import textwrap
from collections.abc import Iterator
from pathlib import Path

from prisma_testing.ros_harness import require_ros

require_ros()

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("src", "test", "bench")
GUARDED = ROOT / "src" / "prisma_node_wiring" / "prisma_node_wiring" / "executor.py"
ATTRIBUTE_CALLS = {"getattr", "setattr", "hasattr", "delattr"}  # builtins and monkeypatch's
# rclpy's executor, entity and action server state: never taken for a project name of the same spelling
ALWAYS_RCLPY = frozenset({"_make_handler", "_spin_once_impl", "_wait_for_ready_callbacks", "_tasks", "_tasks_lock",
                          "_executor_event", "_guard", "_is_shutdown", "_work_tracker", "_goal_handles",
                          "_result_futures", "_rclpy"})


def is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def rclpy_sources() -> list[Path]:
    spec = importlib.util.find_spec("rclpy")
    assert spec is not None and spec.submodule_search_locations, "rclpy not found"
    return sorted(p for folder in spec.submodule_search_locations for p in Path(folder).rglob("*.py"))


def defined_private_names(tree: ast.AST) -> set[str]:
    """The private names a module defines: `self._x`/`cls._x` it assigns, private methods and class
    members, private module members (functions, classes, assignments, imports)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store) \
                and isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
            names.add(node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((alias.asname or alias.name).split(".")[0] for alias in node.names)
    return {name for name in names if is_private(name)}


def rclpy_private_names() -> frozenset[str]:
    names: set[str] = set()
    for source in rclpy_sources():
        names |= defined_private_names(ast.parse(source.read_bytes(), str(source)))
        names |= {part for part in source.with_suffix("").parts if is_private(part)}  # private modules
    # the compiled extension module (rclpy._rclpy_pybind11) has no Python source
    names |= {p.name.split(".")[0] for folder in importlib.util.find_spec("rclpy").submodule_search_locations or ()
              for p in Path(folder).iterdir() if is_private(p.name.split(".")[0])}
    return frozenset(names)


def _dotted_private(dotted: str) -> bool:
    parts = dotted.split(".")
    return parts[0] == "rclpy" and any(is_private(p) for p in parts[1:])


def _owns(value: ast.expr, name: str, own: set[str]) -> bool:
    """`value.name` is the file's own: its `self` or `cls`, and a name the file itself defines."""
    return isinstance(value, ast.Name) and value.id in ("self", "cls") and name in own


def _root(value: ast.expr) -> str | None:
    while isinstance(value, (ast.Attribute, ast.Subscript, ast.Call)):
        value = value.func if isinstance(value, ast.Call) else value.value
    return value.id if isinstance(value, ast.Name) else None


def rclpy_bound_names(tree: ast.AST) -> set[str]:
    """The names a module binds to rclpy by its imports (`import rclpy.x` binds rclpy)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.asname or alias.name.split(".")[0] for alias in node.names
                      if alias.name.split(".")[0] == "rclpy"}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "rclpy":
            names |= {alias.asname or alias.name for alias in node.names}
    return names


def private_uses(source: str | ast.AST, private: frozenset[str],
                 shared: frozenset[str] = frozenset()) -> Iterator[tuple[int, str]]:
    """(line, what) for each use of an rclpy private name in `source` (its text or its tree); a name
    in `shared` (the project's own classes have it too) only on an object reached from an rclpy import."""
    tree = ast.parse(source) if isinstance(source, str) else source
    own = defined_private_names(tree)
    from_rclpy = rclpy_bound_names(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in private:
            if _owns(node.value, node.attr, own):
                continue
            if node.attr in shared and _root(node.value) not in from_rclpy:
                continue
            yield node.lineno, f"{ast.unparse(node)}: rclpy's private {node.attr}"
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "rclpy":
            if _dotted_private(node.module):
                yield node.lineno, f"from {node.module} import: a private rclpy module"
            for alias in node.names:
                if is_private(alias.name):
                    yield node.lineno, f"from {node.module} import {alias.name}: rclpy's private {alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if _dotted_private(alias.name):
                    yield node.lineno, f"import {alias.name}: a private rclpy module"
        elif isinstance(node, ast.Call):
            func = node.func
            name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""
            if name not in ATTRIBUTE_CALLS:
                continue
            for arg in node.args[:2]:
                if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
                    continue
                if node.args and _owns(node.args[0], arg.value, own):
                    continue
                if arg.value in shared and _root(node.args[0]) not in from_rclpy:
                    continue
                if arg.value in private or _dotted_private(arg.value):
                    yield node.lineno, f"{name}(..., {arg.value!r}): rclpy's private {arg.value}"


@functools.cache
def project_files() -> tuple[Path, ...]:
    """Every Python file of src/, test/ and bench/ but the guarded executor."""
    return tuple(sorted(p for folder in SCANNED for p in (ROOT / folder).rglob("*.py")
                        if "__pycache__" not in p.parts and p != GUARDED))


@functools.cache
def project_trees() -> dict[Path, ast.AST]:
    """The project's files that spell any of rclpy's private names as a word, parsed (a tenth of
    them: parsing all 3 MB took seconds of CI's time on a loaded machine)."""
    words = sorted(map(re.escape, PRIVATE), key=len, reverse=True)
    mentions = re.compile(r"(?<![A-Za-z0-9_])(?:" + "|".join(words) + r")(?![A-Za-z0-9_])")
    texts = {path: path.read_text() for path in project_files()}
    return {path: ast.parse(text, str(path)) for path, text in texts.items() if mentions.search(text)}


PRIVATE = rclpy_private_names()


@functools.cache
def names_the_project_defines_too() -> frozenset[str]:
    names: set[str] = set()
    for tree in project_trees().values():
        names |= defined_private_names(tree)
    return frozenset((names & PRIVATE) - ALWAYS_RCLPY)


def test_the_private_names_come_from_rclpy_itself():
    # what the fast executor and the test support once read (issue 42), each found in the sources
    for name in ("_make_handler", "_spin_once_impl", "_tasks", "_executor_event", "_guard", "_is_shutdown",
                 "_work_tracker", "_rclpy", "_rclpy_pybind11", "_WorkTracker"):
        assert name in PRIVATE, name
    assert len(PRIVATE) > 200  # rclpy 7.1.3: 400-odd
    assert not {"spin_once", "create_subscription", "callback", "__init__", "handle"} & PRIVATE


def test_no_module_but_the_guarded_executor_uses_rclpy_private_names():
    trees = project_trees()
    assert len(project_files()) > 300 and len(trees) > 20
    shared = names_the_project_defines_too()
    assert len(shared) < 20, sorted(shared)  # generic ones only (_handle, _lock, _node, ...)
    found = [f"{path.relative_to(ROOT)}:{line}: {what}" for path, tree in trees.items()
             for line, what in private_uses(tree, PRIVATE, shared)]
    assert found == [], "\n".join(found)


def test_the_guarded_executor_is_the_one_that_uses_them():
    # the scan reads real rclpy use: without the exception executor.py would fail it
    found = {what.split(":")[0] for _, what in private_uses(GUARDED.read_text(), PRIVATE)}
    assert {"executor._is_shutdown", "entity._executor_event", "super()._make_handler", "self._guard"} <= found


SEEDED = textwrap.dedent('''\
    import rclpy.executors
    from rclpy.executors import _rclpy
    import rclpy._rclpy_pybind11
    class Harness:
        def __init__(self, executor):
            self.executor = executor
        def count(self, entity, monkeypatch):
            make = self.executor._make_handler
            busy = [t for t, e, _ in self.executor._tasks]
            entity._executor_event = False
            monkeypatch.setattr(rclpy.executors, "_rclpy", None)
            monkeypatch.setattr("rclpy.executors._rclpy", None)
            getattr(entity, "_executor_event")
            return self._guard
    class Fast(rclpy.executors.SingleThreadedExecutor):
        def _spin_once_impl(self, timeout_sec=None, wait_condition=lambda: False):
            super()._spin_once_impl(timeout_sec, wait_condition)
    ''')


def test_a_seeded_violation_is_caught_at_each_line():
    found = sorted(private_uses(SEEDED, PRIVATE, names_the_project_defines_too()))
    assert [line for line, _ in found] == [2, 3, 8, 9, 10, 11, 12, 13, 14, 17], found
    assert found[2] == (8, "self.executor._make_handler: rclpy's private _make_handler")
    # `self._guard` is rclpy's name and this file never assigns it: a subclass reading rclpy's state
    assert found[8] == (14, "self._guard: rclpy's private _guard")


CLEAN = textwrap.dedent('''\
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    class Collector:
        def __init__(self, node):
            self._node = node
            self._tasks = []
            self._guard = None
        def spin(self, executor):
            self._tasks.append(executor.create_task(lambda: None))
            executor.spin_once(timeout_sec=0.1)
            return [s.topic_name for n in executor.get_nodes() for s in n.subscriptions], self._node.get_name()
        def kind(self):
            return self.__class__.__name__, getattr(self, "_guard")
    def _helper():
        return SingleThreadedExecutor()
    ''')


def test_a_clean_snippet_passes():
    assert list(private_uses(CLEAN, PRIVATE, names_the_project_defines_too())) == []


SHARED = textwrap.dedent('''\
    import rclpy.subscription
    from rclpy.node import Node
    def check(emu, sub):
        emu._handle.close()
        with emu._lock:
            sub._executor_event = True
        return rclpy.subscription.Subscription._handle, Node._lock, getattr(emu, "_handle")
    ''')


def test_a_name_the_project_shares_counts_on_an_object_from_rclpy_only():
    shared = names_the_project_defines_too()
    assert {"_handle", "_lock"} <= shared  # the motor emulator's socket handle and lock, among others
    assert [line for line, _ in sorted(private_uses(SHARED, PRIVATE, shared))] == [6, 7, 7]
    assert [line for line, _ in sorted(private_uses(SHARED, PRIVATE))] == [4, 5, 6, 7, 7, 7]
