"""motor_driver: the hand's three motors (Dynamixel or sim) behind /joint_states (rate_hz),
the MoveMotors action /prisma/motors/move (cancel = stop), the HomeMotors action /prisma/motors/home
(find each motor's zero at its open end stop: a servo's turn count is lost at power-up, and
MoveMotors goals are refused `not_homed` until then) and /diagnostics. The zeros homing finds are
saved in the hand's directory (`hand_config`) and loaded from it at start.

    ros2 run prisma_motor_driver motor_driver --ros-args --params-file config/motor_driver.yaml

position_profile_rpm and position_tolerance can be changed at run time; the other parameters are
read-only (node_config.py says why).
"""
from __future__ import annotations

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from prisma_msgs.action import HomeMotors, MoveMotors
from rclpy.action import ActionServer, CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future
from rosidl_runtime_py.utilities import get_action, get_message
from sensor_msgs.msg import JointState

from prisma_common.diagnostics import diagnostics_to_msg, in_namespace
from prisma_common.hand_config import HandConfig, HandConfigError
from prisma_common.messages import robot_types
from prisma_common.parameters import ParameterError
from prisma_common.topics import HOME_MOTORS_ACTION, MOVE_MOTORS_ACTION
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config
from prisma_node_wiring.node_process import run_node
from prisma_node_wiring.sample_streams import stream_publisher
from prisma_node_wiring.single_instance import AlreadyRunning, refuse_if_running

from .backend import BusError
from .homing_job import HomingResult
from .motor_driver_core import MotorDriverCore, make_bus
from .motor_goals import MoveResult, end_severity
from .node_config import MotorDriverConfig
from .ros_conversions import (
    homing_feedback_to_msg,
    homing_result_to_msg,
    joint_state_to_msg,
    move_feedback_to_msg,
    move_goal_from_msg,
    move_result_to_msg,
)


class MotorDriverNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("motor_driver", **kwargs)
        # one motor driver per bus: a second one would open the same port (AlreadyRunning: exit 1)
        refuse_if_running(self, (MOVE_MOTORS_ACTION, HOME_MOTORS_ACTION))
        # fails here, at start, with the parameter's name and value when one is invalid
        self.config = declare_config(self, MotorDriverConfig)
        self.types = robot_types(get_message, get_action)
        now = self._now_ns()
        # under use_sim_time the clock reads 0 until the first /clock: the sim motors then take their
        # time from the first tick instead of integrating from 0 to the first clock reading
        self.hand = HandConfig(self.config.hand_config) if self.config.hand_config else None
        zeros: dict[str, int] = {}
        if self.hand is not None:
            zeros = self.hand.motor_zeros()  # HandConfigError: exit naming the file and the value
            self.get_logger().info(f"zeros from {self.hand.root}: {zeros or 'none saved yet'}")
        self.core = MotorDriverCore(self.config, bus=make_bus(self.config, start_ns=now or None, zeros=zeros),
                                    start_ns=now, zeros=zeros)
        # the bus opens at the first tick (MotorDriverCore.tick connects), not here: opening arms the
        # servos' Bus Watchdog (bus_watchdog, 100 ms), and the rest of the start (the action servers,
        # the garbage collector's settling, the scheduling) outlasted it on a loaded computer: every
        # emulated start logged "bus watchdog fired" for all three servos. The tick that opens the
        # bus reads the servos at once, and every tick after it feeds the watchdog.
        accept_live_changes(self, MotorDriverConfig, self._reconfigure)

        self._goal = None  # ServerGoalHandle of the running goal
        self._goal_done: Future | None = None
        self._homing = None  # ServerGoalHandle of the running homing
        self._homing_done: Future | None = None
        group = ReentrantCallbackGroup()
        self._joint_pub = stream_publisher(self, JointState, "joint_states")
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # a client keeps its motion alive by re-sending the goal every 0.1 s (manipulation_core.
        # MoveLease): finished goals are dropped after 10 s, not rclpy's 15 min, so the status
        # topic lists about a hundred goals, not thousands
        # every goal is accepted: one that cannot run is aborted at once with the reason in its result
        self._server = ActionServer(self, MoveMotors, MOVE_MOTORS_ACTION, self._execute,
                                    cancel_callback=self._on_cancel, callback_group=group, result_timeout=10)
        self._home_server = ActionServer(self, HomeMotors, HOME_MOTORS_ACTION, self._execute_homing,
                                         cancel_callback=self._on_cancel, callback_group=group)
        self._timer = self.create_timer(1.0 / self.config.rate_hz, self._on_tick, callback_group=group)
        self._diag_timer = self.create_timer(self.config.diagnostics_period, self._on_diagnostics)
        self.get_logger().info(
            f"{self.config.backend} motors {dict(zip(self.config.motor_names, self.config.motor_ids))}, "
            f"/joint_states at {self.config.rate_hz:g} Hz")

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _reconfigure(self, config: MotorDriverConfig) -> None:
        self.config = config
        self.core.reconfigure(config)

    # ---- action ----------------------------------------------------------------------------
    def _on_cancel(self, goal_handle) -> CancelResponse:
        return CancelResponse.ACCEPT

    async def _execute(self, goal_handle):
        goal = move_goal_from_msg(goal_handle.request)
        refusal = self.core.validate(goal, self._now_ns())
        if refusal is not None:
            self.get_logger().warning(f"MoveMotors goal refused: {refusal}")
            goal_handle.abort()
            return move_result_to_msg(self.types, MoveResult(False, [], str(refusal)))
        try:
            outcome = self.core.start(goal, self._now_ns())
        except ValueError as exc:  # validated just above: only a driver bug gets here
            goal_handle.abort()
            return move_result_to_msg(self.types, MoveResult(False, [], f"invalid: {exc}"))
        if outcome.preempted is not None:
            self._finish(outcome.preempted)  # the replaced goal's handle ends in every case
        if outcome.failed is not None:
            goal_handle.abort()
            self.get_logger().error(f"MoveMotors goal failed to start: {outcome.failed.reason}")
            return move_result_to_msg(self.types, outcome.failed)
        self._goal, self._goal_done = goal_handle, Future()
        return await self._goal_done

    async def _execute_homing(self, goal_handle):
        motors = list(goal_handle.request.motors)
        refusal = self.core.validate_homing(motors)
        if refusal is not None:
            self.get_logger().warning(f"HomeMotors goal refused: {refusal}")
            goal_handle.abort()
            return homing_result_to_msg(self.types, HomingResult(False, str(refusal)))
        self.get_logger().info(f"homing {', '.join(motors) or 'every motor'}")
        preempted, done = self.core.start_homing(motors, self._now_ns())
        if preempted is not None:
            self._finish(preempted)
        if done is not None:
            return self._homing_ended(goal_handle, done)
        self._homing, self._homing_done = goal_handle, Future()
        return await self._homing_done

    def _homing_ended(self, handle, result: HomingResult):
        """End a homing (its goal's handle; None: the homing at start, which no client waits for):
        save what it found in the hand's directory, log it, return the result message."""
        if result.zero_ticks and self.hand is not None and self.core.bus.needs_homing:
            try:
                self.get_logger().info(f"zeros saved to {self.hand.save_motor_zeros(result.zeros(), note='homing')}")
            except (HandConfigError, OSError) as exc:
                result.reason += f" (zeros not saved: {exc})"
        found = ", ".join(f"{m} zero {z} ticks after {t:.2f} rad, {c:.0f} mA at the stop" for m, z, t, c in
                          zip(result.motors, result.zero_ticks, result.travel_rad, result.stall_current_ma))
        if result.success:
            self.get_logger().info(f"homing ended: {result.reason}: {found}")
        else:
            self.get_logger().error(f"homing ended: {result.reason}{'; ' + found if found else ''}")
        if handle is not None:
            if result.success:
                handle.succeed()
            elif handle.is_cancel_requested and result.reason.endswith("canceled"):
                handle.canceled()
            else:
                handle.abort()
        return homing_result_to_msg(self.types, result)

    def _finish(self, result: MoveResult) -> None:
        handle, done = self._goal, self._goal_done
        self._goal, self._goal_done = None, None
        if handle is None:
            return
        if result.reason == "canceled":
            handle.canceled()
        elif result.success:
            handle.succeed()
        else:
            handle.abort()
        # rclpy fixes a call site's severity: one call site per severity
        severity = end_severity(result)  # None: routine (a refresh, a stop)
        if severity == "info":
            self.get_logger().info(f"MoveMotors goal ended: {result.reason}")
        elif severity == "warn":
            self.get_logger().warning(f"MoveMotors goal ended: {result.reason}")
        done.set_result(move_result_to_msg(self.types, result))

    # ---- timers ----------------------------------------------------------------------------
    def _on_tick(self) -> None:
        now = self._now_ns()
        if self._goal is not None and self._goal.is_cancel_requested:
            result = self.core.cancel()
            if result is not None:
                self._finish(result)
        if self._homing is not None and self._homing.is_cancel_requested:
            canceled = self.core.cancel_homing()
            if canceled is not None:
                self._end_homing_goal(canceled)
        tick = self.core.tick(now)
        self._log_bus_errors()
        if tick.states is not None:
            self._joint_pub.publish(joint_state_to_msg(self.types, now, tick.states))
        if tick.feedback is not None and self._goal is not None:
            self._goal.publish_feedback(move_feedback_to_msg(self.types, tick.feedback))
        if tick.result is not None:
            self._finish(tick.result)
        if tick.homing_feedback is not None and self._homing is not None:
            self._homing.publish_feedback(homing_feedback_to_msg(self.types, tick.homing_feedback))
        if tick.homing_result is not None:
            self._end_homing_goal(tick.homing_result)

    def _end_homing_goal(self, result: HomingResult) -> None:
        handle, done = self._homing, self._homing_done
        self._homing, self._homing_done = None, None
        message = self._homing_ended(handle, result)
        if done is not None:
            done.set_result(message)

    def _log_bus_errors(self) -> None:
        for error in self.core.take_errors():  # each new bus error once, with the port and OS reason
            self.get_logger().error(f"motor bus: {error}; retrying with backoff")

    def _on_diagnostics(self) -> None:
        statuses = in_namespace(self.core.diagnostics(), self.get_namespace())  # which hand says it
        self._diag_pub.publish(diagnostics_to_msg(self.types, self._now_ns(), statuses))

    def destroy_node(self) -> None:
        core = getattr(self, "core", None)  # absent when the parameters were rejected at start
        torque_off = False
        if core is not None:
            connected = core.connected  # close() turns the torque off only on a connected bus
            try:
                core.close()  # torque off
                torque_off = connected
            except BusError as exc:
                self.get_logger().error(f"closing the motor bus: {exc}")
        logger = rclpy.logging.get_logger(self.get_logger().name)
        for server in (getattr(self, "_server", None), getattr(self, "_home_server", None)):
            if server is not None:
                server.destroy()  # Node.destroy_node leaves action servers (and so the node) alive
        super().destroy_node()
        if torque_off:
            # logged once the node is gone: after ctrl-C the context is shut down and the node's
            # /rosout publisher could only fail ("publisher's context is invalid")
            logger.info(f"torque off: {', '.join(self.config.motor_names)}")


def main(args=None) -> None:
    run_node(MotorDriverNode, "motor_driver", (ParameterError, AlreadyRunning, HandConfigError), args)


if __name__ == "__main__":
    main()
