"""teleop: a glove drives the hand through the manipulation node (teleop_core.py decides, this node
carries it out).

    ros2 run prisma_teleop teleop --ros-args --params-file config/teleop.yaml -p engage_at_start:=true
    ros2 run prisma_teleop teleop --ros-args --params-file config/teleop.yaml -p input:=stag

input joint_states: subscribes glove/joint_states (a hand-pose glove's sensor_msgs/JointState;
remap it to the glove's topic), publishes prisma/teleop/motor_targets (sensor_msgs/JointState: the
three motors' targets in rad, stamped with the glove sample's stamp) for every sample, and while
engaged keeps a prisma/teleoperate goal (prisma_msgs/action/Teleoperate) running on the manipulation
node, which follows the targets touch-limited. Services ~/capture_open_hand, ~/capture_fist,
~/capture_thumb_adducted, ~/capture_thumb_opposed (std_srvs/Trigger) take the glove's pose as the
operator's calibration, in use and saved to calibration_file once complete.
input stag: subscribes stag/hand_pose (prisma_msgs/ObjectEstimate) and stag/frame (GloveFrame, for
the total pressure) and sends prisma/grasp goals for held poses and a prisma/gripper_cmd goal at
position 0 for the empty hand.
Both: ~/engage (std_srvs/SetBool) engages (true) or disengages (false, cancelling the running goal);
parameter engage_at_start. Episodes (episodes.py): engaging starts one with the task of parameter
episode_task, letting go (or the Teleoperate goal ending for good) ends it with its outcome;
~/mark_episode (prisma_msgs/srv/MarkEpisode) starts one with a task or ends the open one with the
operator's outcome. Each start and end goes out on prisma/teleop/episode
(prisma_msgs/msg/EpisodeMarker; reliable, transient_local, depth 1: a recorder started later still
gets the open episode's start). A sample whose header stamp is 0, ahead of this node's clock or
older than max_input_age on arrival is refused (nothing moves on it), logged once per episode.
/diagnostics every second: status `teleop` (engaged, the input's rate and age, a refusal and why,
the last goal's end, the episode open and the last one, the calibration in use). Every parameter
is described (node_config.py); the deadband, the stamp
limits, the goals' fields and the STAG hysteresis and forces change at run time.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from action_msgs.msg import GoalStatus
from control_msgs.action import GripperCommand
from diagnostic_msgs.msg import DiagnosticArray
from prisma_msgs.action import Grasp, Teleoperate
from prisma_msgs.msg import EpisodeMarker as EpisodeMarkerMsg
from prisma_msgs.msg import GloveFrame, ObjectEstimate
from prisma_msgs.srv import MarkEpisode
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosidl_runtime_py.utilities import get_action, get_message
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.messages import ns_from_stamp, robot_types
from prisma_common.parameters import ParameterError
from prisma_common.topics import GRASP_ACTION, GRIPPER_ACTION, TELEOPERATE_ACTION, TELEOP_TARGETS, relative
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import stream_publisher, stream_subscription
from stag_glove.ros_conversions import estimate_from_msg

from .calibration import POSES, CalibrationError, load_calibration, save_calibration, unwritable
from .episodes import EpisodeMarker
from .node_config import TeleopConfig
from .retargeting import nominal_calibration
from .ros_conversions import (
    episode_marker_to_msg,
    grasp_goal_to_msg,
    hand_pose_from_msg,
    motor_targets_to_msg,
    open_goal_to_msg,
    pressure_total_from_msg,
    teleoperate_goal_to_msg,
)
from .stag_poses import GraspCommand, OpenCommand
from .teleop_core import CancelGoal, HandPoseTeleop, Note, SendGoal, StagTeleop, describe

ACTIONS = {"teleoperate": (Teleoperate, TELEOPERATE_ACTION), "grasp": (Grasp, GRASP_ACTION),
           "open": (GripperCommand, GRIPPER_ACTION)}
EPISODE_TOPIC = "prisma/teleop/episode"
# depth 1: a subscriber joining late (a recorder) gets the last marker only, the open episode's start
# while one is open; reliable: no marker is lost to a busy subscriber (they come seconds apart)
EPISODE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TeleopNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("teleop", **kwargs)
        # fails here, at start, with the parameter's name and value when one is invalid
        self.config = config = declare_config(self, TeleopConfig)
        self.types = robot_types(get_message, get_action)
        self._seq = 0  # increments with every goal sent: a late answer to an older one is dropped
        self._handle: Any = None  # ClientGoalHandle of the goal running
        self._cancel_on_arrival = False
        self.core: HandPoseTeleop | StagTeleop
        if config.input == "joint_states":
            calibration, loaded = self._calibration()
            glove = self.resolve_topic_name("glove/joint_states")
            self.core = HandPoseTeleop(config, calibration, captured=loaded, input_topic=glove)
            self._targets = stream_publisher(self, JointState, relative(TELEOP_TARGETS))
            stream_subscription(self, JointState, "glove/joint_states", self._on_hand_pose)
            for pose in POSES:
                self.create_service(Trigger, f"~/capture_{pose}",
                                    lambda request, response, pose=pose: self._on_capture(pose, response))
            kinds: tuple[str, ...] = ("teleoperate",)
            started = (f"input joint_states: glove/joint_states -> prisma/teleop/motor_targets, filter delay "
                       f"{self.core.filter.delay_s * 1e3:.1f} ms, calibration {self.core.calibration.operator!r}")
        else:
            self.core = StagTeleop(config, self.resolve_topic_name("stag/hand_pose"),
                                   self.resolve_topic_name("tactile_driver/replace_object"))
            self.create_subscription(GloveFrame, "stag/frame", self._on_glove_frame, 10)
            self.create_subscription(ObjectEstimate, "stag/hand_pose", self._on_pose, 10)
            kinds = ("grasp", "open")
            started = "input stag: stag/hand_pose and stag/frame -> prisma/grasp, prisma/gripper_cmd"
        self._goal_clients = {kind: ActionClient(self, *ACTIONS[kind]) for kind in kinds}
        self.create_service(SetBool, "~/engage", self._on_engage)
        self._episode_pub = self.create_publisher(EpisodeMarkerMsg, EPISODE_TOPIC, EPISODE_QOS)
        self.create_service(MarkEpisode, "~/mark_episode", self._on_mark_episode)
        # every input sample and goal end looks at the goal to keep (a retry is sent with the first
        # sample after retry_period); the status timer once a second looks too (a wake-up of rclpy's
        # executor per sample would cost more than the sample's own work: bench/bench_teleop.py)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._diag_timer = self.create_timer(1.0, self._on_status)
        accept_live_changes(self, TeleopConfig, self._reconfigure)
        self.get_logger().info(f"{started}; {'engaged' if self.core.engaged else 'disengaged (~/engage)'}")
        if config.input == "joint_states" and config.calibration_file:
            why = unwritable(config.calibration_file)
            if why is not None:
                self.get_logger().warning(f"calibration_file {config.calibration_file} cannot be written: {why}. "
                                          "Captures will be in use but NOT saved; give a writable calibration_file")
        self._carry_out(self.core.begin(self._now_ns()))  # engaged at start: the first episode starts now

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _calibration(self):
        """(the calibration to start with, whether it is the operator's own from calibration_file)."""
        path = self.config.calibration_file
        if path and Path(path).expanduser().is_file():
            return load_calibration(path), True  # CalibrationError naming file, value and what to do: exit 1
        if path:
            self.get_logger().info(f"no calibration at {path} yet: the nominal hand until the operator has captured "
                                   "all four poses")
        return nominal_calibration(self.config.joint_groups()), False

    def _reconfigure(self, config: TeleopConfig) -> None:
        self.config = config
        self.core.reconfigure(config)

    # ---- input -----------------------------------------------------------------------------
    def _on_hand_pose(self, msg: JointState) -> None:
        assert isinstance(self.core, HandPoseTeleop)
        try:
            stamp_ns, angles = hand_pose_from_msg(msg)
        except ValueError as exc:
            self.get_logger().warning(f"glove/joint_states: {exc}; sample ignored", throttle_duration_sec=5.0)
            return
        targets, actions = self.core.on_sample(stamp_ns, angles, self._now_ns())
        if targets is not None:  # before the goal the sample may start: the targets flow first
            self._targets.publish(motor_targets_to_msg(self.types, stamp_ns, targets))
        self._carry_out(actions)

    def _on_glove_frame(self, msg: GloveFrame) -> None:
        assert isinstance(self.core, StagTeleop)
        self.core.on_frame(*pressure_total_from_msg(msg))

    def _on_pose(self, msg: ObjectEstimate) -> None:
        assert isinstance(self.core, StagTeleop)
        estimate = estimate_from_msg(msg)
        self._carry_out(self.core.on_pose(ns_from_stamp(msg.header.stamp), estimate.label, estimate.confidence,
                                          self._now_ns()))

    def _on_status(self) -> None:
        now = self._now_ns()
        self._carry_out(self.core.tick(now))  # a goal the rate limit held back, with no sample coming
        statuses = in_namespace([self.core.diagnostics(now)], self.get_namespace())
        self._diag_pub.publish(diagnostics_to_msg(self.types, now, statuses))

    # ---- services --------------------------------------------------------------------------
    def _on_engage(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        message, actions = self.core.engage(bool(request.data), self._now_ns())
        self._carry_out(actions)
        response.success, response.message = True, message
        return response

    def _on_mark_episode(self, request: MarkEpisode.Request, response: MarkEpisode.Response) -> MarkEpisode.Response:
        done, message, episode, actions = self.core.mark_episode(request.event, self._now_ns(), request.task,
                                                                 request.outcome)
        if not done:
            self.get_logger().warning(f"~/mark_episode refused: {message}")
        self._carry_out(actions)
        response.success, response.message, response.episode = done, message, episode
        return response

    def _on_capture(self, pose: str, response: Trigger.Response) -> Trigger.Response:
        assert isinstance(self.core, HandPoseTeleop)
        ok, message, complete = self.core.capture(pose)
        if complete is not None and self.config.calibration_file:
            try:
                message += f"; saved to {save_calibration(complete, self.config.calibration_file)}"
            except CalibrationError as exc:
                message += f"; NOT saved: {exc}"
        self.get_logger().info(f"~/capture_{pose}: {message}")
        response.success, response.message = ok, message
        return response

    # ---- carrying out the core's decisions -------------------------------------------------
    def _carry_out(self, actions: list) -> None:
        for action in actions:
            if isinstance(action, SendGoal):
                self._send(action.command)
            elif isinstance(action, CancelGoal):
                self._cancel(action.why)
            elif isinstance(action, Note):
                self._log(action)
            elif isinstance(action, EpisodeMarker):
                self._episode_pub.publish(episode_marker_to_msg(self.types, action))
                self.get_logger().info(action.describe())

    def _log(self, note: Note) -> None:
        # rclpy fixes a call site's severity at its first call: one call site per severity
        if note.level == "error":
            self.get_logger().error(note.text)
        elif note.level == "warning" and note.throttled:
            self.get_logger().warning(note.text, throttle_duration_sec=2.0)
        elif note.level == "warning":
            self.get_logger().warning(note.text)
        else:
            self.get_logger().info(note.text)

    def _goal(self, command) -> tuple[str, Any]:
        if isinstance(command, GraspCommand):
            return "grasp", grasp_goal_to_msg(self.types, command, self.config.grasp_speed_rpm)
        if isinstance(command, OpenCommand):
            return "open", open_goal_to_msg(self.types)
        return "teleoperate", teleoperate_goal_to_msg(self.types, command)

    def _send(self, command) -> None:
        kind, goal = self._goal(command)
        client = self._goal_clients[kind]
        if not client.server_is_ready():
            name = ACTIONS[kind][1]
            self._carry_out(self.core.on_goal_ended(f"not_ready: no action server {name} (is the manipulation "
                                                    "node running?)", False, self._now_ns()))
            return
        self._seq += 1
        self._handle, self._cancel_on_arrival = None, False
        self.get_logger().info(f"sending {describe(command)}")
        future = client.send_goal_async(goal)
        future.add_done_callback(lambda f, seq=self._seq: self._on_accepted(f, seq))

    def _on_accepted(self, future, seq: int) -> None:
        if seq != self._seq:
            return
        handle = future.result()
        if not handle.accepted:  # the manipulation node accepts every goal and aborts those it refuses
            self._carry_out(self.core.on_goal_ended("rejected", False, self._now_ns()))
            return
        self._handle = handle
        if self._cancel_on_arrival:
            handle.cancel_goal_async()
        handle.get_result_async().add_done_callback(lambda f, seq=seq: self._on_result(f, seq))

    def _on_result(self, future, seq: int) -> None:
        if seq != self._seq:
            return
        self._handle = None
        wrapped = future.result()
        status, result = wrapped.status, wrapped.result
        if status == GoalStatus.STATUS_CANCELED:
            reason = "canceled"
        else:
            reason = getattr(result, "reason", "") or ("succeeded" if status == GoalStatus.STATUS_SUCCEEDED
                                                       else "aborted")
        success = status in (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED)
        self.get_logger().info(f"goal ended: {reason}")
        self._carry_out(self.core.on_goal_ended(reason, success, self._now_ns()))

    def _cancel(self, why: str) -> None:
        self.get_logger().info(f"cancelling the running goal: {why}")
        if self._handle is None:
            self._cancel_on_arrival = True  # still on its way: cancelled when accepted
        else:
            self._handle.cancel_goal_async()

    def destroy_node(self) -> None:
        # Node.destroy_node would leave the action clients (and so the node) in the graph
        for client in getattr(self, "_goal_clients", {}).values():
            client.destroy()
        super().destroy_node()


def main(args=None) -> None:
    run_node(TeleopNode, "teleop", (ParameterError, CalibrationError), args)


if __name__ == "__main__":
    main()
