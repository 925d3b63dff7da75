"""Which executor a node process spins: the decision, ROS-free (executor.py carries it out).

The fast executor (executor.SingleWaitExecutor) overrides private methods of rclpy's
SingleThreadedExecutor and reads its private state, so it is kept only on an rclpy it has been
proven on, and only when its start-up self-test passes there; everywhere else a node spins rclpy's
stock SingleThreadedExecutor, which rclpy publishes. rclpy 7.1.9 (January 2026) replaced the task
list it relies on with task queues; Humble's `_make_handler` takes a fourth argument.

PRISMA_EXECUTOR asks for one:
- auto (the default): fast where proven and self-tested, stock anywhere else;
- fast: the same, but a refusal says that the request could not be honoured;
- stock: rclpy's SingleThreadedExecutor;
- events: rclpy.experimental.EventsExecutor (rclpy 7.1.4 on), which no test of this suite runs.
"""
from __future__ import annotations

import importlib.metadata
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

EXECUTOR_ENV = "PRISMA_EXECUTOR"
AUTO, FAST, STOCK, EVENTS = "auto", "fast", "stock", "events"
EXECUTOR_REQUESTS = (AUTO, FAST, STOCK, EVENTS)
# rclpy releases the fast executor's tests and benchmarks have run on (the shared build's Jazzy)
PROVEN_RCLPY_VERSIONS = frozenset({"7.1.3"})

# what each kind is, in the log line
EXECUTOR_NAMES = {
    FAST: "SingleWaitExecutor (prisma_node_wiring.executor)",
    STOCK: "rclpy's SingleThreadedExecutor",
    EVENTS: "rclpy.experimental.EventsExecutor, untested in this suite",
}


@dataclass(frozen=True)
class ExecutorChoice:
    kind: str  # FAST, STOCK or EVENTS
    reason: str

    def log_line(self) -> str:
        return f"executor: {self.kind}, {EXECUTOR_NAMES[self.kind]}: {self.reason}"


def requested_executor(env: Mapping[str, str] | None = None) -> str:
    """PRISMA_EXECUTOR's value (auto where unset or empty); ValueError names a value that is none of
    EXECUTOR_REQUESTS."""
    env = os.environ if env is None else env
    value = env.get(EXECUTOR_ENV, "").strip().lower() or AUTO
    if value not in EXECUTOR_REQUESTS:
        raise ValueError(f"{EXECUTOR_ENV}={env[EXECUTOR_ENV]!r} is not an executor: set it to one of "
                         f"{', '.join(EXECUTOR_REQUESTS)} (or leave it unset for {AUTO})")
    return value


def rclpy_version(env: Mapping[str, str] | None = None) -> str | None:
    """The installed rclpy's version: its Python distribution's metadata, else the <version> of the
    package.xml its ament prefix installs (share/rclpy/package.xml on AMENT_PREFIX_PATH); None where
    neither is found."""
    try:
        return importlib.metadata.version("rclpy")
    except importlib.metadata.PackageNotFoundError:
        pass
    env = os.environ if env is None else env
    for prefix in filter(None, env.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        version = package_xml_version(Path(prefix) / "share" / "rclpy" / "package.xml")
        if version is not None:
            return version
    return None


def package_xml_version(path: Path) -> str | None:
    """The <version> of a ROS package.xml, None where the file is absent or has none."""
    try:
        version = ET.parse(path).getroot().findtext("version")
    except (OSError, ET.ParseError):
        return None
    return version.strip() if version and version.strip() else None


def choose_executor(requested: str, version: str | None, fast_self_test: Callable[[], str | None],
                    events_available: bool) -> ExecutorChoice:
    """The executor for a `requested` kind (requested_executor) on rclpy `version`.

    fast_self_test() runs only where the fast executor could be chosen, and returns why it failed
    (None: it passed). events_available: rclpy has rclpy.experimental.EventsExecutor."""
    if requested == STOCK:
        return ExecutorChoice(STOCK, f"{EXECUTOR_ENV}=stock")
    if requested == EVENTS:
        if events_available:
            return ExecutorChoice(EVENTS, f"{EXECUTOR_ENV}=events")
        return ExecutorChoice(STOCK, f"{EXECUTOR_ENV}=events, but rclpy {version or '(version unknown)'} "
                                     "has no rclpy.experimental.EventsExecutor (rclpy 7.1.4 on): falling back")
    asked = f"{EXECUTOR_ENV}=fast, refused: " if requested == FAST else f"{EXECUTOR_ENV}={requested}: "
    if version not in PROVEN_RCLPY_VERSIONS:
        running = f"rclpy {version}" if version else "an rclpy of unknown version"
        proven = ", ".join(sorted(PROVEN_RCLPY_VERSIONS))
        return ExecutorChoice(STOCK, f"{asked}{running} is not one the fast executor is proven on ({proven})")
    failure = fast_self_test()
    if failure is not None:
        return ExecutorChoice(STOCK, f"{asked}the fast executor's self-test failed on rclpy {version}: {failure}")
    return ExecutorChoice(FAST, f"{EXECUTOR_ENV}={requested}: rclpy {version} is proven and the self-test passed")
