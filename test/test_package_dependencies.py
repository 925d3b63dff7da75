"""The ROS package graph: declared dependencies cover imports, and colcon can order it.

A module-level import of another workspace package must be declared in package.xml. colcon refuses
cyclic graphs, so an import against the declared direction (the tactile driver's sim source from
prisma_manipulation, the force estimator's bag tools from prisma_bringup) is allowed only inside a
function, where it runs when that feature is used.
"""
from __future__ import annotations

import ast
import xml.etree.ElementTree as ET
from graphlib import CycleError, TopologicalSorter
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / "package.xml").exists())
PYTHON_PACKAGES = [p for p in PACKAGES if (SRC / p / p).is_dir()]


def declared(package: str) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    tags = ("depend", "build_depend", "exec_depend", "build_export_depend")
    return {e.text.strip() for tag in tags for e in root.iter(tag) if e.text}


def workspace_imports(package: str) -> tuple[set[str], set[str]]:
    """(module-level, function-level) imports of other workspace packages."""
    top, nested = set(), set()
    for path in (SRC / package / package).rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            else:
                continue
            for name in names:
                root = name.split(".")[0]
                if root in PACKAGES and root != package:
                    (top if node.col_offset == 0 else nested).add(root)
    return top, nested


def test_packages_found():
    assert {"prisma_msgs", "prisma_tactile_driver", "prisma_force_estimator", "prisma_manipulation",
            "stag_glove", "prisma_bringup"} <= set(PACKAGES)


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_module_level_imports_are_declared(package):
    top, _ = workspace_imports(package)
    missing = top - declared(package)
    assert not missing, f"{package} imports {sorted(missing)} at module level but package.xml does not declare it"


def test_declared_graph_is_acyclic():
    graph = {p: declared(p) & set(PACKAGES) for p in PACKAGES}
    try:
        order = list(TopologicalSorter(graph).static_order())
    except CycleError as exc:
        pytest.fail(f"package.xml dependencies form a cycle: {exc.args[1]}")
    assert order.index("prisma_msgs") < order.index("prisma_tactile_driver") < order.index("prisma_bringup")


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_undeclared_imports_are_function_level_back_edges(package):
    top, nested = workspace_imports(package)
    for other in nested - declared(package):
        # allowed only because the other package depends on this one: declaring it would be a cycle
        assert package in declared(other), (
            f"{package} imports {other} inside a function without declaring it, and {other} does not "
            f"depend on {package}: declare it in package.xml")
