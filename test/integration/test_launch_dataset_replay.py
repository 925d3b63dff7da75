"""launch_testing: `prisma-dataset replay` of a recorded pinch episode into `hand.launch.py
hardware:=sim sim_object:=pinch_ball` (issue 41's acceptance), and its refusals. The episode is made
here, as a lab makes one: prisma-sim's teleop session (`--short`), exported `--whole-bag`. The tests
run in order, on one launch:

1. the replay plays the episode to its end and closes on the ball: its report gives every pad's
   force within 0.2 N of the recording at the matched frames and exits 0; this test's own /prisma/hand/wrench
   collection over the replay has thumb and index at the touch limit (2 N, within 0.15 N) and no
   pad above 2 N + 0.15 N;
2. another node publishing prisma/teleop/motor_targets (a teleop node running): exit 2, one line
   naming it, nothing published by the replay;
3. no hand under the namespace given: exit 2, one line;
4. an episode out of range: exit 2, one line naming the dataset's episodes.
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import re
import shutil
import tempfile
import time
import unittest
from pathlib import Path

from prisma_testing.launch_case import (
    GraphTestCase,
    assert_clean_shutdown,
    assert_touch_limited,
    launch_test,
    touch_limit_n,
    touch_limited_peaks,
)
from prisma_testing.node_process import NodeProcess, console_script, run_process
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from prisma_msgs.msg import HandWrench  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import FINGERS  # noqa: E402

FORCE_TOLERANCE_N = 0.2
PAD_ROW = re.compile(r"^\s+(\w+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+\S+$", re.M)


generate_test_description = launch_test("hand.launch.py", hardware="sim", sim_object="pinch_ball")


def replay_command(dataset: Path, *args: str) -> list[str]:
    return [console_script("prisma-dataset"), "replay", str(dataset), *args]


def one_error_line(output: str) -> str:
    lines = [line for line in output.splitlines() if line.startswith("prisma-dataset: error: ")]
    assert len(lines) == 1 and "Traceback" not in output, output
    return lines[0]


class TestDatasetReplay(GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.work = Path(tempfile.mkdtemp(prefix="prisma_dataset_replay_"))
        cls.dataset = cls.work / "dataset"
        # the recorded pinch episode, made while the launch comes up
        sim = run_process([console_script("prisma-sim"), "--scenarios", "teleop", "--short", "--no-plots",
                           "--out", str(cls.work / "sim")], timeout_sec=180.0)
        assert sim.returncode == 0, sim.output
        export = run_process([console_script("prisma-dataset"), "export", str(cls.work / "sim" / "bags" / "teleop"),
                              "--out", str(cls.dataset), "--whole-bag"], timeout_sec=120.0)
        assert export.returncode == 0, export.output
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.wrenches = ros.collect(HandWrench, "/prisma/hand/wrench")

    @classmethod
    def tearDownClass(cls) -> None:
        shutil.rmtree(cls.work, ignore_errors=True)
        super().tearDownClass()

    def run_replay(self, *args: str, timeout_sec: float = 90.0):
        """The replay's exit status and output, this test's collections spinning meanwhile."""
        with NodeProcess(replay_command(self.dataset, *args)) as proc:
            finished = self.ros.spin_until(lambda: proc.proc.poll() is not None, timeout_sec)
            self.assertTrue(finished, f"the replay still ran after {timeout_sec} s:\n{proc.output}")
            return proc.wait(10.0)

    def test_1_the_replay_closes_on_the_ball_as_recorded_within_the_touch_limit(self):
        ros = self.ros
        ros.wait_until_keeping_up(self.joints, self.wrenches, lag_sec=0.05, checks=10, timeout_sec=90.0)
        started_ns = time.time_ns()
        result = self.run_replay("--episode", "0", "--plots", str(self.work / "plots"))
        print(result.output)
        self.assertEqual(result.returncode, 0, result.output)
        # every frame played to the end (a late tick on a loaded machine may pass a frame: counted, at most 5%)
        played = re.search(r"replay of episode 0: (\d+) of (\d+) frames played.*, played every frame\n", result.output)
        self.assertIsNotNone(played, result.output)
        self.assertGreaterEqual(int(played[1]), 0.95 * int(played[2]), result.output)
        self.assertIn("verdict: the replay matches the recording", result.output)
        rows = {m[1]: [float(v) for v in m.groups()[1:]] for m in PAD_ROW.finditer(result.output)}
        self.assertEqual(sorted(rows), sorted(FINGERS), result.output)
        for finger, (max_diff, _mean_diff, _recorded_peak, _replayed_peak) in rows.items():
            self.assertLessEqual(max_diff, FORCE_TOLERANCE_N, finger)
        # the recording pinched the ball at the limit; so does the replay
        for finger in ("thumb", "index"):
            self.assertGreaterEqual(rows[finger][2], touch_limit_n() - 0.1, finger)
        assert_touch_limited({finger: row[3] for finger, row in rows.items()})
        self.assertTrue((self.work / "plots" / "replay_episode_000.png").is_file())
        # this test's own view of the pads over the replay, not the replay's report
        touch_limited_peaks(self.wrenches, started_ns)

    def test_2_another_publisher_of_the_targets_is_refused(self):
        publisher = self.ros.probe.create_publisher(JointState, "/prisma/teleop/motor_targets", 10)
        try:
            result = self.run_replay("--episode", "0", "--no-plots", timeout_sec=60.0)
        finally:
            self.ros.probe.destroy_publisher(publisher)
        self.assertEqual(result.returncode, 2, result.output)
        line = one_error_line(result.output)
        self.assertIn("/prisma/teleop/motor_targets already has a publisher (/", line)
        self.assertIn("a teleop node drives the hand", line)
        self.assertNotIn("replay of episode", result.output)

    def test_3_no_hand_under_the_namespace_is_refused(self):
        result = self.run_replay("--episode", "0", "--namespace", "no_hand_here", "--wait", "2", timeout_sec=60.0)
        self.assertEqual(result.returncode, 2, result.output)
        self.assertIn("no hand answers: no Teleoperate server on /no_hand_here/prisma/teleoperate within 2 s",
                      one_error_line(result.output))

    def test_4_an_episode_out_of_range_is_refused(self):
        result = self.run_replay("--episode", "1", timeout_sec=60.0)
        self.assertEqual(result.returncode, 2, result.output)
        self.assertRegex(one_error_line(result.output), r"--episode 1: the dataset at .* has episodes 0 \.\. 0$")


@launch_testing.post_shutdown_test()
class TestDatasetReplayShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
