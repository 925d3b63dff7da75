"""teleop on real rclpy over DDS, against stand-ins for the manipulation node's action servers: the
motor targets of each glove sample with its stamp, the Teleoperate goal kept (sent again after a
refusal for now, cancelled by ~/engage false), the episode markers (engage, let go, ~/mark_episode;
latched for a late subscriber), the captures saved and loaded at the next start, and the STAG
input's Grasp and open goals."""
from __future__ import annotations

import time

import pytest

from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from control_msgs.action import GripperCommand  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from prisma_msgs.action import Grasp, Teleoperate  # noqa: E402
from prisma_msgs.msg import EpisodeMarker, GloveFrame, ObjectEstimate  # noqa: E402
from prisma_msgs.srv import MarkEpisode  # noqa: E402
from rclpy.action import ActionServer, CancelResponse  # noqa: E402
from rclpy.task import Future  # noqa: E402
from rosidl_runtime_py.utilities import get_action, get_message  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from prisma_common.diagnostics import WARN, diagnostics_from_msg  # noqa: E402
from prisma_common.hand import MOTOR_NAMES  # noqa: E402
from prisma_common.messages import make_header, robot_types  # noqa: E402
from prisma_teleop.calibration import CalibrationError, load_calibration  # noqa: E402
from prisma_teleop.retargeting import nominal_calibration  # noqa: E402
from prisma_teleop.ros_conversions import hand_pose_to_msg, open_goal_to_msg  # noqa: E402
from prisma_teleop.synthetic_glove_core import Synergies, hand_pose  # noqa: E402
from prisma_teleop.teleop_node import TeleopNode  # noqa: E402
from prisma_testing.repo_paths import CONFIG  # noqa: E402

PARAMS = CONFIG / "teleop.yaml"
TYPES = robot_types(get_message, get_action)
CAL = nominal_calibration()


class FakeServer:
    """An action server standing in for the manipulation node's: refuses the first `refuse` goals
    `not_ready` at once, keeps the others running until cancelled or `finish`ed."""

    def __init__(self, ros, action_type, name: str, refuse: int = 0) -> None:
        self.action_type, self.refuse = action_type, refuse
        self.goals: list = []
        self.running: list[tuple] = []
        self.server = ActionServer(ros.probe, action_type, name, self._execute,
                                   cancel_callback=lambda handle: CancelResponse.ACCEPT)

    async def _execute(self, handle):
        self.goals.append(handle.request)
        if len(self.goals) <= self.refuse:
            handle.abort()
            return self.result("not_ready: prisma/teleop/motor_targets not received yet")
        done = Future()
        self.running.append((handle, done))
        return await done

    def result(self, reason: str):
        result = self.action_type.Result()
        if hasattr(result, "reason"):
            result.reason = reason
        return result

    def finish(self, reason: str, canceled: bool = False) -> None:
        handle, done = self.running.pop()
        if canceled:
            handle.canceled()
        elif reason == "succeeded":
            handle.succeed()
        else:
            handle.abort()
        done.set_result(self.result(reason))


def publish_glove(ros, command: Synergies, seconds: float, rate_hz: float = 60.0, age_s: float | None = 0.0
                  ) -> list[int]:
    """The operator holding `command` for `seconds` on glove/joint_states, stamped `age_s` before
    it is sent (None: stamped 0); the stamps sent."""
    sent = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        stamp = 0 if age_s is None else ros.now_ns() - int(age_s * 1e9)
        ros.publish("/glove/joint_states", hand_pose_to_msg(TYPES, stamp, hand_pose(command, CAL)))
        sent.append(stamp)
        ros.spin_for(1.0 / rate_hz)
    return sent


def test_targets_per_sample_and_the_teleoperate_goal_kept(ros):
    server = FakeServer(ros, Teleoperate, "/prisma/teleoperate", refuse=1)
    ros.node(TeleopNode, {"engage_at_start": True, "max_pad_force": 1.5}, params_files=[PARAMS])
    targets = ros.collect(JointState, "/prisma/teleop/motor_targets")
    sent = publish_glove(ros, Synergies(1.0, 1.0, 1.0), 1.2)
    assert ros.spin_until(lambda: len(targets) == len(sent), 5.0)
    assert [stamp_ns(m) for m in targets] == sent  # one per sample, its stamp
    last = targets[-1]
    assert list(last.name) == list(MOTOR_NAMES) and list(last.position) == [9.0, 7.0, 1.5]
    assert len(last.velocity) == 0 and len(last.effort) == 0
    # refused not_ready at first (the targets had not reached it), sent again after retry_period 0.5 s
    assert len(server.goals) == 2 and len(server.running) == 1
    assert server.goals[1].max_pad_force == pytest.approx(1.5)
    assert ros.call(SetBool, "/teleop/engage", SetBool.Request(data=False)).message == "disengaged"
    handle, _ = server.running[0]
    assert ros.spin_until(lambda: handle.is_cancel_requested, 5.0)
    server.finish("canceled", canceled=True)
    publish_glove(ros, Synergies(0.0, 0.0, 0.0), 0.3)
    assert len(server.goals) == 2  # disengaged: no new goal
    assert ros.call(SetBool, "/teleop/engage", SetBool.Request(data=True)).message == "engaged"
    publish_glove(ros, Synergies(0.0, 0.0, 0.0), 0.3)
    assert len(server.goals) == 3 and len(server.running) == 1


def test_episodes_marked_by_engaging_letting_go_and_the_service_latched_for_a_late_subscriber(ros):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    server = FakeServer(ros, Teleoperate, "/prisma/teleoperate")
    ros.node(TeleopNode, {"engage_at_start": True, "episode_task": "pinch the ball"}, params_files=[PARAMS])
    publish_glove(ros, Synergies(0.5, 0.5, 0.0), 0.3)
    assert len(server.running) == 1
    # a subscriber joining now (a recorder started late) gets the open episode's start, and only it
    late = ros.collect(EpisodeMarker, "/prisma/teleop/episode", latched)
    assert ros.spin_until(lambda: len(late) == 1, 5.0)
    assert (late[0].episode, late[0].event, late[0].task, late[0].reason) == (0, "start", "pinch the ball", "engaged")
    assert ros.call(SetBool, "/teleop/engage", SetBool.Request(data=False)).message == "disengaged"
    assert ros.spin_until(lambda: len(late) == 2, 5.0)
    assert (late[1].episode, late[1].event, late[1].outcome, late[1].reason) == (
        0, "end", "success", "let go; a goal was running")
    started = ros.call(MarkEpisode, "/teleop/mark_episode", MarkEpisode.Request(event="start", task="lift the card"))
    assert (started.success, started.episode, started.message) == (
        True, 1, "episode 1 started (the operator): lift the card")
    again = ros.call(MarkEpisode, "/teleop/mark_episode", MarkEpisode.Request(event="start"))
    assert (again.success, again.episode) == (False, 1) and "end it first" in again.message
    ended = ros.call(MarkEpisode, "/teleop/mark_episode", MarkEpisode.Request(event="end", outcome="failure"))
    assert (ended.success, ended.episode) == (True, 1)
    assert ros.spin_until(lambda: len(late) == 4, 5.0)
    assert [(m.episode, m.event, m.task, m.outcome) for m in late[2:]] == [
        (1, "start", "lift the card", ""), (1, "end", "lift the card", "failure")]
    assert late[3].header.stamp.sec > 0  # stamped with the node's clock
    server.finish("canceled", canceled=True)


def test_captures_are_saved_and_loaded_at_the_next_start(ros, tmp_path):
    path = tmp_path / "operator.yaml"
    node = ros.node(TeleopNode, {"calibration_file": str(path), "capture_samples": 5}, params_files=[PARAMS])
    capture = {pose: f"/teleop/capture_{pose}" for pose in ("open_hand", "fist", "thumb_adducted", "thumb_opposed")}
    reply = ros.call(Trigger, capture["fist"], Trigger.Request())
    assert not reply.success and reply.message.startswith("no glove sample yet")
    publish_glove(ros, Synergies(0.9, 0.7, 0.0), 0.3)  # a fist that closes less than the nominal one
    reply = ros.call(Trigger, capture["fist"], Trigger.Request())
    assert reply.success and reply.message.endswith("unchanged until open hand, thumb adducted, thumb opposed are "
                                                    "captured too")
    for pose, synergies in (("open_hand", Synergies(0.0, 0.0, 0.0)), ("thumb_adducted", Synergies(0.0, 0.0, -1.0))):
        publish_glove(ros, synergies, 0.3)
        assert ros.call(Trigger, capture[pose], Trigger.Request()).success
    assert not path.exists()  # the nominal hand's thumb opposed is not the operator's: nothing saved yet
    publish_glove(ros, Synergies(0.0, 0.0, 1.0), 0.3)
    reply = ros.call(Trigger, capture["thumb_opposed"], Trigger.Request())
    assert reply.success and reply.message == f"captured thumb opposed (5 samples); calibration in use; saved to {path}"
    saved = load_calibration(path)
    assert saved.operator == "captured"
    assert saved.fist["index_pip"] == pytest.approx(0.9 * CAL.fist["index_pip"])
    assert saved.fist["thumb_ip"] == pytest.approx(0.7 * CAL.fist["thumb_ip"])
    ros.destroy_node(node)
    ros.node(TeleopNode, {"calibration_file": str(path)}, params_files=[PARAMS])
    targets = ros.collect(JointState, "/prisma/teleop/motor_targets")
    publish_glove(ros, Synergies(0.9, 0.7, 0.0), 0.3)
    assert ros.spin_until(lambda: bool(targets), 5.0)
    assert list(targets[-1].position)[:2] == [9.0, 7.0]  # this operator's fist closes the hand fully


def test_a_calibration_file_that_cannot_be_written_is_said_at_start(ros, tmp_path):
    a_file = tmp_path / "not_a_dir"
    a_file.write_text("")
    ros.capture_logs()
    ros.node(TeleopNode, {"calibration_file": str(a_file / "operator.yaml")}, params_files=[PARAMS])
    assert ros.wait_for_log(name="teleop", contains="cannot be written", timeout_sec=5.0)
    assert ros.logs(name="teleop", contains="cannot be written") == [
        f"calibration_file {a_file / 'operator.yaml'} cannot be written: {a_file} is not a directory. Captures will "
        "be in use but NOT saved; give a writable calibration_file"]


def test_a_glove_stamped_0_sends_no_target_and_no_goal_says_so_once_and_on_diagnostics(ros):
    server = FakeServer(ros, Teleoperate, "/prisma/teleoperate")
    ros.capture_logs()
    ros.node(TeleopNode, {"engage_at_start": True}, params_files=[PARAMS])
    targets = ros.collect(JointState, "/prisma/teleop/motor_targets")
    statuses = ros.collect(DiagnosticArray, "/diagnostics")
    publish_glove(ros, Synergies(1.0, 1.0, 0.0), 1.5, age_s=None)
    publish_glove(ros, Synergies(1.0, 1.0, 0.0), 1.0, age_s=5.0)
    assert ros.spin_until(lambda: len(statuses) >= 2, 5.0)
    assert (targets, server.goals) == ([], [])
    refused = ros.logs(name="teleop", contains="/glove/joint_states stamped")
    assert len(refused) == 2 and refused[0] == ("/glove/joint_states stamped 0: publish header.stamp (ros2 topic pub: "
                                                "header: auto); its samples are refused until then")
    status = diagnostics_from_msg(statuses[-1])[0]
    assert (status.name, status.level) == ("teleop", WARN)
    assert status.message.startswith("input refused: /glove/joint_states stamped 5.")
    publish_glove(ros, Synergies(1.0, 1.0, 0.0), 0.5)  # stamped when taken: followed
    assert ros.spin_until(lambda: bool(targets) and bool(server.goals), 5.0)
    assert len(ros.logs(name="teleop", contains="/glove/joint_states accepted again")) == 1


def test_a_bad_calibration_file_fails_at_start_naming_it(ros, tmp_path):
    path = tmp_path / "operator.yaml"
    path.write_text("format: prisma_teleop_calibration\nversion: 1\nopen_hand: {index_mcp: x}\n")
    with pytest.raises(CalibrationError, match=f"{path}: open_hand.index_mcp = 'x' is not a finite angle"):
        ros.node(TeleopNode, {"calibration_file": str(path)}, params_files=[PARAMS])


def glove_frame(stamp: int, pressure: float) -> GloveFrame:
    values = [0.0] * 1024
    values[:100] = [pressure / 100] * 100
    return GloveFrame(header=make_header(TYPES, stamp, "stag_glove"), rows=32, cols=32, raw=[0] * 1024,
                      pressure=values, shorted=False, contact=pressure > 0)


def show_poses(ros, labels: list[str], pressure: float) -> None:
    for label in labels:
        stamp = ros.now_ns()
        ros.publish("/stag/frame", glove_frame(stamp, pressure))
        ros.publish("/stag/hand_pose", ObjectEstimate(header=make_header(TYPES, stamp, "stag_glove"), label=label,
                                                      confidence=0.97, labels=[label], probabilities=[0.97],
                                                      frames_used=1))
        ros.spin_for(0.05)


def test_stag_poses_send_grasps_and_the_empty_hand_opens(ros):
    grasps = FakeServer(ros, Grasp, "/prisma/grasp")
    grippers = FakeServer(ros, GripperCommand, "/prisma/gripper_cmd")
    ros.capture_logs()
    ros.node(TeleopNode, {"input": "stag", "engage_at_start": True}, params_files=[PARAMS])
    show_poses(ros, ["pinch", "power", "pinch", "pinch", "pinch"], pressure=35.0)  # power: one frame, nothing
    assert ros.spin_until(lambda: bool(grasps.goals), 5.0)
    ros.spin_for(0.3)
    (goal,) = grasps.goals
    assert (goal.grasp, goal.finger_force, goal.thumb_force) == ("pinch", pytest.approx(1.2), pytest.approx(1.5))
    grasps.finish("force_reached", canceled=False)
    show_poses(ros, ["hook"] * 3, pressure=1.0)  # a hand pressing nothing holds nothing
    assert ros.spin_until(lambda: bool(grippers.goals), 5.0), ros.logs(name="teleop")
    assert (grippers.goals[0].command.position, grippers.goals[0].command.max_effort) == (0.0, 0.0)
    assert open_goal_to_msg(TYPES) == GripperCommand.Goal()
