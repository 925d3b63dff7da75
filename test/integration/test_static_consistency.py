"""Static cross-check of launch files, setup.cfg entry points, config YAML, nodes and the topic table.

Data-driven: adding a node (console script in src/<pkg>/setup.cfg), a launch file, a config file or
a topic-table row needs no change here.

1. every executable a launch file starts is a console script of the package the launch file names
   (or, for a ROS package outside the workspace, one prisma_bringup depends on and that installs it);
   its parameter files exist in config/ and address that node by name; every parameter given inline
   in the launch file is declared by the node, literal values with the declared type (and the node
   starts with them); every LaunchConfiguration is a declared launch argument; every included
   launch file exists and declares the arguments passed to it; every launch file returns
   launch_nodes.checked_launch_description (arguments checked, required nodes watched);
2. every parameter in a config file (ros__parameters form, top key = node name, `/**/<node>`) is declared by that
   node, with the same type and the same value as its default; every node name there is a node;
3. every topic of docs/architecture.md's topic table (except /diagnostics) has exactly one
   publishing node, the one in its 'from' column; every action there exactly one action server.

Nodes are found by instantiating the rclpy Node subclass of every console-script module (real
rclpy; those checks skip where ROS is absent) with default parameters and reading what they
declared, published and served (rclpy's own /rosout, /parameter_events and the action servers'
hidden topics left out). A row or entry whose node is no console script fails, naming it (a typo in
`executable=` or in the table).
"""
from __future__ import annotations

import ast
import importlib
import inspect
import re
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import yaml
from setuptools.config.setupcfg import read_configuration

from prisma_testing.launch_files import (
    CONTROL_PATH_NODE,
    NOT_LITERAL,
    LaunchedNode,
    declared_arguments,
    launched_nodes,
    string_literal,
)
from prisma_testing.repo_paths import BRINGUP, CONFIG, LAUNCH, ROOT
from prisma_testing.ros_harness import ROS_AVAILABLE, require_ros
from prisma_testing.topic_table import SHARED_TOPICS, TableRow, topic_table

# ------------------------------------------------------------------------------------------------
# Sources: setup.cfg, launch files, config files, topic table


@dataclass(frozen=True)
class ConsoleScript:
    package: str
    executable: str
    module: str
    function: str


def console_scripts(setup_cfg: Path) -> list[ConsoleScript]:
    """The console scripts a package's setup.cfg declares, as setuptools reads them."""
    config = read_configuration(setup_cfg)
    entries = config["options"].get("entry_points", {}).get("console_scripts", [])
    scripts = []
    for entry in entries:
        executable, _, target = (part.strip() for part in entry.partition("="))
        module, _, function = target.partition(":")
        scripts.append(ConsoleScript(config["metadata"]["name"], executable, module.strip(), function.strip()))
    return scripts


def all_console_scripts() -> dict[tuple[str, str], ConsoleScript]:
    scripts = {}
    for setup_cfg in sorted(ROOT.glob("src/*/setup.cfg")):
        for script in console_scripts(setup_cfg):
            scripts[(script.package, script.executable)] = script
    return scripts


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [c for c in ast.walk(tree) if isinstance(c, ast.Call)
            and getattr(c.func, "id", getattr(c.func, "attr", None)) == name]


def declared_launch_arguments(launch_file: Path) -> set[str]:
    return set(declared_arguments(launch_file))


def used_launch_configurations(launch_file: Path) -> list[tuple[int, str | None]]:
    tree = ast.parse(launch_file.read_text(), filename=str(launch_file))
    used = _calls(tree, "LaunchConfiguration")
    return sorted((c.lineno, string_literal(c.args[0]) if c.args else None) for c in used)


@dataclass(frozen=True)
class Include:
    launch_file: str
    line: int
    target: str | None  # the *.launch.py file name named in the include
    arguments: tuple[str, ...]


def launch_includes(launch_file: Path) -> list[Include]:
    tree = ast.parse(launch_file.read_text(), filename=str(launch_file))
    found = []
    for call in _calls(tree, "IncludeLaunchDescription"):
        names = [c.value for c in ast.walk(call.args[0]) if isinstance(c, ast.Constant)
                 and isinstance(c.value, str) and c.value.endswith(".launch.py")] if call.args else []
        arguments = ()
        for keyword in call.keywords:
            if keyword.arg == "launch_arguments":
                mapping = next((d for d in ast.walk(keyword.value) if isinstance(d, ast.Dict)), None)
                arguments = tuple(string_literal(k) or "<not a literal>" for k in mapping.keys) if mapping else ()
        found.append(Include(launch_file.name, call.lineno, names[0] if len(names) == 1 else None, arguments))
    return found


def all_launched_nodes() -> list[LaunchedNode]:
    return [n for path in sorted(LAUNCH.glob("*.launch.py")) for n in launched_nodes(path)]


def parameter_files() -> dict[str, dict]:
    """config YAML files in ros__parameters form: {relative path: {node key: {param: value}}}."""
    found = {}
    for path in sorted(CONFIG.glob("**/*.y*ml")):
        document = yaml.safe_load(path.read_text())
        if not isinstance(document, dict) or not document:
            continue
        if not all(isinstance(body, dict) and "ros__parameters" in body for body in document.values()):
            continue  # hardware maps and other data files
        per_node = {}
        for key, body in document.items():
            flat: dict = {}
            _flatten("", body["ros__parameters"] or {}, flat)
            per_node[str(key)] = flat
        found[str(path.relative_to(BRINGUP))] = per_node
    return found


def _flatten(prefix: str, values: dict, out: dict) -> None:
    for key, value in values.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            _flatten(name, value, out)
        else:
            out[name] = value


# ------------------------------------------------------------------------------------------------
# Nodes, instantiated


@dataclass
class NodeInfo:
    script: ConsoleScript
    class_name: str = ""
    name: str = ""
    error: str = ""
    parameters: dict = field(default_factory=dict)  # name -> Parameter (default value)
    parameter_types: dict = field(default_factory=dict)  # name -> declared Parameter.Type
    publishers: dict = field(default_factory=dict)  # topic -> [types]
    action_servers: dict = field(default_factory=dict)  # action -> [types]


def _node_class(module) -> type | None:
    from rclpy.node import Node

    classes = [c for _, c in inspect.getmembers(module, inspect.isclass)
               if issubclass(c, Node) and c is not Node and c.__module__ == module.__name__]
    if len(classes) > 1 and hasattr(module, "main"):
        used = inspect.getsource(module.main)
        classes = [c for c in classes if re.search(rf"\b{c.__name__}\s*\(", used)] or classes
    return classes[0] if classes else None


@contextmanager
def _thread_settings_kept() -> Iterator[None]:
    """A node started here must not change process-wide settings for the tests that follow:
    glove_perception sets torch's and the BLAS pools' thread counts for its process."""
    import torch
    from threadpoolctl import threadpool_limits

    torch_threads = torch.get_num_threads()
    with threadpool_limits(limits=None):  # sets nothing; on exit restores every pool's thread count
        try:
            yield
        finally:
            torch.set_num_threads(torch_threads)


# every rclpy node publishes these, and an action server its hidden feedback and status topics
RCLPY_OWN_TOPICS = {"/rosout", "/parameter_events"}


def _inspect_node(script: ConsoleScript, overrides: tuple[tuple[str, str], ...] = ()) -> NodeInfo | None:
    """What the node of `script` declares, publishes and serves, started with default parameters but
    `overrides` (name, value as written)."""
    import rclpy
    from rclpy.parameter import Parameter

    info = NodeInfo(script)
    try:
        module = importlib.import_module(script.module)
    except Exception as exc:  # noqa: BLE001 - reported by the test
        info.error = f"import {script.module} failed: {exc!r}"
        return info
    cls = _node_class(module)
    if cls is None:
        return None  # a ROS-free console script, not a node
    info.class_name = cls.__name__
    with _thread_settings_kept():
        rclpy.init()
        try:
            node = cls(parameter_overrides=[Parameter(n, value=v) for n, v in overrides]) if overrides else cls()
        except Exception as exc:  # noqa: BLE001
            info.error = f"{cls.__name__}() with parameters {dict(overrides) or 'default'} failed: {exc!r}"
            rclpy.shutdown()
            return info
        try:
            from rclpy.action import get_action_server_names_and_types_by_node

            info.name = node.get_name()
            names = node.list_parameters([], 0).names
            for name, descriptor in zip(names, node.describe_parameters(names)):
                info.parameters[name] = node.get_parameter_or(name)
                info.parameter_types[name] = Parameter.Type(descriptor.type)
            fqn = (node.get_name(), node.get_namespace())
            # the graph learns of the node's own endpoints through discovery, one by one: read until
            # /rosout is there and nothing changed for 0.2 s
            seen, stable_since, deadline = None, time.monotonic(), time.monotonic() + 10.0
            while time.monotonic() < deadline:
                now = (dict(node.get_publisher_names_and_types_by_node(*fqn)),
                       dict(get_action_server_names_and_types_by_node(node, *fqn)))
                if now != seen:
                    seen, stable_since = now, time.monotonic()
                elif "/rosout" in now[0] and time.monotonic() - stable_since > 0.2:
                    break
                time.sleep(0.02)
            publishers, info.action_servers = seen
            info.publishers = {name: types for name, types in publishers.items()
                               if name not in RCLPY_OWN_TOPICS and "/_action/" not in name}
        finally:
            node.destroy_node()
            rclpy.shutdown()
    return info


@pytest.fixture(scope="module")
def nodes() -> dict[tuple[str, str], NodeInfo]:
    """(package, executable) -> NodeInfo for every console script that is a node."""
    if not ROS_AVAILABLE:
        require_ros()  # skips (or fails under PRISMA_REQUIRE_ROS=1): nodes start only on real rclpy
    import rclpy

    if rclpy.ok():
        rclpy.shutdown()
    found = {}
    for key, script in all_console_scripts().items():
        info = _inspect_node(script)
        if info is not None:
            found[key] = info
    return found


def _launch_names() -> dict[str, tuple[str, str]]:
    """Node names given in launch files -> (package, executable)."""
    return {n.name: (n.package, n.executable) for n in all_launched_nodes() if n.name and n.package and n.executable}


def _node_named(nodes: dict, node_name: str) -> NodeInfo | None:
    name = node_name.strip("/").rsplit("/", 1)[-1]
    launched = _launch_names().get(name)
    if launched in nodes:
        return nodes[launched]
    return next((info for info in nodes.values() if info.name == name), None)


def _require_started(info: NodeInfo) -> None:
    assert not info.error, f"{info.script.package}/{info.script.executable}: {info.error}"


# ------------------------------------------------------------------------------------------------
# 1. launch files -> console scripts


def _launch_id(entry: LaunchedNode) -> str:
    return f"{entry.launch_file}:{entry.line}:{entry.package}/{entry.executable}"


def _in_workspace(entry: LaunchedNode) -> bool:
    """The node is one of this workspace's (the parameter checks apply), not another ROS package's."""
    return (ROOT / "src" / entry.package).is_dir()


def _check_installed_executable(entry: LaunchedNode) -> None:
    """An executable of another ROS package: prisma_bringup depends on that package, and (with ROS)
    the package installs it."""
    declared = {e.text for e in ET.parse(BRINGUP / "package.xml").getroot()
                if e.tag in ("depend", "exec_depend")}
    assert entry.package in declared, (
        f"{entry.launch_file}:{entry.line}: starts {entry.package}/{entry.executable}, but "
        f"src/prisma_bringup/package.xml does not depend on {entry.package}")
    if ROS_AVAILABLE:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix

        try:
            prefix = Path(get_package_prefix(entry.package))
        except PackageNotFoundError:
            pytest.fail(f"{entry.launch_file}:{entry.line}: ROS package {entry.package} is not installed")
        assert (prefix / "lib" / entry.package / entry.executable).exists(), (
            f"{entry.launch_file}:{entry.line}: {entry.package} has no executable {entry.executable}")


@pytest.mark.parametrize("entry", all_launched_nodes(), ids=_launch_id)
def test_launched_executable_is_a_console_script(entry: LaunchedNode):
    assert entry.package and entry.executable, (
        f"{entry.launch_file}:{entry.line}: package and executable must be string literals")
    scripts = all_console_scripts()
    if (entry.package, entry.executable) in scripts:
        return
    package_dir = ROOT / "src" / entry.package
    if not package_dir.is_dir():  # a ROS package of the robot's install (robot_state_publisher, rviz2)
        _check_installed_executable(entry)
        return
    module_file = package_dir / entry.package / f"{entry.executable}_node.py"
    assert not module_file.exists(), (
        f"{entry.launch_file}:{entry.line}: {module_file.relative_to(ROOT)} exists but "
        f"'{entry.executable}' is not a console script in src/{entry.package}/setup.cfg")
    pytest.fail(f"{entry.launch_file}:{entry.line}: {entry.package}/{entry.executable} is neither a console script of "
                f"src/{entry.package}/setup.cfg nor a module {module_file.relative_to(ROOT)}: a typo in executable=?")


@pytest.mark.parametrize("entry", [e for e in all_launched_nodes() if e.parameter_files], ids=_launch_id)
def test_launched_parameter_files_exist(entry: LaunchedNode):
    assert (entry.package, entry.executable) in all_console_scripts() or not _in_workspace(entry), (
        f"{entry.launch_file}:{entry.line}: {entry.package}/{entry.executable} is not a console script")
    missing = [f for f in entry.parameter_files if not list(CONFIG.glob(f"**/{f}"))]
    assert not missing, f"{entry.launch_file}:{entry.line}: parameter files missing from config/: {missing}"


@pytest.mark.parametrize("entry", [e for e in all_launched_nodes() if e.parameter_files], ids=_launch_id)
def test_launched_parameter_files_address_the_node_by_name(entry: LaunchedNode):
    """A params file whose top key is not the node's name is silently ignored by ROS."""
    files = parameter_files()
    for name in entry.parameter_files:
        matches = [path for path in files if Path(path).name == name]
        if not matches:
            continue  # reported by test_launched_parameter_files_exist
        keys = {key.strip("/").rsplit("/", 1)[-1] for path in matches for key in files[path]}  # /**/<node> too
        assert entry.name in keys or "**" in keys, (
            f"{entry.launch_file}:{entry.line}: {name} has node key(s) {sorted(keys)}, "
            f"the node is named '{entry.name}'")


@pytest.mark.parametrize("entry", [e for e in all_launched_nodes() if e.inline_parameters and _in_workspace(e)],
                         ids=_launch_id)
def test_launched_inline_parameters_are_declared(nodes, entry: LaunchedNode):
    import rclpy
    from rclpy.parameter import Parameter

    info = nodes.get((entry.package, entry.executable))
    assert info is not None, (
        f"{entry.launch_file}:{entry.line}: {entry.package}/{entry.executable} is not a console script")
    _require_started(info)
    problems = []
    for name, value in entry.inline_parameters:
        if name not in info.parameters:
            problems.append(f"'{name}' is not declared by {info.class_name}")
        elif value is not NOT_LITERAL:
            problems += config_problems(info, {name: value})[:1] if Parameter.Type.from_parameter_value(value) \
                != info.parameter_types[name] else []
    assert not problems, f"{entry.launch_file}:{entry.line}: " + "; ".join(problems)
    literals = [(n, v) for n, v in entry.inline_parameters if v is not NOT_LITERAL]
    if literals:  # the node starts with exactly these values (e.g. the sim backends of hand.launch.py)
        module = importlib.import_module(info.script.module)
        if rclpy.ok():
            rclpy.shutdown()
        with _thread_settings_kept():
            rclpy.init()
            try:
                node = getattr(module, info.class_name)(
                    parameter_overrides=[Parameter(n, value=v) for n, v in literals])
                node.destroy_node()
            finally:
                rclpy.shutdown()


@pytest.mark.parametrize("launch_file", sorted(LAUNCH.glob("*.launch.py")), ids=lambda p: p.name)
def test_launch_configurations_are_declared_arguments(launch_file: Path):
    declared = declared_launch_arguments(launch_file)
    undeclared = [(line, name) for line, name in used_launch_configurations(launch_file) if name not in declared]
    assert not undeclared, f"{launch_file.name}: LaunchConfiguration without DeclareLaunchArgument: {undeclared}"


@pytest.mark.parametrize("include", [i for p in sorted(LAUNCH.glob("*.launch.py")) for i in launch_includes(p)],
                         ids=lambda i: f"{i.launch_file}:{i.line}")
def test_included_launch_files_exist_and_declare_their_arguments(include: Include):
    assert include.target, f"{include.launch_file}:{include.line}: include names no *.launch.py literal"
    target = LAUNCH / include.target
    assert target.exists(), f"{include.launch_file}:{include.line}: {include.target} is not in launch/"
    missing = sorted(set(include.arguments) - declared_launch_arguments(target))
    assert not missing, f"{include.launch_file}:{include.line}: {include.target} declares no argument(s) {missing}"


def test_every_launch_file_starts_something():
    files = sorted(LAUNCH.glob("*.launch.py"))
    assert {p.name for p in files} >= {"hand.launch.py", "glove.launch.py", "calibration.launch.py", "all.launch.py"}
    for path in files:
        tree = ast.parse(path.read_text())
        assert _calls(tree, "Node") or _calls(tree, CONTROL_PATH_NODE) or _calls(tree, "IncludeLaunchDescription") \
            or _calls(tree, "ExecuteProcess"), path.name  # record.launch.py: ros2 bag record


@pytest.mark.parametrize("launch_file", sorted(LAUNCH.glob("*.launch.py")), ids=lambda p: p.name)
def test_every_launch_file_starts_whole_or_not_at_all(launch_file: Path):
    """generate_launch_description returns launch_nodes.checked_launch_description (an undeclared
    argument refused, required nodes watched), never a bare LaunchDescription."""
    tree = ast.parse(launch_file.read_text())
    generate = next(f for f in tree.body if isinstance(f, ast.FunctionDef) and f.name == "generate_launch_description")
    returned = [r.value for r in ast.walk(generate) if isinstance(r, ast.Return) and r.value is not None]
    called = [getattr(v.func, "id", getattr(v.func, "attr", None)) for v in returned if isinstance(v, ast.Call)]
    assert called == ["checked_launch_description"], \
        f"{launch_file.name}: generate_launch_description returns {called}, not checked_launch_description(...)"
    assert not _calls(tree, "LaunchDescription"), f"{launch_file.name}: a bare LaunchDescription(...)"


def test_console_scripts_point_at_modules_with_main():
    for (package, executable), script in all_console_scripts().items():
        module_file = ROOT / "src" / package / (script.module.replace(".", "/") + ".py")
        assert module_file.exists(), f"{package}/{executable}: no module {script.module}"
        tree = ast.parse(module_file.read_text())
        functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert script.function in functions, f"{package}/{executable}: {script.module} has no {script.function}()"


def test_every_node_starts_with_default_parameters(nodes):
    failures = [f"{k[0]}/{k[1]}: {info.error}" for k, info in nodes.items() if info.error]
    assert not failures, "\n".join(failures)


def config_problems(info: NodeInfo, values: dict) -> list[str]:
    from rclpy.parameter import Parameter

    """What is wrong with giving `values` (from a config file) to the node `info`."""
    problems = []
    for name, value in values.items():
        declared = info.parameters.get(name)
        if declared is None:
            problems.append(f"'{name}' is not declared by {info.class_name} ({info.name})")
            continue
        try:
            config_type = Parameter.Type.from_parameter_value(value)
        except TypeError as exc:
            problems.append(f"'{name}': {exc}")
            continue
        declared_type = info.parameter_types[name]
        if config_type != declared_type:
            problems.append(f"'{name}': config {value!r} is {config_type.name}, node declares "
                            f"{declared_type.name} (default {declared.value!r})")
        elif name != "use_sim_time" and _plain(declared.value) != _plain(value):
            problems.append(f"'{name}': config {value!r} != node default {declared.value!r}")
    return problems


def _plain(value):
    return list(value) if isinstance(value, (list, tuple)) or hasattr(value, "tolist") else value


# ------------------------------------------------------------------------------------------------
# 2. config parameters -> declared by the node, defaults agree


def _config_entries() -> list[tuple[str, str]]:
    return [(path, key) for path, per_node in parameter_files().items() for key in per_node]


@pytest.mark.parametrize("path,node_key", _config_entries(), ids=lambda v: str(v))
def test_config_parameters_are_declared_with_matching_defaults(nodes, path: str, node_key: str):
    values = parameter_files()[path][node_key]
    if node_key.strip("/") == "**":
        targets = [info for info in nodes.values() if not info.error]
    else:
        info = _node_named(nodes, node_key)
        if info is None:
            launched = _launch_names().get(node_key.strip("/").rsplit("/", 1)[-1])
            assert launched is not None, (
                f"{path}: node '{node_key}' is neither a node of a console script nor named in a launch file")
            pytest.fail(f"{path}: node '{node_key}' is launched as {launched[0]}/{launched[1]}, not a console script")
        _require_started(info)
        targets = [info]
    problems = [problem for info in targets for problem in config_problems(info, values)]
    assert not problems, f"{path} [{node_key}]:\n  " + "\n  ".join(problems)


# ------------------------------------------------------------------------------------------------
# 3. topic table -> exactly one publisher / action server


def _table_id(row: TableRow) -> str:
    return row.name


def _from_another_package(row: TableRow) -> bool:
    """The row's source is a node the launch files start from another ROS package (robot_state_publisher)."""
    launched = _launch_names().get(row.source)
    return launched is not None and not (ROOT / "src" / launched[0]).is_dir()


@pytest.mark.parametrize("row", [r for r in topic_table()
                                 if r.name not in SHARED_TOPICS and not _from_another_package(r)], ids=_table_id)
def test_topic_table_row_has_exactly_one_source(nodes, row: TableRow):
    # 'tactile_driver (backend=sim, contact_source=hand_world)': a topic the node has with those parameters
    match = re.fullmatch(r"(\S+)(?: \((.*)\))?", row.source)
    assert match, f"docs/architecture.md topic table: {row.name}'s source '{row.source}': a node name, then (p=v, ...)"
    source = _node_named(nodes, match.group(1))
    assert source is not None, f"docs/architecture.md topic table: {row.name}'s source '{row.source}' is no node here"
    _require_started(source)
    if match.group(2):
        overrides = tuple(tuple(part.strip().split("=", 1)) for part in match.group(2).split(","))
        assert all(len(o) == 2 for o in overrides), f"{row.name}: parameters of '{row.source}' are not p=v, ..."
        variant = _inspect_node(source.script, overrides)  # type: ignore[arg-type]
        assert variant is not None
        _require_started(variant)
        nodes = {**nodes, (source.script.package, source.script.executable): variant}
        source = variant
    kind = "action servers" if row.is_action else "publishers"
    providers = []
    for info in nodes.values():
        endpoints = info.action_servers if row.is_action else info.publishers
        if row.name in endpoints:
            providers.append((info.name, endpoints[row.name]))
    assert [name for name, _ in providers] == [source.name], (
        f"{row.name}: expected exactly one of {kind}, node '{source.name}'; found {providers or 'none'}")
    assert providers[0][1] == [row.type], f"{row.name}: {source.name} offers {providers[0][1]}, table says {row.type}"


def test_topic_table_parses():
    rows = topic_table()
    assert rows, "docs/architecture.md has no '## Topic table' rows"
    assert {"/diagnostics"} <= {r.name for r in rows}
    assert all(re.fullmatch(r"[a-z_0-9]+/(msg|action|srv)/[A-Za-z0-9]+", r.type) for r in rows), rows


# ------------------------------------------------------------------------------------------------
# The checks themselves, on synthetic sources (so a green run above means something)

_SETUP_CFG = """
[metadata]
name = demo_pkg

[options.entry_points]
console_scripts =
    talker = demo_pkg.talker_node:main
    cli = demo_pkg.cli:main
"""

_LAUNCH = """
from launch import LaunchDescription
from launch_ros.actions import Node
from launch.substitutions import LaunchConfiguration

def generate_launch_description():
    return LaunchDescription([
        Node(package="demo_pkg", executable="talker", name="chatty",
             parameters=["talker.yaml", {"rate": LaunchConfiguration("rate")}]),
        Node(package=LaunchConfiguration("pkg"), executable="x"),
    ])
"""

_INCLUDE = """
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("sim", default_value="true"),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(PathJoinSubstitution(["launch", "demo.launch.py"])),
            launch_arguments={"sim": LaunchConfiguration("sim"), "rate": "10"}.items()),
    ])
"""

_NODE = """
import rclpy
from rclpy.node import Node
from rclpy.action import ActionServer
from std_msgs.msg import String
from prisma_msgs.action import Grasp


class TalkerNode(Node):
    def __init__(self):
        super().__init__("talker")
        self.declare_parameter("rate_hz", 10.0)
        self.declare_parameter("fingers", ["thumb", "index"])
        self.create_publisher(String, "chatter", 10)
        ActionServer(self, Grasp, "/prisma/grasp", lambda goal_handle: Grasp.Result())


def main(args=None):
    rclpy.init(args=args)
    rclpy.spin(TalkerNode())
"""


def test_checks_parse_setup_and_launch_sources(tmp_path):
    (tmp_path / "demo_pkg").mkdir()
    (tmp_path / "demo_pkg" / "setup.cfg").write_text(_SETUP_CFG)
    scripts = console_scripts(tmp_path / "demo_pkg" / "setup.cfg")
    assert scripts == [ConsoleScript("demo_pkg", "talker", "demo_pkg.talker_node", "main"),
                       ConsoleScript("demo_pkg", "cli", "demo_pkg.cli", "main")]
    (tmp_path / "demo.launch.py").write_text(_LAUNCH)
    first, second = launched_nodes(tmp_path / "demo.launch.py")
    assert (first.package, first.executable, first.name, first.parameter_files) == (
        "demo_pkg", "talker", "chatty", ("talker.yaml",))
    assert first.inline_parameters == (("rate", NOT_LITERAL),)
    assert second.package is None  # not a literal: reported by the launch test
    assert used_launch_configurations(tmp_path / "demo.launch.py") == [(9, "rate"), (10, "pkg")]
    assert declared_launch_arguments(tmp_path / "demo.launch.py") == set()  # both undeclared: a test fails
    (tmp_path / "outer.launch.py").write_text(_INCLUDE)
    (include,) = launch_includes(tmp_path / "outer.launch.py")
    assert (include.target, include.arguments) == ("demo.launch.py", ("sim", "rate"))
    assert declared_launch_arguments(tmp_path / "outer.launch.py") == {"sim"}


def test_checks_find_what_a_node_declares_publishes_and_serves(tmp_path, monkeypatch):
    if not ROS_AVAILABLE:
        require_ros()
    import rclpy

    (tmp_path / "demo_static_pkg").mkdir()
    (tmp_path / "demo_static_pkg" / "__init__.py").write_text("")
    (tmp_path / "demo_static_pkg" / "talker_node.py").write_text(_NODE)
    monkeypatch.syspath_prepend(str(tmp_path))
    if rclpy.ok():
        rclpy.shutdown()
    info = _inspect_node(ConsoleScript("demo_static_pkg", "talker", "demo_static_pkg.talker_node", "main"))
    assert not info.error and info.name == "talker" and info.class_name == "TalkerNode"
    assert info.publishers == {"/chatter": ["std_msgs/msg/String"]}
    assert info.action_servers == {"/prisma/grasp": ["prisma_msgs/action/Grasp"]}
    assert config_problems(info, {"rate_hz": 10.0, "fingers": ["thumb", "index"], "use_sim_time": True}) == []
    problems = config_problems(info, {"rate_hz": 10, "fingers": ["thumb"], "unknown": 1})
    assert len(problems) == 3
    assert "INTEGER" in problems[0] and "DOUBLE" in problems[0]
    assert "!= node default" in problems[1] and "not declared" in problems[2]


# ---- one converter signature ------------------------------------------------------------------
def test_every_converter_to_a_message_takes_the_message_lookup_first():
    """`<thing>_to_msg(types, data, ...)` in every package: the lookup first, as rclpy and the
    typestore are the two places messages come from, then the core data."""
    modules = sorted((ROOT / "src").glob("*/*/ros_conversions.py"))
    modules.append(ROOT / "src" / "prisma_common" / "prisma_common" / "diagnostics.py")
    converters = {}
    for path in modules:
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.FunctionDef) and node.name.endswith("_to_msg"):
                converters[f"{path.parent.name}.{node.name}"] = node.args.args[0].arg
    assert len(converters) >= 18
    assert {name: first for name, first in converters.items() if first != "types"} == {}


# ---- one naming scheme ------------------------------------------------------------------------
def test_node_core_config_backend_and_converter_modules_are_named_alike_in_every_package():
    """`<name>_node.py` has its decisions in `<name>_core.py`, its parameters in `node_config.py` and
    its messages in `ros_conversions.py`; a package with hardware backends has the interface in
    `backend.py` and each implementation in `<kind>_backend.py`."""
    problems = []
    nodes = [path for path in sorted((ROOT / "src").glob("*/*/*_node.py")) if path.parent.name != "test"]
    assert len(nodes) == 11
    for node in nodes:
        folder, name = node.parent, node.name.removesuffix("_node.py")
        for expected in (f"{name}_core.py", "node_config.py", "ros_conversions.py"):
            if not (folder / expected).is_file():
                problems.append(f"{node.relative_to(ROOT)} has no {expected} beside it")
    for implementation in [p for p in sorted((ROOT / "src").glob("*/*/*_backend.py")) if p.parent.name != "test"]:
        if not (implementation.parent / "backend.py").is_file():
            problems.append(f"{implementation.relative_to(ROOT)} has no backend.py (the interface) beside it")
    for interface in sorted((ROOT / "src").glob("*/*/backend.py")):
        if len(list(interface.parent.glob("*_backend.py"))) < 2:
            problems.append(f"{interface.relative_to(ROOT)}: an interface with fewer than two backends")
    assert problems == []
