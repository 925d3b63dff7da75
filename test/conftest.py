"""Test setup: real rclpy when it is importable, the in-memory stand-in (test/standin/) otherwise.

Fixtures:
- `ros`: a fresh ROS context for one test (init before, every node destroyed and shutdown after),
  with helpers to run callbacks and move test time; see test/standin/README.md.
- `real_rclpy`: True when the tests run against a real ROS 2 installation.
"""
from __future__ import annotations

import os

# One BLAS/OpenMP thread per process, set before anything loads numpy or torch (they read these at
# load time; subprocesses inherit them). On a busy 2-core machine multi-threaded OpenBLAS spins
# against the other jobs: a 64x1024 PCA fit took 1.7 ms on one thread and 310 ms on two.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

STANDIN_DIR = Path(__file__).resolve().parent / "standin"

try:
    import rclpy  # noqa: F401

    REAL_RCLPY = "standin" not in str(Path(rclpy.__file__).resolve().parent.parent)
except ImportError:
    # The stand-in packages (rclpy, std_msgs, prisma_msgs, ...) shadow nothing: ROS is absent.
    sys.path.insert(0, str(STANDIN_DIR))
    REAL_RCLPY = False


class RealRosHarness:
    """Best-effort `ros` fixture on real rclpy: wall time passes instead of test time."""

    uses_standin = False

    def __init__(self, args=None) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        rclpy.init(args=args)
        self.rclpy = rclpy
        self.context = rclpy.get_default_context()
        self.executor = SingleThreadedExecutor()
        self._probe = None
        self._overrides: list = []

    def now_ns(self) -> int:
        return time.time_ns()

    def add(self, node):
        self.executor.add_node(node)
        return node

    def override(self, node: str = "/**", **params) -> None:
        raise NotImplementedError("pass parameter_overrides=[Parameter(...)] to the node on real rclpy")

    def params_file(self, path) -> None:
        raise NotImplementedError("pass cli_args=['--ros-args', '--params-file', path] on real rclpy")

    def process(self, max_callbacks: int = 10_000, settle_sec: float = 0.2) -> int:
        """Real rclpy cannot tell when nothing is pending: spin for a short wall-clock window."""
        end = time.monotonic() + settle_sec
        count = 0
        while time.monotonic() < end and count < max_callbacks:
            self.executor.spin_once(timeout_sec=0.01)
            count += 1
        return count

    def advance(self, seconds: float) -> int:
        end = time.monotonic() + seconds
        count = 0
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=max(0.0, min(0.01, end - time.monotonic())))
            count += 1
        return count

    def spin_until(self, condition, timeout_sec: float = 10.0, step_sec=None) -> bool:
        done = condition.done if hasattr(condition, "done") else condition
        end = time.monotonic() + timeout_sec
        while not done() and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)
        return bool(done())

    @property
    def probe(self):
        if self._probe is None:
            self._probe = self.add(self.rclpy.create_node("test_probe"))
        return self._probe

    def collect(self, msg_type, topic, qos_profile=10) -> list:
        received: list = []
        self.probe.create_subscription(msg_type, topic, received.append, qos_profile)
        return received

    def publisher(self, msg_type, topic, qos_profile=10):
        return self.probe.create_publisher(msg_type, topic, qos_profile)

    def publish(self, topic, msg, qos_profile=10) -> None:
        publishers = self.__dict__.setdefault("_publishers", {})
        key = (topic, type(msg))
        if key not in publishers:
            publishers[key] = self.publisher(type(msg), topic, qos_profile)
        publishers[key].publish(msg)

    def call(self, srv_type, name, request, timeout_sec: float = 10.0):
        clients = self.__dict__.setdefault("_clients", {})
        if (name, srv_type) not in clients:
            clients[(name, srv_type)] = self.probe.create_client(srv_type, name)
        future = clients[(name, srv_type)].call_async(request)
        self.spin_until(future, timeout_sec)
        return future.result() if future.done() else None

    def action_client(self, action_type, name):
        from rclpy.action import ActionClient

        return ActionClient(self.probe, action_type, name)

    def logs(self, severity=None, name=None, contains=None) -> list:
        return []

    def shutdown(self) -> None:
        for node in self.executor.get_nodes():
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()
        self.rclpy.try_shutdown()


@pytest.fixture
def real_rclpy() -> bool:
    return REAL_RCLPY


@pytest.fixture
def ros():
    """Fresh ROS context per test; nodes created in the test are spun by `ros.executor`."""
    if REAL_RCLPY:
        harness = RealRosHarness()
    else:
        from ros_standin.harness import RosHarness

        harness = RosHarness()
    try:
        yield harness
    finally:
        harness.shutdown()
