"""What the launch tests share: the launch description a test starts, the test class on one
RosHarness, the checks of what a graph did (the touch limit) and after it stopped, and every launched
process's full output kept in a file when a test fails.

    generate_test_description = launch_test("hand.launch.py", sim="true")

    class TestHand(GraphTestCase):
        @classmethod
        def subscribe(cls, ros):
            cls.joints = ...  # ros.collect(...), ros.action_client(...): what every test of the class uses

Kept output: `graph_under_test` registers a handler for every process's stdout and stderr (RViz's
included) of the launch; `ros2 launch` and other commands a plain pytest test starts are NodeProcesses
(node_process), which keep their own. When a test fails, the root conftest.py writes all of it whole
to `launch_log_path(<test id>)` and names the file in the failure message.
"""
from __future__ import annotations

import math
import os
import re
import tempfile
import time
import unittest
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_testing.node_process import NodeProcess
from prisma_testing.repo_paths import ROOT, node_parameters
from prisma_testing.ros_harness import RosHarness, joint, stamp_ns

LOG_DIR_VARIABLE = "PRISMA_LAUNCH_LOG_DIR"
# rclpy's field checks (the root conftest.py turns them on for this process) cost the idle sim graph a
# quarter more CPU (0.65 -> 0.82 cores on a 2-core VM, /proc over 10 s) on the cores the test's own
# process needs to keep up with the streams. The converters and nodes are checked with them on where
# they run in the test's process (src/*/test, RosHarness); the launched graph runs as the robot does.
LAUNCHED_FIELD_CHECKS = "0"

# process name ('motor_driver-2') -> its output so far, and its exit code once it exited; filled by
# the handlers graph_under_test registers, emptied by the conftest when a test file starts
_launched_output: dict[str, list[str]] = {}
_launched_exit: dict[str, int | None] = {}


# ---- the launch description -------------------------------------------------------------------------
def include_launch(launch_file: str, package: str = "prisma_bringup", **arguments: str):
    """An installed launch file (`share/<package>/launch/<launch_file>`) with `name:=value` arguments,
    for a launch test's generate_graph_under_test, as `ros2 launch <package> <launch_file>` starts it."""
    from launch.actions import IncludeLaunchDescription
    from launch.launch_description_sources import PythonLaunchDescriptionSource
    from launch.substitutions import PathJoinSubstitution
    from launch_ros.substitutions import FindPackageShare

    return IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([FindPackageShare(package), "launch", launch_file])),
        launch_arguments=arguments.items())


def installed_config() -> Path:
    """config/ of the installed prisma_bringup: the parameter files hand.launch.py gives its nodes."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("prisma_bringup")) / "config"


def installed_parameters(node: str) -> dict[str, Any]:
    """The node's parameters in the installed config/<node>.yaml, nested ones flattened as ROS names
    them (a.b)."""
    flat: dict[str, Any] = {}

    def walk(prefix: str, values: dict[str, Any]) -> None:
        for key, value in values.items():
            if isinstance(value, dict):
                walk(f"{prefix}{key}.", value)
            else:
                flat[f"{prefix}{key}"] = value
    walk("", node_parameters(installed_config() / f"{node}.yaml", node))
    return flat


def graph_under_test(*actions: Any):
    """generate_graph_under_test's LaunchDescription: `actions`, every process's output kept (for the
    file a failing test names), then ReadyToTest. The launched nodes run as on the robot, without
    rclpy's field checks (LAUNCHED_FIELD_CHECKS)."""
    import launch
    import launch_testing.actions
    from launch.actions import RegisterEventHandler, SetEnvironmentVariable
    from launch.event_handlers import OnProcessExit, OnProcessIO

    def keep(event: Any) -> None:
        _launched_output.setdefault(event.process_name, []).append(event.text.decode(errors="replace"))

    def exited(event: Any, _context: Any) -> None:
        _launched_exit[event.process_name] = event.returncode

    return launch.LaunchDescription([
        SetEnvironmentVariable("ROS_PYTHON_CHECK_FIELDS", LAUNCHED_FIELD_CHECKS),
        RegisterEventHandler(OnProcessIO(on_stdout=keep, on_stderr=keep)),
        RegisterEventHandler(OnProcessExit(on_exit=exited)),
        *actions,
        launch_testing.actions.ReadyToTest()])


def launch_test(launch_file: str, package: str = "prisma_bringup", **arguments: str) -> Callable[[], Any]:
    """A launch test file's entry point, `generate_test_description = launch_test("hand.launch.py",
    sim="true")`: the installed launch file with these arguments under graph_under_test (a file whose
    launch needs more, a folder made first, writes its own generate_test_description)."""
    import pytest

    @pytest.mark.launch_test
    def generate_test_description():
        return graph_under_test(include_launch(launch_file, package, **arguments))
    return generate_test_description


def emulated_hand_launch(emulator_dir: Path, **arguments: str):
    """generate_graph_under_test's LaunchDescription for `hand.launch.py hardware:=emulated home:=true`
    with its devices in `emulator_dir` (created here): the servos come up as real ones do, without
    their turn count, and are homed at start (`emulated_launch.wait_until_homed`)."""
    emulator_dir.mkdir(exist_ok=True)
    return graph_under_test(include_launch("hand.launch.py", hardware="emulated", home="true",
                                           emulator_dir=str(emulator_dir), **arguments))


# ---- the test class -----------------------------------------------------------------------------------
class GraphTestCase(unittest.TestCase):
    """A launch test's class on one RosHarness: made (logs captured) before its tests, shut down after
    them (with every client and subscription it made). `subscribe(ros)` adds what the class collects
    and the clients it uses (ros.collect, ros.action_client), as class attributes."""

    ros: RosHarness

    @classmethod
    def setUpClass(cls) -> None:
        ros = cls.ros = RosHarness()
        try:
            ros.capture_logs()
            cls.subscribe(ros)
        except BaseException:
            ros.shutdown()
            raise

    @classmethod
    def subscribe(cls, ros: RosHarness) -> None:
        """Collections and clients of the class, as class attributes."""

    @classmethod
    def tearDownClass(cls) -> None:
        cls.ros.shutdown()


class MotorPositions:
    """For a GraphTestCase whose subscribe() sets `cls.joints` (a /joint_states collection): where the
    motors stand, and that they reach targets."""

    JOINT_STATES_WAIT_S = 10.0  # for the next /joint_states

    def positions(self) -> dict[str, float]:
        """Where the motors stood in the first /joint_states published from now on."""
        last = self.ros.message_at(self.joints, 0.0, timeout_sec=self.JOINT_STATES_WAIT_S)  # type: ignore[attr-defined]
        return {m: joint(last, m) for m in MOTOR_NAMES}

    def assert_reaches(self, targets: dict[str, float], tolerance: float, timeout_sec: float) -> dict[str, float]:
        """The motors' positions once each of `targets` is within `tolerance` (rad); AssertionError
        naming the motors still off it at the timeout."""
        deadline = time.monotonic() + timeout_sec
        while True:
            at = self.positions()
            off = {m: round(at[m], 3) for m, v in targets.items() if abs(at[m] - v) > tolerance}
            if not off:
                return at
            if time.monotonic() > deadline:
                raise AssertionError(f"not within {tolerance} rad of {targets} after {timeout_sec} s: {off}")
            self.ros.spin_for(0.1)  # type: ignore[attr-defined]


# ---- after the launch ---------------------------------------------------------------------------------
def pad_force_peaks(hand_wrenches: Sequence, since_ns: int, fingers: Sequence[str] = FINGERS) -> dict[str, float]:
    """Each pad's highest estimated Fz in a /prisma/hand/wrench collection, over its own estimates
    stamped `since_ns` or later (a HandWrench's header is the newest of its pads' stamps);
    AssertionError naming the fingers with none."""
    from prisma_force_estimator.ros_conversions import hand_wrench_samples

    peaks: dict[str, float] = {}
    for message in hand_wrenches:
        for finger, wrench in hand_wrench_samples(message):
            if stamp_ns(wrench) >= since_ns:
                peaks[finger] = max(peaks.get(finger, -math.inf), wrench.wrench.force.z)
    missing = [f for f in fingers if f not in peaks]
    if missing:
        raise AssertionError(f"no wrench of {', '.join(missing)} stamped at or after {since_ns} ns "
                             f"in {len(hand_wrenches)} HandWrench messages")
    return {f: peaks[f] for f in fingers}


def touch_limit_n() -> float:
    """teleop_max_pad_force of the installed config/manipulation.yaml: the launched manipulation node's
    touch limit, where a teleoperated close stops each pad (N)."""
    return float(installed_parameters("manipulation")["teleop_max_pad_force"])


def assert_touch_limited(peaks: dict[str, float], reached_n: float | None = None,
                         fingers: Sequence[str] = ("thumb", "index")) -> None:
    """A close on the pinch ball stopped by the touch limit: no pad's peak estimated Fz (`pad_force_peaks`)
    more than prisma-sim's force tolerance above `touch_limit_n`, and `fingers` (the two the ball sits
    between) at `reached_n` or more (default: within 0.1 N of the limit)."""
    from prisma_sim.sim_runner import FORCE_TOLERANCE_N

    limit = touch_limit_n()
    reached = limit - 0.1 if reached_n is None else reached_n
    over = {f: round(p, 3) for f, p in peaks.items() if p > limit + FORCE_TOLERANCE_N}
    short = {f: round(peaks[f], 3) for f in fingers if peaks[f] < reached}
    assert not over and not short, (f"pads above {limit} + {FORCE_TOLERANCE_N} N: {over}; {', '.join(fingers)} "
                                    f"below {reached:.3f} N: {short}")


def touch_limited_peaks(hand_wrenches: Sequence, since_ns: int, reached_n: float | None = None) -> dict[str, float]:
    """Each pad's peak estimated Fz in a /prisma/hand/wrench collection since `since_ns`
    (`pad_force_peaks`), printed with its overshoot of the touch limit and checked
    (`assert_touch_limited`): what a teleoperated close on the pinch ball must show."""
    peaks = pad_force_peaks(hand_wrenches, since_ns)
    print(f"pad Fz peaks { {f: round(v, 3) for f, v in peaks.items()} }, overshoot "
          f"{max(peaks.values()) - touch_limit_n():+.3f} N of the {touch_limit_n()} N touch limit")
    assert_touch_limited(peaks, reached_n)
    return peaks


def process_outputs(proc_output: Any) -> dict[str, str]:
    """A launch test's captured output, stdout and stderr together, per process name ('motor_driver-2')."""
    texts: dict[str, list[str]] = {}
    for event in proc_output:
        texts.setdefault(event.process_name, []).append(event.text.decode(errors="replace"))
    return {name: "".join(parts) for name, parts in texts.items()}


def output_of(proc_output: Any, node: str) -> str:
    """The captured output of the one process launched for `node` (named '<node>-<n>' by launch)."""
    (text,) = [text for name, text in process_outputs(proc_output).items() if name.rsplit("-", 1)[0] == node]
    return text


def assert_clean_shutdown(proc_info: Any, proc_output: Any) -> None:
    """Post-shutdown check of a launch test (launch stopped every process with SIGINT, as Ctrl-C on
    `ros2 launch` does): every process exited 0 and none printed a Python traceback."""
    import launch_testing.asserts

    launch_testing.asserts.assertExitCodes(proc_info)
    tracebacks = {name: text[text.index("Traceback"):][:2000]
                  for name, text in process_outputs(proc_output).items() if "Traceback" in text}
    assert not tracebacks, "tracebacks in the output of " + "; ".join(f"{n}:\n{t}" for n, t in tracebacks.items())


# ---- the full output of a failed test -----------------------------------------------------------------
def forget_launched_output() -> None:
    """Start afresh (a new test file): what earlier launches and processes printed is not this test's."""
    _launched_output.clear()
    _launched_exit.clear()
    NodeProcess.started.clear()


def launched_output() -> dict[str, str]:
    """Every process the current test file launched or started -> its exit code and full output so far."""
    texts = {}
    for name, parts in _launched_output.items():
        texts[f"{name} (exit code {_launched_exit.get(name, 'none yet')})"] = "".join(parts)
    for n, proc in enumerate(NodeProcess.started, 1):
        texts[f"#{n} {' '.join(proc.args)} (exit code {proc.proc.poll()})"] = proc.output
    return texts


def launch_log_path(test_id: str) -> Path:
    """Where a failed test's launched output goes: $PRISMA_LAUNCH_LOG_DIR, else test-results/launch-logs/
    under the repository root; one file per test, named by its id."""
    folder = Path(os.environ.get(LOG_DIR_VARIABLE) or ROOT / "test-results" / "launch-logs")
    return folder / (re.sub(r"[^A-Za-z0-9_.-]+", "_", test_id).strip("_") + ".log")


def write_launch_log(test_id: str, outputs: dict[str, str]) -> Path:
    """Write `outputs` (title -> text) to launch_log_path(test_id), whole or not at all; its path."""
    path = launch_log_path(test_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, prefix=f".{path.name}.", delete=False) as out:
        out.write(f"{test_id}: the full output of every process it launched or started\n")
        for title, text in outputs.items():
            out.write(f"\n===== {title} =====\n{text}")
    os.chmod(out.name, 0o644)  # NamedTemporaryFile makes it 0600: readable as any other log
    os.replace(out.name, path)
    return path


def failure_note(test_id: str) -> str | None:
    """For a failed test: the launched output written to its file and the line naming the file; None
    when the test launched nothing."""
    texts = launched_output()
    if not texts:
        return None
    path = write_launch_log(test_id, texts)
    return f"the full output of every launched process ({len(texts)}): {path}"
