"""manipulation: Algorithm 1 on every fingertip sample (/prisma/<finger>/contact, also when idle),
one action server per goal kind (goal_kinds.GOAL_KINDS: Grasp on /prisma/grasp, Manipulate
on /prisma/manipulate, control_msgs GripperCommand on /prisma/gripper_cmd, Teleoperate on
/prisma/teleoperate following /prisma/teleop/motor_targets), one goal at a time across them, a
client of /prisma/motors/move, and the 100 ms sensor watchdog (checking every watchdog_period while
a goal runs; an idle node's timer is cancelled).

    ros2 run prisma_manipulation manipulation --ros-args --params-file config/manipulation.yaml

Subscribes /prisma/hand/taxels and /prisma/hand/wrench (Fz = normal force), or the per-finger
/prisma/<finger>/taxels and /prisma/<finger>/wrench until those speak, and /joint_states; publishes
each sample's ContactState on /prisma/<finger>/contact (while subscribed) and those of each received
scan together on /prisma/hand/contact.
k, min_mean_voltage, stale_timeout, the goal defaults and the gripper settings can be changed at run
time (`ros2 param set /manipulation k 0.7`); the other parameters are read-only (node_config.py says
why). Every goal is accepted; one the core refuses (beyond the limits, another goal running, a stream
it needs not flowing, the MoveMotors server down, a manipulation without contact) is aborted at once
with `<code>: <why>` as its result's reason (GripperCommand's result has no text: the log says it,
once per episode, and /diagnostics `manipulation: goals`, the last goal's kind, end and reason).
Motion goals sent to the motor driver expire after 0.3 s unless re-sent, so the motors stop when
this node dies (docs/manipulation.md, "Safety").
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from prisma_msgs.action import MoveMotors
from prisma_msgs.msg import ContactState, HandContact, HandTaxels, HandWrench, TaxelArray
from rclpy.action import ActionClient, ActionServer, CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future
from rosidl_runtime_py.utilities import get_action, get_message
from sensor_msgs.msg import JointState

from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.messages import ns_from_stamp, robot_types
from prisma_common.parameters import ParameterError
from prisma_common.sample_stamps import StampNews
from prisma_force_estimator.ros_conversions import hand_wrench_samples
from prisma_motor_driver.ros_conversions import move_goal_to_msg, move_result_from_msg, velocity_goal
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import FingerAndHandInput, stream_publisher, stream_subscription
from prisma_node_wiring.single_instance import AlreadyRunning, refuse_if_running
from prisma_tactile_driver.ros_conversions import hand_taxels_samples

from .controllers import TIMEOUT
from .goal_ends import CANCELED, REFUSED, SUCCEEDED, GoalEnd, GoalEnds
from .goal_kind import GoalKind, InputStream
from .goal_kinds import GOAL_KINDS
from .manipulation_core import (
    ActionHandlers,
    Feedback,
    Finished,
    GoalRefused,
    Ignored,
    ManipulationCore,
    SendMove,
)
from .node_config import ManipulationConfig
from .ros_conversions import (
    contact_state_to_msg,
    hand_contact_to_msg,
    joint_sample_from_msg,
    normal_force_from_wrench,
)

# finished goals kept a minute for their results, not rclpy's 15: each status change sends every kept goal to
# each client, and longer arrays slowed a soak's goals (docs/performance.md "Soak")
RESULT_TIMEOUT_S = 60
# a goal's result waits until the MoveMotors goal it stopped has ended on the motor driver, so that a
# client's next command finds the motors free (not `busy`, held by the ending goal); at most this
# long: a motor driver that does not answer (the link down) has stopped them by the goal's lease
RELEASE_WAIT_S = 0.5
DIAGNOSTICS_PERIOD_S = 1.0


class ManipulationNode(Node):
    def __init__(self, kinds: tuple[GoalKind, ...] = GOAL_KINDS, **kwargs) -> None:
        """`kinds`: the goal kinds it serves (a test adds one to GOAL_KINDS)."""
        super().__init__("manipulation", **kwargs)
        # one controller per hand: a second would start every goal too and send MoveMotors for it
        refuse_if_running(self, tuple(kind.action for kind in kinds))  # AlreadyRunning: exit 1
        # fails here, at start, with the parameter's name and value when one is invalid
        self.config = declare_config(self, ManipulationConfig)
        self.core = ManipulationCore(self.config, kinds)
        self.types = robot_types(get_message, get_action)
        accept_live_changes(self, ManipulationConfig, self._reconfigure)

        self._goal = None  # ServerGoalHandle of the running goal (any kind)
        self._goal_done: Future | None = None
        self._move_handle = None  # ClientGoalHandle of our current MoveMotors goal
        self._move_result: Future | None = None  # its result's future
        self._releasing: Future | None = None  # the result of the MoveMotors goal last stopped
        self._move_seq = 0  # increments with every MoveMotors goal we send or stop
        self._handlers = ActionHandlers(send_move=self._send_move, stop_motors=lambda _: self._stop_motors(),
                                        feedback=self._publish_feedback, finished=self._finish,
                                        ignored=self._log_ignored, stamp_news=self._log_stamp_news)
        group = ReentrantCallbackGroup()

        self._contact_pubs = {f: stream_publisher(self, ContactState, f"prisma/{f}/contact")
                              for f in self.config.fingers}
        self._hand_contact_pub = stream_publisher(self, HandContact, "prisma/hand/contact")
        self._contacts: list = []  # ContactState of the taxel message being handled, for /prisma/hand/contact
        self._taxels = FingerAndHandInput(self, TaxelArray, HandTaxels, "taxels", self.config.fingers,
                                          hand_taxels_samples, self._on_taxels, self._publish_contacts,
                                          callback_group=group)
        self._wrenches = FingerAndHandInput(self, WrenchStamped, HandWrench, "wrench", self.config.fingers,
                                            hand_wrench_samples, self._on_wrench, callback_group=group)
        stream_subscription(self, JointState, "joint_states", self._on_joints, callback_group=group)
        self._move_client = ActionClient(self, MoveMotors, self.config.move_action, callback_group=group)
        self._kinds = {kind.name: kind for kind in kinds}
        # a kind's extra inputs (none for grasp, manipulate, gripper): fed to the core like the sensors
        for kind in kinds:
            for spec in kind.inputs:
                stream_subscription(self, get_message(spec.msg_type), spec.topic, self._input_callback(spec),
                                    callback_group=group)
        # one server per kind, each on the generic path; every goal is accepted (rclpy's default goal
        # callback): _execute aborts a refused one at once
        self._servers = [ActionServer(self, get_action(kind.action_type), kind.action, self._executor(kind),
                                      cancel_callback=self._on_cancel, callback_group=group,
                                      result_timeout=RESULT_TIMEOUT_S) for kind in kinds]
        self._watchdog = self.create_timer(self.config.watchdog_period, self._on_watchdog, callback_group=group)
        # it ticks only while a goal runs (idle, the core's check has nothing to watch): the idle node
        # is not woken watchdog_period^-1 times a second for nothing, beside the control path
        self._watchdog.cancel()
        # each goal's end, on /diagnostics at once and every second (`manipulation: goals`), and which
        # ends the log shows: a kind without a result text logs a failure once per episode
        self.goal_ends = GoalEnds(frozenset(k.name for k in kinds if not k.result_has_text))
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._diag_timer = self.create_timer(DIAGNOSTICS_PERIOD_S, self._publish_diagnostics)
        self.get_logger().info(f"k={self.config.k}, fingers {', '.join(self.config.fingers)}, "
                               f"stale after {self.config.stale_timeout * 1e3:.0f} ms")

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    # ---- parameters ------------------------------------------------------------------------
    def _reconfigure(self, config: ManipulationConfig) -> None:
        self.config = config
        self.core.reconfigure(config)

    # ---- sensor input ----------------------------------------------------------------------
    def _on_taxels(self, finger: str, msg: TaxelArray) -> None:
        evaluation, actions = self.core.on_taxels(finger, ns_from_stamp(msg.header.stamp),
                                                  np.asarray(msg.voltages, dtype=np.float32), self._now_ns())
        # a ContactState costs ~9 us to build; on the launched graph nobody reads them until rqt_plot
        # or a recorder starts, so it is built only for a subscriber of either form
        finger_pub = self._contact_pubs[finger]
        alone = finger_pub.get_subscription_count() > 0
        together = self._hand_contact_pub.get_subscription_count() > 0
        if alone or together:
            contact = contact_state_to_msg(self.types, evaluation, self.config.frame_id_format.format(finger=finger))
            if alone:
                finger_pub.publish(contact)
            if together:
                self._contacts.append(contact)
        self._apply(actions)

    def _publish_contacts(self) -> None:
        """The ContactStates of the taxel message just handled, together (collected only while
        /prisma/hand/contact has a subscriber)."""
        if self._contacts:
            self._hand_contact_pub.publish(hand_contact_to_msg(self.types, self._contacts))
            self._contacts = []

    def _on_wrench(self, finger: str, msg: WrenchStamped) -> None:
        stamp_ns, fz = normal_force_from_wrench(msg)
        self._apply(self.core.on_wrench(finger, stamp_ns, fz, self._now_ns()))

    def _input_callback(self, spec: InputStream) -> Callable[[Any], None]:
        def on_input(msg: Any) -> None:
            stamp_ns, value = spec.from_msg(msg)
            self._apply(self.core.on_input(spec.stream, stamp_ns, value, self._now_ns()))
        return on_input

    def _on_joints(self, msg: JointState) -> None:
        self._apply(self.core.on_joints(joint_sample_from_msg(msg), self._now_ns()))

    def _on_watchdog(self) -> None:
        now = self._now_ns()
        if self._goal is not None and self._goal.is_cancel_requested:
            self._apply(self.core.cancel(now))
        self._apply(self.core.check(now))
        if self._goal is None and not self.core.busy:
            self._watchdog.cancel()  # until the next goal starts it (_execute)

    # ---- goals -----------------------------------------------------------------------------
    def _on_cancel(self, goal_handle) -> CancelResponse:
        return CancelResponse.ACCEPT

    def _executor(self, kind: GoalKind):
        """The execute callback of `kind`'s action server."""
        async def execute(goal_handle):
            return await self._execute(kind, goal_handle)
        return execute

    async def _execute(self, kind: GoalKind, goal_handle):
        request = kind.request_from_msg(goal_handle.request)
        now = self._now_ns()
        refusal = self.core.accept(request, self._move_client.server_is_ready(), now)
        if refusal is None:
            try:
                actions = self.core.start(request, now)
            except GoalRefused as exc:
                refusal = exc.refusal
        if refusal is not None:
            if self._goal_ended(GoalEnd(kind.name, REFUSED, str(refusal), goal_id(goal_handle))):
                self.get_logger().warning(f"{kind.label} goal refused: {refusal}")
            goal_handle.abort()
            return kind.result_to_msg(self.types, self.core.refused(kind.name, refusal))
        # with "goal ended" below, the log shows which goals overlapped and which came one after another
        self.get_logger().info(f"{kind.name} goal started: {request}")
        done = self._goal_done = Future()
        self._goal = goal_handle
        self._watchdog.reset()  # its first check one watchdog_period from now
        self._apply(actions)  # may end it at once (a gripper already at its position)
        return await done

    # ---- carrying out the core's decisions -------------------------------------------------
    def _apply(self, actions: list) -> None:
        self._handlers.carry_out(actions)

    def _publish_feedback(self, action: Feedback) -> None:
        if self._goal is not None:
            self._goal.publish_feedback(self._kinds[action.kind].feedback_to_msg(self.types, action))

    def _log_ignored(self, action: Ignored) -> None:
        self.get_logger().warning(f"ignoring {action.topic}: {action.reason}", throttle_duration_sec=10.0)

    def _log_stamp_news(self, action: StampNews) -> None:
        """A stream refused by its stamps, or accepted again: once each."""
        if action.level == "warning":
            self.get_logger().warning(action.text)
        else:
            self.get_logger().info(action.text)

    def _send_move(self, action: SendMove) -> None:
        self._move_seq += 1
        seq = self._move_seq
        # stamped with when its data arrived (SendMove): the lease counts from there, so a goal a dropped
        # link delivers late is refused; named: the motor driver serves one controller at a time and
        # says which one holds the motors
        goal = move_goal_to_msg(self.types, velocity_goal(action.velocities_rpm, action.timeout_s, action.stamp_ns,
                                                          self.get_fully_qualified_name()))
        future = self._move_client.send_goal_async(goal)
        future.add_done_callback(lambda f, s=seq: self._on_move_accepted(f, s))

    def _on_move_accepted(self, future, seq: int) -> None:
        handle = future.result()
        if seq != self._move_seq:
            # a newer command or a stop came while this one was on its way: it must not keep running
            # (if a newer goal already replaced it on the motor driver, the cancel is simply refused),
            # and its rejection (the motor driver refuses one delivered after its lease) ends nothing
            if handle.accepted:
                handle.cancel_goal_async()
            return
        if not handle.accepted:
            self.get_logger().error("MoveMotors goal rejected by the motor driver")
            self._apply(self.core.on_move_result("motor_fault: MoveMotors goal rejected", self._now_ns()))
            return
        self._move_handle = handle
        self._move_result = handle.get_result_async()
        self._move_result.add_done_callback(lambda f, s=seq: self._on_move_result(f, s))

    def _on_move_result(self, future, seq: int) -> None:
        if seq != self._move_seq:
            return  # preempted by our own newer goal (a refresh or a new command)
        self._move_handle = self._move_result = None
        result = move_result_from_msg(future.result().result)
        if result.reason == TIMEOUT and self.core.busy:
            self.get_logger().warning("MoveMotors goal expired before its refresh (the motors stopped): re-sending")
        self._apply(self.core.on_move_result(result.reason, self._now_ns()))

    def _stop_motors(self) -> None:
        self._move_seq += 1  # an answer still on its way is cancelled on arrival
        if self._move_handle is not None:
            self._move_handle.cancel_goal_async()
            self._releasing = self._move_result
            self._move_handle = self._move_result = None

    def _finish(self, done: Finished) -> None:
        handle, future = self._goal, self._goal_done
        self._goal, self._goal_done = None, None
        if handle is None:
            return
        releasing, self._releasing = self._releasing, None
        if releasing is None or releasing.done():
            self._report(done, handle, future)
            return
        reported: list[bool] = []

        def report_once() -> None:
            if not reported:
                reported.append(True)
                timer.cancel()
                self.destroy_timer(timer)
                self._report(done, handle, future)

        timer = self.create_timer(RELEASE_WAIT_S, report_once)
        releasing.add_done_callback(lambda _: report_once())

    def _report(self, done: Finished, handle: Any, future: Future) -> None:
        """The goal's end to its client (as its kind ends it), and the log line."""
        kind = self._kinds[done.kind]
        end = kind.outcome(done)
        if end == CANCELED:
            handle.canceled()
        elif end == SUCCEEDED:
            handle.succeed()
        else:
            handle.abort()
        reason = f"{done.reason}: {done.detail}" if done.detail else done.reason
        message = f"{done.kind} goal ended: {done.reason}" + (f" ({done.detail})" if done.detail else "")
        # rclpy fixes a call site's severity at its first call: one call site per severity
        if self._goal_ended(GoalEnd(done.kind, end, reason, goal_id(handle))):
            if done.success:
                self.get_logger().info(message)
            else:
                self.get_logger().warning(message)
        future.set_result(kind.result_to_msg(self.types, done))

    def _goal_ended(self, end: GoalEnd) -> bool:
        """Record a goal's end, on /diagnostics at once; whether the log shows it."""
        logged = self.goal_ends.ended(end)
        self._publish_diagnostics()
        return logged

    def _publish_diagnostics(self) -> None:
        stamps = self.core.stamp_status()  # once a stream was refused by its stamps
        statuses = in_namespace([self.goal_ends.status()] + ([stamps] if stamps else []), self.get_namespace())
        self._diag_pub.publish(diagnostics_to_msg(self.types, self._now_ns(), statuses))

    def destroy_node(self) -> None:
        # Node.destroy_node leaves action servers and clients (and so the node) in the graph
        # absent when the parameters were rejected at start
        for action in [*getattr(self, "_servers", []), getattr(self, "_move_client", None)]:
            if action is not None:
                action.destroy()
        super().destroy_node()


def goal_id(goal_handle: Any) -> str:
    """A goal's id as hex, for /diagnostics."""
    return bytes(goal_handle.goal_id.uuid).hex()


def main(args=None) -> None:
    run_node(ManipulationNode, "manipulation", (ParameterError, AlreadyRunning), args)


if __name__ == "__main__":
    main()
