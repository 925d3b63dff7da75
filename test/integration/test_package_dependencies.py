"""The ROS package graph: declared dependencies cover imports, and colcon can order it.

Every import of another workspace package is at module level (a `TYPE_CHECKING` block counts as
module level) and declared in package.xml; none hides inside a function. The declared graph is
acyclic, so it has no back-edges: prisma_common and prisma_hand_sim, the ROS-free layers, sit
below every driver and import no ROS; the hand emulator (hardware) reads no controller package. A
message's converters are imported from its writer's package, and no package's modules import each
other in a circle. docs/architecture.md's workspace layout lists every package,
and its dependency drawing has the declared graph's layering (each package above the same ones).
"""
from __future__ import annotations

import ast
import re
import xml.etree.ElementTree as ET
from graphlib import CycleError, TopologicalSorter
from pathlib import Path

import pytest

from prisma_testing.repo_paths import ROOT

SRC = ROOT / "src"
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / "package.xml").exists())
PYTHON_PACKAGES = [p for p in PACKAGES if (SRC / p / p).is_dir()]
ROS_FREE = ("prisma_common", "prisma_hand_sim")


def declared(package: str) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    tags = ("depend", "build_depend", "exec_depend", "build_export_depend")
    return {e.text.strip() for tag in tags for e in root.iter(tag) if e.text}


def imported_modules(node: ast.AST) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
        return [node.module]
    return []


def imports(package: str) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """(module-level, function-level) imports of `package`: top-level name -> the modules importing it."""
    top: dict[str, set[str]] = {}
    nested: dict[str, set[str]] = {}

    def visit(node: ast.AST, in_function: bool, where: str) -> None:
        for child in ast.iter_child_nodes(node):
            for name in imported_modules(child):
                (nested if in_function else top).setdefault(name.split(".")[0], set()).add(where)
            visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)),
                  where)

    for path in sorted((SRC / package / package).rglob("*.py")):
        visit(ast.parse(path.read_text()), False, str(path.relative_to(SRC)))
    return top, nested


def workspace(found: dict[str, set[str]], package: str) -> dict[str, set[str]]:
    return {name: where for name, where in found.items() if name in PACKAGES and name != package}


def test_packages_found():
    assert {"prisma_msgs", "prisma_common", "prisma_node_wiring", "prisma_hand_sim", "prisma_tactile_driver",
            "prisma_motor_driver", "prisma_force_estimator", "prisma_manipulation", "stag_glove",
            "prisma_teleop", "prisma_hand_emulator", "prisma_sim", "prisma_bringup"} <= set(PACKAGES)


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_module_level_imports_are_declared(package):
    top, _ = imports(package)
    missing = {name: sorted(where) for name, where in workspace(top, package).items() if name not in declared(package)}
    assert not missing, f"{package} imports these workspace packages but package.xml does not declare them: {missing}"


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_no_function_level_imports_of_other_workspace_packages(package):
    _, nested = imports(package)
    found = {name: sorted(where) for name, where in workspace(nested, package).items()}
    assert not found, (f"{package} imports other workspace packages inside functions: {found}; "
                       "import them at module level")


def test_declared_graph_is_acyclic():
    graph = {p: declared(p) & set(PACKAGES) for p in PACKAGES}
    try:
        order = list(TopologicalSorter(graph).static_order())
    except CycleError as exc:
        pytest.fail(f"package.xml dependencies form a cycle: {exc.args[1]}")
    assert order.index("prisma_common") < order.index("prisma_hand_sim") < order.index("prisma_tactile_driver")
    for package in ("prisma_tactile_driver", "prisma_motor_driver", "prisma_force_estimator", "prisma_manipulation",
                    "stag_glove"):
        assert order.index("prisma_node_wiring") < order.index(package) < order.index("prisma_bringup")
    # the drivers are siblings: none needs another to run (their shared wiring is prisma_node_wiring)
    drivers = {"prisma_tactile_driver", "prisma_motor_driver", "stag_glove"}
    for driver in drivers:
        assert not declared(driver) & (drivers - {driver}), f"{driver} depends on another driver"
    # the off-robot sessions run the cores of manipulation, teleop and the glove: above them, and
    # nothing in the workspace depends on prisma_sim (the hand's launch files do not run it)
    for package in ("prisma_manipulation", "prisma_teleop", "stag_glove"):
        assert order.index(package) < order.index("prisma_sim")
    assert not [p for p in PACKAGES if "prisma_sim" in declared(p)]
    # the dataset tool reads bags: no node package depends on it; the launch files do (record.launch.py
    # records the topics it names), as the tools above it may
    dependers = {p for p in PACKAGES if "prisma_dataset" in declared(p)}
    assert "prisma_bringup" in dependers
    assert not dependers & {"prisma_common", "prisma_node_wiring", "prisma_hand_sim", "prisma_tactile_driver",
                            "prisma_motor_driver", "prisma_force_estimator", "prisma_manipulation", "prisma_teleop",
                            "stag_glove", "prisma_hand_emulator"}
    # the policy learns from datasets and drives the hand through Teleoperate: a tool, nothing depends on it
    assert not [p for p in PACKAGES if "prisma_policy" in declared(p)]
    # the emulator stands in for the hardware the drivers talk to: below the launch files that start
    # it, and no node package depends on it (the drivers reach it through their hardware backends)
    assert [p for p in PACKAGES if "prisma_hand_emulator" in declared(p)] == ["prisma_bringup"]
    # it is hardware, not a controller: its worlds (the scenarios' starts included) come from
    # prisma_hand_sim, which the sim runner reads too, not from the controller package above it
    assert not declared("prisma_hand_emulator") & {"prisma_manipulation", "prisma_teleop", "prisma_sim"}


def test_the_ros_free_layers_are_at_the_bottom():
    # prisma_common's only workspace dependency is the interface package whose .msg files its typestore reads
    assert declared("prisma_common") & set(PACKAGES) <= {"prisma_msgs"}
    assert declared("prisma_hand_sim") & set(PACKAGES) == {"prisma_common"}
    for package in ROS_FREE:
        top, nested = imports(package)
        ros = {name: sorted(where) for name, where in {**top, **nested}.items()
               if name in ("rclpy", "rosidl_runtime_py") or name.endswith("_msgs")}
        assert not ros, f"{package} must stay ROS-free, imports {ros}"


# each message's converters sit beside its writer, and its readers import them from there:
# converter -> the package whose node writes the message (HandWrench, WrenchStamped: the force estimator)
CONVERTER_HOMES = {"hand_wrench_samples": "prisma_force_estimator", "hand_wrench_to_msg": "prisma_force_estimator",
                   "wrench_from_msg": "prisma_force_estimator", "wrench_to_msg": "prisma_force_estimator"}


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_message_converters_are_imported_from_the_writers_package(package):
    wrong = []
    for path in sorted((SRC / package / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                for alias in node.names:
                    home = CONVERTER_HOMES.get(alias.name)
                    if home is not None and node.module.split(".")[0] != home:
                        wrong.append(f"{path.relative_to(SRC)}: {alias.name} from {node.module}, not {home}")
    assert not wrong, wrong


def module_imports(package: str, src: Path = SRC) -> dict[str, set[str]]:
    """`package`'s modules -> the modules of the same package each imports (relative or absolute, at
    any level: a function's import or a TYPE_CHECKING one closes a circle as well)."""
    root = src / package
    modules = {".".join(p.relative_to(root).with_suffix("").parts).removesuffix(".__init__"): p
               for p in sorted((root / package).rglob("*.py"))}
    graph: dict[str, set[str]] = {}
    for module, path in modules.items():
        parts = module.split(".")
        # a relative import counts from the module's package (a package's __init__ is its own)
        here = parts if path.name == "__init__.py" else parts[:-1]
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = ".".join(here[:len(here) - node.level + 1] + [node.module or ""]).strip(".") \
                    if node.level else (node.module or "")
                candidates = [base] + [f"{base}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                candidates = [a.name for a in node.names]
            else:
                continue
            found |= {c for c in candidates if c in modules and c != module}
        graph[module] = found
    return graph


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_no_import_circle_inside_a_package(package):
    try:
        list(TopologicalSorter(module_imports(package)).static_order())
    except CycleError as exc:
        pytest.fail(f"{package}'s modules import each other in a circle: {' -> '.join(exc.args[1])}")


def test_the_circle_check_sees_a_type_checking_import(tmp_path):
    package = tmp_path / "src" / "pkg"
    (package / "pkg").mkdir(parents=True)
    (package / "pkg" / "__init__.py").write_text("")
    (package / "pkg" / "a.py").write_text("from .b import B\n")
    (package / "pkg" / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .a import A\n")
    assert module_imports("pkg", tmp_path / "src") == {"pkg": set(), "pkg.a": {"pkg.b"}, "pkg.b": {"pkg.a"}}


ARCHITECTURE = (ROOT / "docs" / "architecture.md").read_text()
ALWAYS_BELOW = {"prisma_common", "prisma_msgs"}  # the drawing leaves them implicit under every package


def drawn_graph() -> dict[str, set[str]]:
    """architecture.md's drawing: lines of `a, b <- c <- d  (note)`, and `all of the above but x`."""
    block = ARCHITECTURE.split("## Package dependencies\n```\n", 1)[1].split("```", 1)[0]
    graph: dict[str, set[str]] = {}
    above: list[str] = []  # every package named on the lines so far
    for line in block.splitlines():
        levels = [level.strip() for level in re.sub(r"\(.*?\)", "", line).split("<-")]
        for lower, upper in zip(levels, levels[1:]):
            names: list[str] = []
            for item in (s.strip() for s in lower.split(",")):
                but = re.fullmatch(r"all of the above but (\w+)", item)
                names += [n for n in above if n != but.group(1)] if but else [item]
            graph.setdefault(upper, set()).update(names)
            above += [n for n in [*names, upper] if n not in above]
    return graph


def below(graph: dict[str, set[str]], package: str) -> set[str]:
    found: set[str] = set()
    todo = [package]
    while todo:
        for dependency in graph.get(todo.pop(), ()):
            if dependency not in found:
                found.add(dependency)
                todo.append(dependency)
    return found - ALWAYS_BELOW


def test_the_workspace_layout_lists_every_package():
    layout = ARCHITECTURE.split("## Workspace layout\n```\n", 1)[1].split("```", 1)[0]
    listed = sorted(re.findall(r"^src/(\w+)/", layout, re.MULTILINE))
    assert listed == PACKAGES, f"docs/architecture.md's layout lists {listed}, src/ holds {PACKAGES}"


def test_the_dependency_drawing_has_the_declared_layering():
    drawn = drawn_graph()
    declared_graph = {p: declared(p) & set(PACKAGES) for p in PACKAGES}
    assert set(drawn) | {n for names in drawn.values() for n in names} == set(PACKAGES)
    for package in PACKAGES:
        assert below(drawn, package) == below(declared_graph, package), (
            f"docs/architecture.md draws {package} above {sorted(below(drawn, package))}, "
            f"its package.xml puts it above {sorted(below(declared_graph, package))}")
