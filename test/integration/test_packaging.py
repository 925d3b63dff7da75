"""Packaging: rosdep keys, console scripts, installed data and the wheel.

- every package.xml dependency is a workspace package, a ROS package released for Jazzy or a
  rosdep key with an Ubuntu 24.04 entry (lists below, checked against ros/rosdistro), and every
  third-party module a package imports is declared by its key;
- pyproject.toml's [project.scripts] and the setup.cfg console scripts are one list, and setup.cfg
  installs them where `ros2 run` looks (lib/<package>/);
- prisma_bringup's setup.cfg installs all of its launch/ and config/ under share/prisma_bringup;
- the wheel (`pip install .`) carries the model bundles, the glove layout and the message
  definitions under share/, where share_data finds them, and LICENSE; share_data's lookup order;
- the top-level launch/ and config/ links are walked once (ruff, colcon);
- with the workspace built and sourced: the scripts and data are where ROS looks.
No test here needs the network.
"""
from __future__ import annotations

import ast
import configparser
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Iterable
from pathlib import Path

import pytest
from setuptools.config.setupcfg import read_configuration

from prisma_common import share_data
from prisma_force_estimator.bundle import DEFAULT_BUNDLE, resolve_bundle_path
from prisma_testing.repo_paths import BRINGUP, ROOT
from prisma_testing.ros_harness import require_ros
from stag_glove import paths as glove_paths

SRC = ROOT / "src"
INTEGRATION = ROOT / "test" / "integration"
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / "package.xml").is_file())
PYTHON_PACKAGES = [p for p in PACKAGES if (SRC / p / "setup.cfg").is_file()]

# ros/rosdistro jazzy/distribution.yaml (commit 59a60b4): packages released for Jazzy that a
# package.xml here names. apt: ros-jazzy-<name with - for _>.
JAZZY_ROS_PACKAGES = {
    "action_msgs", "ament_cmake", "ament_index_python", "builtin_interfaces", "control_msgs", "diagnostic_msgs",
    "dynamixel_sdk", "geometry_msgs", "launch", "launch_ros", "launch_testing", "launch_testing_ros", "rcl_interfaces",
    "rclpy", "ros2bag", "rosbag2_storage_mcap", "rosidl_default_generators", "rosidl_default_runtime",
    "rosidl_runtime_py", "sensor_msgs", "std_msgs", "std_srvs", "python_qt_binding", "rqt_plot",
    # (commit 8468e88) the description, TF and RViz side
    "joint_state_publisher", "robot_state_publisher", "rviz2", "tf2_msgs", "tf2_ros_py", "urdfdom_py",
    "visualization_msgs", "xacro",
}
# ros/rosdistro rosdep/python.yaml (commit b045bb7): keys with an apt package for Ubuntu 24.04
# (noble); every one maps to the apt package of the same name there. Not keys: python3-dynamixel-sdk
# (use the ROS package dynamixel_sdk), python3-rosbags (only python3-rosbags-pip, which PEP 668
# refuses on noble: rosbags is pip-installed in the venv, see docs/install.md), pyarrow
# (no key found for it: pip-installed in the venv like rosbags).
NOBLE_ROSDEP_KEYS = {
    "python3-h5py", "python3-hypothesis", "python3-matplotlib", "python3-numpy", "python3-pytest",
    "python3-scipy", "python3-serial", "python3-setuptools", "python3-sklearn", "python3-smbus2",
    "python3-torch", "python3-yaml",
}
# Third-party Python modules the packages import -> the dependency that provides them.
MODULE_DEPENDENCY = {
    "numpy": "python3-numpy", "yaml": "python3-yaml", "serial": "python3-serial",
    "smbus2": "python3-smbus2", "torch": "python3-torch", "scipy": "python3-scipy",
    "sklearn": "python3-sklearn", "threadpoolctl": "python3-sklearn",  # a dependency of scikit-learn
    "h5py": "python3-h5py", "matplotlib": "python3-matplotlib", "dynamixel_sdk": "dynamixel_sdk",
    "urdf_parser_py": "urdfdom_py", "tf2_ros": "tf2_ros_py",
}
# Modules with no rosdep key usable on noble: docs/install.md's venv installs them with pip, and the
# package.xml of a package importing one says so in a comment naming it.
PIP_ONLY = {"rosbags", "pyarrow"}
DEPENDENCY_TAGS = ("depend", "build_depend", "buildtool_depend", "build_export_depend", "exec_depend",
                   "test_depend")


def dependencies(package: str, tags=DEPENDENCY_TAGS) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    return {e.text.strip() for tag in tags for e in root.iter(tag) if e.text and e.text.strip()}


def imported_roots(package: str, folder: str | None = None) -> set[str]:
    """Top-level names of every module a package's Python code (or its `folder`, e.g. test/) imports,
    at module or function level."""
    return roots_imported_by((SRC / package / (folder or package)).rglob("*.py"))


def roots_imported_by(paths: Iterable[Path]) -> set[str]:
    """Top-level names of every module the Python files `paths` import, at module or function level."""
    names = set()
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names.add(node.module.split(".")[0])
    return names


# ---------------------------------------------------------------------------------------------
# rosdep keys

@pytest.mark.parametrize("package", PACKAGES)
def test_every_dependency_resolves_in_rosdep_for_jazzy_on_noble(package):
    unknown = dependencies(package) - set(PACKAGES) - JAZZY_ROS_PACKAGES - NOBLE_ROSDEP_KEYS
    assert not unknown, (
        f"src/{package}/package.xml names {sorted(unknown)}: neither a workspace package, a ROS package "
        f"released for Jazzy nor a rosdep key with a noble entry. Check it in ros/rosdistro "
        f"(jazzy/distribution.yaml, rosdep/python.yaml, rosdep/base.yaml) and add it to the list in "
        f"this test, or drop it and document the pip install in docs/install.md")


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_every_third_party_import_is_declared(package):
    roots = imported_roots(package) - set(sys.stdlib_module_names) - set(PACKAGES) - {"__future__"}
    run_deps = dependencies(package, ("depend", "exec_depend"))
    xml_text = (SRC / package / "package.xml").read_text()
    for module in sorted(roots):
        if module in PIP_ONLY:
            assert module in xml_text, f"{package} imports {module} (pip only): say so in package.xml"
        elif module in MODULE_DEPENDENCY:
            assert MODULE_DEPENDENCY[module] in run_deps, (
                f"{package} imports {module} but package.xml does not exec_depend on "
                f"{MODULE_DEPENDENCY[module]}")
        else:  # a ROS package imported by its own name (rclpy, *_msgs, rosidl_runtime_py, ...)
            assert module in JAZZY_ROS_PACKAGES, (
                f"{package} imports {module}: map it to its rosdep key in MODULE_DEPENDENCY")
            assert module in run_deps, f"{package} imports {module} but package.xml does not declare it"
    check_test_imports_declared(package)


# The shared test helpers (the package prisma_testing in test/support/, on the path pyproject.toml's
# pytest `pythonpath` gives; not installed) and the test runners.
TEST_SUPPORT = {"prisma_testing"}
# bench/'s scripts and its graph_bench package, which tests of bench/ import from that folder: part of
# this repository, not something colcon or rosdep provides
BENCH_MODULES = {path.stem for path in (ROOT / "bench").glob("*.py")} | {
    path.parent.name for path in (ROOT / "bench").glob("*/__init__.py")}
TEST_MODULES = {"pytest": "python3-pytest", "hypothesis": "python3-hypothesis", "setuptools": "python3-setuptools"}
TEST_PIP_ONLY = {"mcap", "mcap_ros2"}  # pyproject.toml's test extra (mcap-ros2-support); no rosdep key


def setup_options(folder: Path) -> dict:
    """[options] of folder/setup.cfg (where each package declares itself; its setup.py is `setup()`), as
    setuptools reads them: data_files globs expanded relative to the folder."""
    return read_configuration(folder / "setup.cfg")["options"]


@pytest.mark.parametrize("folder", [*(SRC / p for p in PYTHON_PACKAGES), INTEGRATION], ids=lambda p: p.name)
def test_setup_py_is_a_bare_setup_call(folder):
    """colcon's ament_python build runs setup.py; all it declares is in setup.cfg, once (a keyword here
    would override it there)."""
    calls = [node for node in ast.walk(ast.parse((folder / "setup.py").read_text())) if isinstance(node, ast.Call)]
    assert [(ast.unparse(c.func), c.args, c.keywords) for c in calls] == [("setup", [], [])]


def check_test_imports_declared(package: str) -> None:
    """`colcon test` runs a package's pytest tests when its setup.cfg names pytest as a test extra
    (tests_require is gone from setuptools 72 on, so colcon would not see it there); what
    src/<package>/test/ imports (workspace packages, ROS packages, third-party modules) is declared
    in package.xml (as test_depend, or already as a run dependency)."""
    extras = setup_options(SRC / package).get("extras_require")
    assert extras == {"test": ["pytest"]}, f"src/{package}/setup.cfg: [options.extras_require] test = pytest"
    if not (SRC / package / "test").is_dir():
        return
    roots = imported_roots(package, "test") - {package}
    declared = dependencies(package, ("depend", "exec_depend", "test_depend"))
    missing = undeclared_test_imports(roots, declared, (SRC / package / "package.xml").read_text())
    assert not missing, f"src/{package}/test imports what src/{package}/package.xml does not declare: {missing}"


def undeclared_test_imports(roots: set[str], declared: set[str], xml_text: str) -> list[str]:
    """What tests importing `roots` need and a package.xml (`declared`, its text `xml_text`) does not
    declare: the rosdep key of each third-party or ROS module, pip-only modules named in a comment."""
    missing = []
    for module in sorted(roots - set(sys.stdlib_module_names) - TEST_SUPPORT - BENCH_MODULES - {"__future__"}):
        if module in PIP_ONLY | TEST_PIP_ONLY:
            if module not in xml_text:
                missing.append(f"{module} (pip only: say so in a comment)")
        else:
            key = {**MODULE_DEPENDENCY, **TEST_MODULES}.get(module, module)
            if key not in declared:
                missing.append(key)
    return missing



def test_integration_tests_are_a_package_colcon_test_runs():
    """test/integration/ is the test-only package prisma_integration_tests, so that `colcon test`
    runs it as it runs src/<package>/test/: pytest as its test extra, and a test_depend on what its
    tests import (colcon builds and sources those before testing it)."""
    root = ET.parse(INTEGRATION / "package.xml").getroot()
    assert root.findtext("name") == "prisma_integration_tests"
    assert (INTEGRATION / "resource" / "prisma_integration_tests").is_file()
    assert setup_options(INTEGRATION).get("extras_require") == {"test": ["pytest"]}
    declared = {e.text.strip() for e in root.iter("test_depend") if e.text}
    missing = undeclared_test_imports(roots_imported_by(INTEGRATION.glob("test_*.py")), declared,
                                      (INTEGRATION / "package.xml").read_text())
    assert not missing, f"test/integration imports what its package.xml does not test_depend on: {missing}"
    unknown = declared - set(PACKAGES) - JAZZY_ROS_PACKAGES - NOBLE_ROSDEP_KEYS
    assert not unknown, f"test/integration/package.xml names {sorted(unknown)}: not resolvable by rosdep"


def _robot_section() -> str:
    text = (ROOT / "docs" / "install.md").read_text()
    start = text.index("## On the robot (ROS 2)")
    return text[start:text.index("\n## ", start + 1)]


def test_the_robot_setup_in_the_docs_matches_the_declared_keys():
    section = _robot_section()
    rosdep = next(line for line in section.splitlines() if line.lstrip().startswith("rosdep install"))
    skipped = set(re.search(r"--skip-keys\s+\"?([\w\- ]+)\"?", rosdep).group(1).split())
    declared = set().union(*(dependencies(p) for p in PACKAGES))
    # one torch: the pip one in the venv, not apt's python3-torch as well
    assert skipped == {"python3-torch"} and skipped <= declared
    pip = " ".join(line for line in section.splitlines() if re.match(r"\s*(python3 -m )?pip install", line))
    # setuptools<80: torch pulls a newer one, whose `develop` has no --editable (--symlink-install)
    for requirement in ("numpy<2", "setuptools<80", "torch==", *PIP_ONLY):
        assert requirement in pip, f"docs/install.md's robot venv does not pip install {requirement}"
    assert "--system-site-packages" in section and "python3 -m colcon build" in section


# ---------------------------------------------------------------------------------------------
# console scripts

def setup_console_scripts(package: str) -> dict[str, str]:
    """name -> 'module:function' from src/<package>/setup.cfg."""
    entries = setup_options(SRC / package).get("entry_points", {}).get("console_scripts", [])
    return {name.strip(): target.strip() for name, target in (e.split("=", 1) for e in entries)}


def pyproject_scripts() -> dict[str, str]:
    tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from Python 3.11")
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]


# console scripts only `ros2 run` knows, under a shorter name than the tool's own on PATH
ROS2_RUN_ALIASES = {"doctor": "prisma-doctor"}  # ros2 run prisma_bringup doctor


def test_pyproject_scripts_are_the_setup_cfg_scripts_less_the_nodes():
    union: dict[str, str] = {}
    for package in PYTHON_PACKAGES:
        for name, target in setup_console_scripts(package).items():
            assert name not in union, f"console script {name} is in two setup.cfg files"
            union[name] = target
            # ros2 run <package> <name>: the script must be in the setup.cfg of its module's package
            assert target.split(".")[0] == package, f"{name} -> {target} is in src/{package}/setup.cfg"
    nodes = {name for name, target in union.items() if target.split(":")[0].endswith("_node")}
    # `ros2 run <package> <short name>` beside a tool's own name: the same entry point, kept off PATH
    for alias, tool in ROS2_RUN_ALIASES.items():
        assert union.pop(alias) == union[tool], f"ros2 run alias {alias} is not {tool}"
    assert {name: union[name] for name in sorted(set(union) - nodes)} == dict(sorted(pyproject_scripts().items()))
    # the three tactile CLIs that once were only in pyproject.toml
    assert {"prisma-tactile-calset", "prisma-tactile-pad-plot", "prisma-tactile-hub-emulator"} <= set(
        setup_console_scripts("prisma_tactile_driver"))


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_setup_cfg_installs_scripts_where_ros2_run_looks(package):
    cfg = configparser.ConfigParser()
    cfg.read(SRC / package / "setup.cfg")
    assert cfg.get("develop", "script_dir") == f"$base/lib/{package}"  # colcon --symlink-install
    assert cfg.get("install", "install_scripts") == f"$base/lib/{package}"  # colcon build


# ---------------------------------------------------------------------------------------------
# launch/ and config/ in prisma_bringup's colcon install

def repo_files(*folders: str) -> set[str]:
    """The files of prisma_bringup's `folders` (launch/, config/), relative to the package."""
    return {str(p.relative_to(BRINGUP)) for folder in folders for p in (BRINGUP / folder).rglob("*")
            if p.is_file() and "__pycache__" not in p.parts}


def bringup_data_files(monkeypatch, cwd: Path) -> dict[str, Path]:
    """share path -> source file of prisma_bringup's setup.cfg data_files, read from `cwd`."""
    monkeypatch.chdir(cwd)
    return {os.path.join(dest, os.path.basename(src)): (BRINGUP / src).resolve()
            for dest, sources in setup_options(BRINGUP)["data_files"] for src in sources}


@pytest.mark.parametrize("where", ["package directory", "elsewhere"])
def test_bringup_installs_all_of_launch_and_config(monkeypatch, tmp_path, where):
    # setup.cfg's globs are relative to its folder (colcon runs setup.py there, or in build/ among
    # links to each file with --symlink-install), whatever the working directory: a new launch or
    # config file is installed; a new folder needs its line in setup.cfg.
    cwd = SRC / "prisma_bringup" if where == "package directory" else tmp_path
    installed = bringup_data_files(monkeypatch, cwd)
    expected = {f"share/prisma_bringup/{rel}": BRINGUP / rel for rel in repo_files("launch", "config")}
    assert "launch/hand.launch.py" in repo_files("launch") and "config/manipulation.yaml" in repo_files("config")
    assert {k: v for k, v in installed.items() if k in expected} == expected
    assert "share/prisma_bringup/config/glove/layout.yaml" in installed
    assert "share/prisma_bringup/config/models/cnn2/model.pt" in installed


def test_the_top_level_links_are_walked_once():
    """launch/ and config/ at the root are links to prisma_bringup's folders: ruff checks each launch
    file once (by its path in the package) and colcon finds each package once."""
    ruff = subprocess.run([sys.executable, "-m", "ruff", "check", "--show-files", "."], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    if ruff.returncode != 0 and "No module named ruff" in ruff.stderr:
        pytest.skip("ruff is not installed (pip install -e '.[test]')")
    checked = [Path(line) for line in ruff.stdout.splitlines() if line.endswith(".py")]
    launch_files = [p.resolve() for p in checked if p.name.endswith(".launch.py")]
    in_packages = sorted(p.resolve() for p in SRC.glob("*/launch/*.launch.py"))  # bringup's, the description's
    assert sorted(launch_files) == in_packages  # each once, by its path in its package
    if shutil.which("colcon"):
        listed = subprocess.run(["colcon", "list", "--names-only"], cwd=ROOT, capture_output=True, text=True,
                                timeout=120).stdout.split()
        assert sorted(listed) == sorted([*PACKAGES, "prisma_integration_tests"])


# ---------------------------------------------------------------------------------------------
# the wheel

WHEEL_SHARE = {  # share path in the wheel -> files of the repository
    "share/prisma_bringup/": repo_files("config"),
    "share/prisma_msgs/": {str(p.relative_to(SRC / "prisma_msgs")) for p in
                           [*(SRC / "prisma_msgs" / "msg").glob("*.msg"),
                            *(SRC / "prisma_msgs" / "action").glob("*.action"),
                            *(SRC / "prisma_msgs" / "srv").glob("*.srv")]},
}


def _bdist_wheel_builtin() -> bool:
    try:
        import setuptools
    except ImportError:
        return False
    major, minor = (int(x) for x in setuptools.__version__.split(".")[:2])
    return (major, minor) >= (70, 1)


@pytest.fixture(scope="module")
def wheel_names(tmp_path_factory) -> set[str]:
    """Names in the wheel `pip wheel .` builds, from a copy of the sources (setuptools writes
    build/ and *.egg-info beside pyproject.toml, where colcon keeps its build/)."""
    work = tmp_path_factory.mktemp("wheel")
    tree = work / "tree"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    shutil.copytree(SRC, tree / "src", ignore=ignore)
    shutil.copytree(ROOT / "test" / "support", tree / "test" / "support", ignore=ignore)  # to be left out
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / name, tree / name)
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(work / "dist"), str(tree)]
    # setuptools >= 70.1 builds wheels itself: no isolated build env, so no download
    if _bdist_wheel_builtin():
        cmd.insert(cmd.index("--no-deps"), "--no-build-isolation")
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    (wheel,) = (work / "dist").glob("prisma_hand_suite-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        return set(zf.namelist())


def test_wheel_carries_bundles_layout_and_message_definitions(wheel_names):
    data = {n.split(".data/data/", 1)[1] for n in wheel_names if ".data/data/" in n}
    for prefix, files in WHEEL_SHARE.items():
        shipped = {n[len(prefix):] for n in data if n.startswith(prefix)}
        assert shipped == files, f"{prefix}: missing {sorted(files - shipped)}, extra {sorted(shipped - files)}"
    assert {"config/models/cnn2/model.pt", "config/models/glove_object/metadata.json",
            "config/glove/layout.yaml"} <= WHEEL_SHARE["share/prisma_bringup/"]
    assert {"msg/TaxelArray.msg", "action/Grasp.action"} <= WHEEL_SHARE["share/prisma_msgs/"]
    assert "prisma_common/share_data.py" in wheel_names
    # the Apache-2.0 text in the wheel's metadata (setuptools picks LICENSE up by name)
    assert any(n.split("/")[0].endswith(".dist-info") and n.endswith("/LICENSE") for n in wheel_names)


def test_the_wheel_ships_the_suite_not_its_test_support(wheel_names):
    """`pip install .` installs the packages a lab runs; prisma_testing (test/support/) serves the tests
    and bench/ of a checkout, from its folder."""
    top_level = {name.split("/")[0] for name in wheel_names if "/" in name}
    assert "prisma_testing" not in top_level, "the wheel carries prisma_testing: drop test/support from pyproject"
    assert {"prisma_common", "prisma_manipulation", "prisma_bringup"} <= top_level


# ---------------------------------------------------------------------------------------------
# share_data: source tree, colcon install, wheel prefix

def test_share_data_recognises_the_source_tree(tmp_path):
    assert share_data.source_root(SRC / "prisma_common" / "prisma_common" / "share_data.py") == ROOT
    # a colcon install or a wheel: no repository around the module
    site = tmp_path / "lib" / "python3" / "site-packages" / "prisma_common" / "share_data.py"
    assert share_data.source_root(site) is None


def test_share_data_looks_in_the_source_tree_first(monkeypatch):
    # (the module may be imported from a colcon install here, where SOURCE_ROOT is None)
    monkeypatch.setattr(share_data, "SOURCE_ROOT", ROOT)
    assert share_data.package_directories("prisma_msgs")[0] == SRC / "prisma_msgs"
    assert share_data.package_directories("prisma_bringup")[0] == BRINGUP
    assert share_data.find(DEFAULT_BUNDLE, ["prisma_bringup"]) == BRINGUP / DEFAULT_BUNDLE
    assert share_data.find("config/nothing_here", ["prisma_bringup"]) is None


def _install(prefix: Path, package: str, relative: str, text: str = "x") -> Path:
    path = prefix / "share" / package / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.fixture
def installed(monkeypatch, tmp_path):
    """No source tree; a colcon install prefix and a Python (wheel) prefix under tmp_path."""
    colcon, wheel = tmp_path / "install" / "prisma_bringup", tmp_path / "venv"
    monkeypatch.setattr(share_data, "SOURCE_ROOT", None)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(colcon))
    monkeypatch.delenv("PRISMA_MSGS_DIR", raising=False)
    monkeypatch.setattr(sys, "prefix", str(wheel))
    monkeypatch.chdir(tmp_path)
    return colcon, wheel


def test_share_data_finds_a_wheel_install(installed):
    from prisma_common.typestore import find_interface_dir

    _, wheel = installed
    bundle = _install(wheel, "prisma_bringup", "config/models/cnn2/metadata.json").parent
    layout = _install(wheel, "prisma_bringup", "config/glove/layout.yaml")
    _install(wheel, "prisma_msgs", "msg/TaxelArray.msg")
    assert resolve_bundle_path(DEFAULT_BUNDLE) == bundle
    assert glove_paths.resolve("config/glove/layout.yaml") == layout
    assert find_interface_dir() == wheel / "share" / "prisma_msgs"


def test_share_data_prefers_the_colcon_install_to_the_wheel(installed):
    colcon, wheel = installed
    _install(wheel, "prisma_bringup", "config/models/cnn2/metadata.json")
    bundle = _install(colcon, "prisma_bringup", "config/models/cnn2/metadata.json").parent
    assert resolve_bundle_path(DEFAULT_BUNDLE) == bundle
    # the glove package's own share comes before prisma_bringup's
    _install(colcon, "prisma_bringup", "config/glove/layout.yaml")
    own = _install(colcon, "stag_glove", "config/glove/layout.yaml")
    assert glove_paths.resolve("config/glove/layout.yaml") == own


def test_missing_shipped_file_names_every_place_looked(installed):
    colcon, wheel = installed
    with pytest.raises(FileNotFoundError) as err:
        glove_paths.resolve("config/glove/layout.yaml")
    message = str(err.value)
    for place in (colcon / "share" / "stag_glove", colcon / "share" / "prisma_bringup",
                  wheel / "share" / "prisma_bringup"):
        assert str(place / "config" / "glove" / "layout.yaml") in message
    # a bundle that is nowhere comes back as given, for load_bundle to report
    assert resolve_bundle_path(DEFAULT_BUNDLE) == Path(DEFAULT_BUNDLE)


# ---------------------------------------------------------------------------------------------
# the built and sourced workspace (ROS only)

@pytest.fixture
def ament():
    require_ros()  # skips, or fails under PRISMA_REQUIRE_ROS=1
    from ament_index_python import packages

    return packages


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_every_console_script_is_where_ros2_run_finds_it(ament, package):
    lib = Path(ament.get_package_prefix(package)) / "lib" / package
    for name in setup_console_scripts(package):
        script = lib / name
        assert script.is_file() and os.access(script, os.X_OK), (
            f"ros2 run {package} {name}: {script} missing; rebuild with colcon build")


def test_launch_config_and_definitions_are_installed(ament):
    bringup = Path(ament.get_package_share_directory("prisma_bringup"))
    for rel in sorted(repo_files("launch", "config")):
        installed = bringup / rel
        assert installed.is_file(), f"{installed} missing; rebuild prisma_bringup with colcon build"
        assert installed.read_bytes() == (BRINGUP / rel).read_bytes(), f"{installed} differs from {rel}"
    msgs = Path(ament.get_package_share_directory("prisma_msgs"))
    for rel in WHEEL_SHARE["share/prisma_msgs/"]:
        assert (msgs / rel).read_bytes() == (SRC / "prisma_msgs" / rel).read_bytes()
