"""The rclpy side of `prisma-dataset replay`: a node that carries out ReplayCore's steps on a running
hand (replay_plan.py decides, replay_compare.py judges) and records what the hand did. Not a
`*_node.py`: no launch file starts it and it has no parameters; it lives as long as one replay.

Publishes prisma/teleop/motor_targets (sensor_msgs/JointState, freshly stamped, the teleop node's
converter) and keeps one prisma/teleoperate goal (prisma_msgs/action/Teleoperate, the teleop node's
default fields: 0 = the manipulation node's touch limit, speed and input timeout); subscribes
joint_states, prisma/hand/wrench (Fz = the pad's normal force) and prisma/hand/contact, all under
`--namespace`. Refuses (ReplayRefused: one line, exit 2) when no Teleoperate server answers within
the wait and when another node already publishes the targets (a teleop node running: two
publishers would fight over the hand); one that starts publishing them mid-replay stops it.

Imported by cli.py only for `replay`, so export and show run without ROS.
"""
from __future__ import annotations

import time
from typing import Any

import rclpy
from action_msgs.msg import GoalStatus
from prisma_msgs.action import Teleoperate
from prisma_msgs.msg import HandContact, HandWrench
from rclpy.action import ActionClient
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rosidl_runtime_py.utilities import get_action, get_message
from sensor_msgs.msg import JointState

from prisma_common.cli_args import UserError
from prisma_common.messages import robot_types
from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY, try_rt_priority
from prisma_common.topics import TELEOPERATE_ACTION, TELEOP_TARGETS, relative
from prisma_force_estimator.ros_conversions import wrench_from_msg
from prisma_manipulation.ros_conversions import contact_state_from_msg, joint_sample_from_msg
from prisma_teleop.node_config import TeleopConfig
from prisma_teleop.ros_conversions import motor_targets_to_msg, teleoperate_goal_to_msg
from prisma_teleop.teleop_core import TeleopGoal

from .replay_compare import ReplayRecording, Samples
from .replay_plan import STARTING, CancelGoal, Finished, Publish, ReplayCore, SendGoal
from .sampling import NS

TARGETS_TOPIC = relative(TELEOP_TARGETS)
DEPTH = 10
DISCOVERY_SETTLE_S = 1.0  # after the server appeared: the rest of the graph (a teleop node's publisher) too
WATCH_PERIOD_S = 0.5  # how often a replay looks for another publisher of the targets
RESULT_WAIT_S = 5.0  # after the cancel: the goal's result


class ReplayRefused(UserError):
    """No hand to replay into, or one already driven by another publisher of the targets."""


class ReplayNode(Node):
    def __init__(self, core: ReplayCore, namespace: str = "") -> None:
        super().__init__("dataset_replay", namespace=namespace)
        self.core = core
        self.types = robot_types(get_message, get_action)
        # the teleop node's goal fields: 0 = the manipulation node's parameters
        self.goal = teleoperate_goal_to_msg(self.types, TeleopGoal.of(TeleopConfig()))
        self.client = ActionClient(self, Teleoperate, TELEOPERATE_ACTION)
        self.targets_topic = self.resolve_topic_name(TARGETS_TOPIC)
        self.motors = core.episode.motors
        self.recording = ReplayRecording([], Samples(), {f: Samples() for f in core.episode.fingers},
                                         {f: Samples() for f in core.episode.fingers}, "not started", False)
        self.latest_positions: list[float] | None = None
        self.finished: Finished | None = None
        self._handle: Any = None
        self._publisher: Any = None
        self._timer: Any = None
        self.create_subscription(JointState, "joint_states", self._on_joints, DEPTH)
        self.create_subscription(HandWrench, "prisma/hand/wrench", self._on_wrench, DEPTH)
        self.create_subscription(HandContact, "prisma/hand/contact", self._on_contact, DEPTH)

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    # ---- the graph's answers -----------------------------------------------------------------
    def other_target_publishers(self) -> list[str]:
        mine = self.get_fully_qualified_name()
        found = []
        for info in self.get_publishers_info_by_topic(self.targets_topic):
            name = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
            if name != mine:
                found.append(name)
        return found

    def start(self) -> None:
        """Start publishing: the timer at the frame period carries the replay."""
        self._publisher = self.create_publisher(JointState, TARGETS_TOPIC, DEPTH)
        self._timer = self.create_timer(self.core.period_ns / NS, self._on_tick)
        self._watch = self.create_timer(WATCH_PERIOD_S, self._on_watch)

    # ---- recording ---------------------------------------------------------------------------
    def _on_joints(self, msg: JointState) -> None:
        sample = joint_sample_from_msg(msg)
        if all(m in sample.positions for m in self.motors):
            positions = [sample.positions[m] for m in self.motors]
            self.latest_positions = positions
            self.recording.positions.add(sample.stamp_ns, positions)

    def _on_wrench(self, msg: HandWrench) -> None:
        for finger, stamped in zip(msg.fingers, msg.wrenches):
            if finger in self.recording.forces:
                sample = wrench_from_msg(stamped)
                self.recording.forces[finger].add(sample.stamp_ns, sample.wrench[2])

    def _on_contact(self, msg: HandContact) -> None:
        for contact in msg.contacts:
            evaluation = contact_state_from_msg(contact)
            if evaluation.finger in self.recording.contact:
                self.recording.contact[evaluation.finger].add(evaluation.stamp_ns, float(evaluation.feasible))

    # ---- carrying out the core's steps ---------------------------------------------------------
    def _on_tick(self) -> None:
        self._carry_out(self.core.tick(self._now_ns(), self.latest_positions))

    def _on_watch(self) -> None:
        others = self.other_target_publishers()
        if others:
            self._carry_out(self.core.on_other_publisher(sorted(others)))

    def _carry_out(self, steps: list) -> None:
        for step in steps:
            if isinstance(step, Publish):
                self._publisher.publish(motor_targets_to_msg(self.types, step.stamp_ns, step.targets))
            elif isinstance(step, SendGoal):
                self._handle = None
                self.client.send_goal_async(self.goal, feedback_callback=self._on_feedback) \
                    .add_done_callback(self._on_accepted)
            elif isinstance(step, CancelGoal):
                if self._handle is not None:
                    self._handle.cancel_goal_async()
            elif isinstance(step, Finished):
                self.finished = step
                self.recording.ended_ns = self._now_ns()

    def _on_accepted(self, future) -> None:
        handle = future.result()
        if not handle.accepted:  # the manipulation node accepts every goal and aborts those it refuses
            self._carry_out(self.core.on_goal_ended("rejected", self._now_ns()))
            return
        self._handle = handle
        if self.finished is not None:  # the replay stopped while its goal was on its way
            handle.cancel_goal_async()
        handle.get_result_async().add_done_callback(self._on_result)

    def _on_feedback(self, _feedback) -> None:
        # the goal runs once it speaks: one the hand refuses is aborted without a feedback
        self.core.on_goal_running(self._now_ns())

    def _on_result(self, future) -> None:
        wrapped = future.result()
        if wrapped.status == GoalStatus.STATUS_CANCELED:
            reason = "canceled"
        else:
            reason = str(getattr(wrapped.result, "reason", "")) or "aborted"
        self._handle = None
        self._carry_out(self.core.on_goal_ended(reason, self._now_ns()))

    def destroy_node(self) -> None:
        self.client.destroy()  # Node.destroy_node would leave the action client in the graph
        super().destroy_node()


def _spin_until(executor: SingleThreadedExecutor, done, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not done():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=0.02)
    return True


def run_replay(core: ReplayCore, namespace: str = "", wait_s: float = 10.0) -> ReplayRecording:
    """Replay `core`'s episode into the hand under `namespace`; what it published and observed.
    ReplayRefused when no hand answers within `wait_s` or another node publishes the targets."""
    try_rt_priority(CONTROL_PATH_RT_PRIORITY)  # the teleop node's rung, where permitted; its threads inherit it
    rclpy.init()
    node = None
    try:
        node = ReplayNode(core, namespace)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        action = node.resolve_topic_name(TELEOPERATE_ACTION)
        if not _spin_until(executor, node.client.server_is_ready, wait_s):
            raise ReplayRefused(f"no hand answers: no Teleoperate server on {action} within {wait_s:g} s; start the "
                                f"hand (ros2 launch prisma_bringup hand.launch.py) or give its --namespace")
        _spin_until(executor, lambda: False, DISCOVERY_SETTLE_S)
        others = node.other_target_publishers()
        if others:
            raise ReplayRefused(f"{node.targets_topic} already has a publisher ({', '.join(sorted(others))}): a "
                                f"teleop node drives the hand; stop it (or disengage and stop it) before a replay")
        node.start()
        episode_s = core.episode.frames * core.period_ns / NS
        budget = wait_s + core.options.lead_in_timeout_s + episode_s + core.options.tail_s + RESULT_WAIT_S
        if not _spin_until(executor, lambda: node.finished is not None or core.phase not in STARTING, wait_s + 1.0):
            raise ReplayRefused(f"no hand answers: the Teleoperate goal on {action} did not start within {wait_s:g} s")
        _spin_until(executor, lambda: node.finished is not None, budget)
        finished = node.finished or Finished(f"the goal did not end within {RESULT_WAIT_S:g} s of the cancel", False)
        recording = node.recording
        recording.published = list(core.published)
        recording.outcome, recording.played = finished.outcome, finished.played
        recording.skipped = core.skipped
        if core.lead_in_note:
            recording.notes.append(core.lead_in_note)
        return recording
    except ExternalShutdownException:
        raise KeyboardInterrupt from None
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
