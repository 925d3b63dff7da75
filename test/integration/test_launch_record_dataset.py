"""launch_testing: a live teleop session recorded and exported as a dataset, on `teleop.launch.py`
(the synthetic glove's operator, the teleop node engaged at start) with `hardware:=sim` and with
`hardware:=emulated` (prisma-hand-emulator's servos and pads, homed at start):

1. once the Teleoperate goal runs, `record.launch.py out:=<bag>` starts (ros2 bag record of
   prisma_dataset's record_topics); it still gets episode 0's start, marked before it started (the
   markers are latched);
2. episode 0 ends by letting go (~/engage false): outcome success (the goal was running);
3. episode 1 is started by the operator's service (~/mark_episode start, task 'hold the ball'), the
   hand engaged again, and ended by the service with outcome failure (or, should the goal end for good
   first on a loaded machine, sensor_stale, by the teleop node: a failure with the goal's reason);
4. the recording stopped (ctrl-C), `prisma-dataset export <bag> --out <dataset>` writes a dataset that
   passes prisma_dataset.dataset_check with 2 episodes, the tasks and outcomes of the markers, each
   episode's frames inside its marked span (at most its length at 50 fps; at least 0.2 s: a stream
   that fell silent longer than its max age on a loaded machine ends an episode early, and the
   export says which).
After the launch is stopped every node exits 0 without a traceback.

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
import unittest
from pathlib import Path

import pytest

from prisma_testing.emulated_launch import wait_until_homed
from prisma_testing.launch_case import GraphTestCase, assert_clean_shutdown, graph_under_test, include_launch
from prisma_testing.node_process import NodeProcess
from prisma_testing.ros_harness import require_ros

require_ros()

import launch_testing  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.msg import EpisodeMarker  # noqa: E402
from prisma_msgs.srv import MarkEpisode  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

import prisma_dataset.bag_export  # noqa: E402,F401  (imported here: the export's timing is the export's own)
from prisma_common.hand import MOTOR_NAMES  # noqa: E402
from prisma_dataset.cli import main as dataset_main  # noqa: E402
from prisma_dataset.dataset_check import check_dataset  # noqa: E402
from prisma_dataset.recorded_topics import EPISODE_TOPIC  # noqa: E402
from prisma_teleop.episodes import DEFAULT_TASK  # noqa: E402

# the same paths in both imports of this module (launch_testing imports it twice)
WORK = Path(tempfile.gettempdir()) / f"prisma_record_dataset_{os.getpid()}"
LATCHED = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
EPISODE_S = 2.0  # each episode's recorded time (at 50 fps: 100 frames)


@pytest.mark.launch_test
@launch_testing.parametrize("hardware", ["sim", "emulated"])
def generate_test_description(hardware):
    WORK.mkdir(exist_ok=True)
    arguments = {"hardware": hardware}
    if hardware == "emulated":
        emulator_dir = WORK / "emulator"
        emulator_dir.mkdir(exist_ok=True)
        arguments["emulator_dir"] = str(emulator_dir)
    return graph_under_test(include_launch("teleop.launch.py", **arguments))


class TestRecordDataset(GraphTestCase):
    @classmethod
    def subscribe(cls, ros) -> None:
        cls.joints = ros.collect(JointState, "/joint_states")
        cls.diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
        cls.markers = ros.collect(EpisodeMarker, EPISODE_TOPIC, LATCHED)

    def goals_started(self) -> int:
        return len(self.ros.logs(name="manipulation", contains="teleop goal started"))

    def test_1_two_marked_episodes_recorded_and_exported(self, hardware):
        ros = self.ros
        if hardware == "emulated":
            wait_until_homed(ros, self.diagnostics, MOTOR_NAMES)
        self.assertTrue(ros.spin_until(lambda: self.goals_started() >= 1, 60.0), ros.logs(name="teleop")[-5:])
        run = WORK / hardware
        shutil.rmtree(run, ignore_errors=True)
        run.mkdir()
        bag, dataset = run / "bag", run / "dataset"
        recorder = NodeProcess(["ros2", "launch", "prisma_bringup", "record.launch.py", f"out:={bag}"])
        try:
            self.assertTrue(recorder.wait_for_output(f"Subscribed to topic '{EPISODE_TOPIC}'", 60.0),
                            recorder.output[-2000:])
            self.assertTrue(recorder.wait_for_output("Subscribed to topic '/joint_states'", 30.0),
                            recorder.output[-2000:])
            ros.spin_for(EPISODE_S)
            let_go = ros.call(SetBool, "/teleop/engage", SetBool.Request(data=False))
            self.assertEqual(let_go.message, "disengaged")
            ros.spin_for(0.5)
            started = ros.call(MarkEpisode, "/teleop/mark_episode",
                               MarkEpisode.Request(event="start", task="hold the ball"))
            self.assertEqual((started.success, started.episode), (True, 1), started.message)
            goals = self.goals_started()
            self.assertEqual(ros.call(SetBool, "/teleop/engage", SetBool.Request(data=True)).message, "engaged")
            self.assertTrue(ros.spin_until(lambda: self.goals_started() > goals, 30.0), ros.logs(name="teleop")[-5:])
            ros.spin_for(EPISODE_S)
            ended = ros.call(MarkEpisode, "/teleop/mark_episode", MarkEpisode.Request(event="end", outcome="failure"))
            if not ended.success:
                # the goal ended for good first (on a loaded machine: sensor_stale, /joint_states late):
                # the teleop node ended the episode itself, a failure with the goal's reason
                self.assertEqual(ended.message, "no episode is open: start one (event 'start', or engage)")
                self.assertTrue(self.markers[-1].reason.startswith("the goal ended "), self.markers[-1])
            ros.spin_for(0.5)
        finally:
            stopped = recorder.interrupt(timeout_sec=30.0)
        self.assertEqual(stopped.returncode, 0, stopped.output[-2000:])
        seen = [(m.episode, m.event, m.outcome) for m in self.markers]
        self.assertEqual(seen, [(0, "start", ""), (0, "end", "success"), (1, "start", ""), (1, "end", "failure")])

        started_s = time.monotonic()
        self.assertEqual(dataset_main(["export", str(bag), "--out", str(dataset)]), 0)
        export_s = time.monotonic() - started_s
        report = check_dataset(dataset)
        self.assertTrue(report.ok, report.problems)
        episodes = report.episodes
        notes = json.loads((dataset / "meta" / "prisma_export.json").read_text())["episodes"]
        print(f"{hardware}: exported in {export_s:.1f} s: " + "; ".join(
            f"episode {e['episode_index']}: {e['length']} frames, {e['tasks']}, {e['outcome']}, ended by "
            f"{n['ended']}" for e, n in zip(episodes, notes)))
        self.assertEqual(report.info["total_episodes"], 2)
        self.assertEqual(report.tasks, [DEFAULT_TASK, "hold the ball"])
        self.assertEqual([(e["tasks"], e["outcome"]) for e in episodes],
                         [([DEFAULT_TASK], "success"), (["hold the ball"], "failure")])
        fps = report.info["fps"]
        stamps = {(m.episode, m.event): m.header.stamp.sec * 1e9 + m.header.stamp.nanosec for m in self.markers}
        for e, (row, note) in enumerate(zip(episodes, notes)):
            span_s = (stamps[(e, "end")] - stamps[(e, "start")]) / 1e9
            if e == 0 or ended.success:  # marked by the test, not ended by a failed goal
                self.assertGreaterEqual(span_s, EPISODE_S, (e, span_s))
            self.assertGreaterEqual(row["length"], fps // 5, (row, note["ended"]))
            self.assertLessEqual(row["length"], span_s * fps + 1, (row, span_s))
            if not note["ended"].startswith("a gap"):
                self.assertEqual(note["ended"], "its end marker")
        self.assertIn("observation.glove_pose", report.info["features"])  # the synthetic glove was recorded


@launch_testing.post_shutdown_test()
class TestRecordDatasetShutdown(unittest.TestCase):
    def test_every_node_exits_0_without_a_traceback(self, proc_info, proc_output):
        assert_clean_shutdown(proc_info, proc_output)
        shutil.rmtree(WORK, ignore_errors=True)
