"""Test setup for every test: unit tests in src/<package>/test/, the rest in test/integration/
(pytest finds this file above both, from the repository root and under `colcon test`, which runs
pytest in src/<package>/ with this repository's pyproject.toml as its configuration).

Fixture `ros`: a fresh rclpy context for one test on real ROS 2 (see ros_harness.py); tests using it
skip with the reason where ROS 2 and the built workspace are not sourced.

A test that fails keeps the full output of every process its file launched or started (launch tests'
nodes, RViz's stderr included; `ros2 launch` and other commands it ran): written whole to
test-results/launch-logs/<test id>.log (or $PRISMA_LAUNCH_LOG_DIR), the failure message naming the file.
"""
from __future__ import annotations

import gc
import os
import re

# One BLAS/OpenMP thread per process, set before anything loads numpy or torch (they read these at
# load time; subprocesses inherit them). On a busy 2-core machine multi-threaded OpenBLAS spins
# against the other jobs: a 64x1024 PCA fit took 1.7 ms on one thread and 310 ms on two.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
# rclpy's generated messages check every field assignment (as Humble always does; Jazzy reads this
# when a message module is imported), so a converter that fills a field wrongly fails here, not on
# the robot. Subprocesses (launched nodes) inherit it.
os.environ.setdefault("ROS_PYTHON_CHECK_FIELDS", "1")

import pytest  # noqa: E402

from prisma_testing.launch_case import failure_note, forget_launched_output  # noqa: E402
from prisma_testing.left_behind import mark_this_run, started_by_this_run, stop_left_behind  # noqa: E402
from prisma_testing.ros_harness import ROS_AVAILABLE, process_domain_id, require_ros  # noqa: E402

mark_this_run()  # before any test starts a process: they inherit it (left_behind.py)

if ROS_AVAILABLE:
    # Before any rclpy.init and before launch tests start their processes (they inherit it).
    os.environ["ROS_DOMAIN_ID"] = str(process_domain_id())


@pytest.hookimpl(tryfirst=True)
def pytest_pycollect_makemodule(module_path, parent):
    """Test modules that are not launch tests are collected here, in the import mode of
    pyproject.toml (importlib: test files of different packages share names, e.g. test_cli.py).
    launch_testing's collection hook (ROS sourced) imports every test module by its bare name to look
    for generate_test_description, which fails on the second test_cli.py; only the launch tests go
    to it."""
    if module_path.name == "__init__.py" or _LAUNCH_TEST.search(module_path.read_text(errors="replace")):
        return None
    return pytest.Module.from_parent(parent, path=module_path)


_LAUNCH_TEST = re.compile(r"^(def generate_test_description\(|generate_test_description = )", re.M)


@pytest.fixture
def ros():
    """Fresh rclpy context per test; the nodes made with `ros.node` are spun by `ros.executor`."""
    require_ros()
    from prisma_testing.ros_harness import RosHarness

    harness = RosHarness()
    try:
        yield harness
    finally:
        harness.shutdown()


def pytest_collection_modifyitems(config, items):
    """launch_testing runs each launch in debug mode when pytest's verbosity is truthy, and the
    README's `pytest -q` gives -1: asyncio's debug mode (every callback timed, every coroutine's
    origin kept) and a DEBUG line per launch event, in the pytest process that also spins the test's
    probes. On 2 cores beside a running graph that is CPU the graph needs, so debug mode here
    follows -v only."""
    debug = config.getoption("verbose") > 0
    for item in items:
        runner_cls = getattr(item, "runner_cls", None)
        if runner_cls is not None:
            item.runner_cls = _runner_with_debug(runner_cls, debug)


def _runner_with_debug(runner_cls, debug: bool):
    def make(*args, **kwargs):
        kwargs["debug"] = debug
        return runner_cls(*args, **kwargs)
    return make


_current_file: list = [None]
_running_at_file_start: set[int] = set()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """A new test file: what the previous one launched or started is not its output (before the
    file's fixtures start processes of its own)."""
    if item.path != _current_file[0]:
        _current_file[0] = item.path
        forget_launched_output()
        _running_at_file_start.clear()
        _running_at_file_start.update(started_by_this_run())


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item, nextitem):
    """The end of a test file (its fixtures torn down): a process it started and left running is
    killed, and the file's last test fails naming it, instead of the later tests it would starve.
    Its garbage is collected then and what outlives it frozen out of later collections (below)."""
    yield
    if nextitem is None or nextitem.path != item.path:
        # Python's full collection walks every object this process holds: after twenty launch tests
        # (half a million objects: their collections, rclpy's entities) one took 3.0 s of the main
        # thread on a quiet machine, inside test_launch_hand_tf, and beside the load harness long
        # enough that the test's streams looked silent for 10 s. Collected here, between files, and
        # the survivors frozen, a test's collections walk only what it made itself.
        gc.collect()
        gc.freeze()
        left = stop_left_behind(_running_at_file_start)
        if left:
            listed = "; ".join(f"{pid}: {command[:200]}" for pid, command in sorted(left.items()))
            raise AssertionError(f"{item.path.name} left {len(left)} process(es) running, now killed: {listed}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failed test (its call, or its fixtures' setup or teardown): the full output of what it
    launched goes to a file, and the failure message names it (a later phase's failure rewrites it
    with the output up to then)."""
    outcome = yield
    report = outcome.get_result()
    if report.failed:
        note = failure_note(item.nodeid)
        if note is not None:
            report.longrepr = f"{report.longrepr}\n\n{note}"
