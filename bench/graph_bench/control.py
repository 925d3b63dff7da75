"""The benchmark's own rclpy node: waits for the graph and sends its Grasp and MoveMotors goals. It
subscribes to no sensor topic (the probe is the bag recorder)."""
from __future__ import annotations

import atexit
import functools
import math
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from graph_bench.facts import GRASP, OPEN_RPM
from graph_bench.processes import Proc, check_alive

ROS_HINT = ("needs ROS 2 (source /opt/ros/jazzy/setup.bash, or ../shared/ros2/setup.sh in this repository's "
            "development setup; then colcon build and source install/setup.bash)")


def ros_missing() -> str | None:
    """Why the ROS measurements cannot run here, or None when they can."""
    try:
        import rclpy  # noqa: F401
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
        from prisma_msgs.msg import TaxelArray  # noqa: F401
    except ImportError as exc:
        return f"{ROS_HINT} ({exc})"
    try:
        get_package_share_directory("prisma_bringup")
    except PackageNotFoundError:
        return f"{ROS_HINT} (prisma_bringup is not in AMENT_PREFIX_PATH)"
    if shutil.which("ros2") is None:
        return f"{ROS_HINT} (no ros2 command on PATH)"
    try:
        import mcap  # noqa: F401  (reads the probe's bags: publish and receive times)
    except ImportError:
        return "the probe's bags are read with the mcap package: pip install -e '.[test]'"
    return None


def measured_with_ros(notes: dict, logs: Callable[[], Path], measure: Callable[[], float]) -> float:
    """measure() of a bench/run.py entry, or nan with notes["skipped"] saying why ROS is missing;
    notes["logs"]: the folder of the runs' logs."""
    missing = ros_missing()
    if missing:
        notes["skipped"] = missing
        return math.nan
    notes["logs"] = str(logs())
    return measure()


class Control:
    """An rclpy node in this process, spun on a thread of its own, in a context of its own."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("perf_bench_control", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()
        self._clients: dict[tuple[Any, str], Any] = {}

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except (ExternalShutdownException, self._rclpy.executors.ShutdownException):
            pass

    def close(self) -> None:
        for client in self._clients.values():
            client.destroy()
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=2.0)

    def wait_publishers(self, topics: list[str], timeout_s: float, procs: list[Proc]) -> None:
        """Until every topic has a publisher; fails early when one of `procs` exits."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            check_alive(procs)
            if all(self.node.count_publishers(t) > 0 for t in topics):
                return
            time.sleep(0.2)
        raise RuntimeError(f"timed out after {timeout_s:.0f} s waiting for publishers of "
                           f"{[t for t in topics if self.node.count_publishers(t) == 0]}")

    def _client(self, action_type: Any, name: str) -> Any:
        from rclpy.action import ActionClient

        key = (action_type, name)
        if key not in self._clients:
            self._clients[key] = ActionClient(self.node, action_type, name)
        return self._clients[key]

    @staticmethod
    def _await(future: Any, timeout_s: float) -> Any:
        done = threading.Event()
        future.add_done_callback(lambda f: done.set())
        if not done.wait(timeout_s):
            return None
        return future.result()

    def send(self, action_type: Any, name: str, goal: Any, timeout_s: float) -> tuple:
        """(accepted, accept_stamp_ns, status, result, end_ns) of one goal."""
        client = self._client(action_type, name)
        if not client.wait_for_server(timeout_sec=timeout_s):
            raise RuntimeError(f"action server {name} not available after {timeout_s:.0f} s")
        handle = self._await(client.send_goal_async(goal), timeout_s)
        if handle is None or not handle.accepted:
            return False, 0, None, None, time.time_ns()
        accept_ns = handle.stamp.sec * 1_000_000_000 + handle.stamp.nanosec
        response = self._await(handle.get_result_async(), timeout_s)
        end_ns = time.time_ns()
        if response is None:
            handle.cancel_goal_async()
            return True, accept_ns, None, None, end_ns
        return True, accept_ns, response.status, response.result, end_ns

    def grasp_cycle(self, prefix: str = "") -> dict:
        """One pinch Grasp goal (sent again while refused for now: streams not flowing yet), then
        the hand opened by a MoveMotors position goal. prefix: the hand's namespace ("/left")."""
        from prisma_msgs.action import Grasp, MoveMotors

        from prisma_common.goal_refusal import RETRY_LATER, refusal_code

        deadline = time.monotonic() + 20.0
        while True:
            accepted, accept_ns, status, result, end_ns = self.send(Grasp, f"{prefix}/prisma/grasp",
                                                                    Grasp.Goal(**GRASP), 20.0)
            # the node accepts every goal and aborts one it cannot run yet at once, saying why
            accepted = accepted and not (result is not None and refusal_code(result.reason) in RETRY_LATER)
            if accepted or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        out = {"accepted": accepted, "accept_ns": accept_ns, "end_ns": end_ns,
               "success": bool(result.success) if result is not None else False,
               "reason": result.reason if result is not None else ("rejected" if not accepted else "no result")}
        # at full speed, thumb first, each until its open stop: a fast release keeps the presenting
        # support from letting go, and opening both at once would roll the ball along the pads (the
        # sim world keeps it), ~0.3 mm per grasp, until the pads miss it
        opened = [self.send(MoveMotors, f"{prefix}/prisma/motors/move",
                            MoveMotors.Goal(motors=[motor], mode="velocity", targets=[-OPEN_RPM], timeout=0.0), 20.0)
                  for motor in ("thumb_flexion", "fingers")]
        out["opened"] = all(o[3] is not None and o[3].success for o in opened)
        return out


@functools.cache
def shared_control() -> Control:
    """The one Control of this process (the entries of bench/run.py share it), closed at exit."""
    control = Control()
    atexit.register(control.close)
    return control
