"""rclpy.action.server: ActionServer and ServerGoalHandle over the stand-in graph.

Protocol steps travel through the context's work FIFO like the real services and topics do:
goal request -> (server node spun) goal_callback -> goal response (client node spun);
accepted goals go to handle_accepted_callback, whose default calls goal_handle.execute(), which
runs execute_callback as a task of the server node's executor. An async execute_callback may
`await` Futures that other callbacks complete; a plain one runs to its end in one step.
"""
from __future__ import annotations

import copy
import inspect
from enum import Enum

from action_msgs.msg import GoalInfo, GoalStatus
from action_msgs.srv import CancelGoal
from ros_standin import clock as _test_clock
from ros_standin.messages import convert as _convert

from .._rclpy_pybind11 import RCLError
from ..task import Future
from ..time import Time


class GoalResponse(Enum):
    REJECT = 1
    ACCEPT = 2


class CancelResponse(Enum):
    REJECT = 1
    ACCEPT = 2


class GoalEvent(Enum):
    EXECUTE = 0
    CANCEL_GOAL = 1
    SUCCEED = 2
    ABORT = 3
    CANCELED = 4


_TRANSITIONS = {
    (GoalStatus.STATUS_ACCEPTED, GoalEvent.EXECUTE): GoalStatus.STATUS_EXECUTING,
    (GoalStatus.STATUS_ACCEPTED, GoalEvent.CANCEL_GOAL): GoalStatus.STATUS_CANCELING,
    (GoalStatus.STATUS_EXECUTING, GoalEvent.CANCEL_GOAL): GoalStatus.STATUS_CANCELING,
    (GoalStatus.STATUS_EXECUTING, GoalEvent.SUCCEED): GoalStatus.STATUS_SUCCEEDED,
    (GoalStatus.STATUS_EXECUTING, GoalEvent.ABORT): GoalStatus.STATUS_ABORTED,
    (GoalStatus.STATUS_CANCELING, GoalEvent.SUCCEED): GoalStatus.STATUS_SUCCEEDED,
    (GoalStatus.STATUS_CANCELING, GoalEvent.ABORT): GoalStatus.STATUS_ABORTED,
    (GoalStatus.STATUS_CANCELING, GoalEvent.CANCELED): GoalStatus.STATUS_CANCELED,
}
_ACTIVE = (GoalStatus.STATUS_ACCEPTED, GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_CANCELING)


def default_goal_callback(goal_request):
    return GoalResponse.ACCEPT


def default_handle_accepted_callback(goal_handle):
    goal_handle.execute()


def default_cancel_callback(cancel_request):
    return CancelResponse.REJECT


class ServerGoalHandle:
    def __init__(self, action_server: "ActionServer", goal_info, goal_request) -> None:
        self._action_server = action_server
        self._goal_info = goal_info
        self._goal_request = goal_request
        self._status = GoalStatus.STATUS_ACCEPTED
        self._result_future = Future()
        self._destroyed = False

    def __eq__(self, other):
        return isinstance(other, ServerGoalHandle) and bytes(self.goal_id.uuid) == bytes(other.goal_id.uuid)

    def __hash__(self):
        return hash(bytes(self.goal_id.uuid))

    @property
    def request(self):
        return self._goal_request

    @property
    def goal_id(self):
        return self._goal_info.goal_id

    @property
    def is_active(self) -> bool:
        return self._status in _ACTIVE

    @property
    def is_cancel_requested(self) -> bool:
        return self._status == GoalStatus.STATUS_CANCELING

    @property
    def status(self) -> int:
        return self._status

    def _update_state(self, event: GoalEvent) -> None:
        new_status = _TRANSITIONS.get((self._status, event))
        if new_status is None:
            raise RCLError(
                f"Failed to update goal state: goal_handle attempted invalid transition from state "
                f"{self._status} with event {event.name}")
        self._status = new_status
        self._action_server._publish_status(self)

    def execute(self, execute_callback=None) -> None:
        # A goal canceled before it started keeps CANCELING; the callback still runs to handle it.
        if not self.is_cancel_requested:
            self._update_state(GoalEvent.EXECUTE)
        self._action_server._notify_execute(self, execute_callback)

    def publish_feedback(self, feedback) -> None:
        feedback_type = self._action_server._action_type.Feedback
        if getattr(feedback, "__msgtype__", None) != feedback_type.__msgtype__:
            raise TypeError(f"Expected feedback of type {feedback_type}, got {type(feedback)}")
        if not self.is_active:
            raise RCLError("Failed to publish feedback: goal is not active")
        message = self._action_server._action_type.Impl.FeedbackMessage(
            goal_id=copy.deepcopy(self.goal_id), feedback=_convert(feedback))
        self._action_server._publish_feedback(message)

    def succeed(self) -> None:
        self._update_state(GoalEvent.SUCCEED)

    def abort(self) -> None:
        self._update_state(GoalEvent.ABORT)

    def canceled(self) -> None:
        self._update_state(GoalEvent.CANCELED)

    def destroy(self) -> None:
        self._destroyed = True


class ActionServer:
    def __init__(self, node, action_type, action_name: str, execute_callback, *, callback_group=None,
                 goal_callback=default_goal_callback,
                 handle_accepted_callback=default_handle_accepted_callback,
                 cancel_callback=default_cancel_callback, goal_service_qos_profile=None,
                 result_service_qos_profile=None, cancel_service_qos_profile=None,
                 feedback_pub_qos_profile=None, status_pub_qos_profile=None, result_timeout=900) -> None:
        self._node = node
        self._action_type = action_type
        self._action_name = node.resolve_topic_name(action_name)
        self._execute_callback = execute_callback
        self._goal_callback = goal_callback
        self._handle_accepted_callback = handle_accepted_callback
        self._cancel_callback = cancel_callback
        self.callback_group = callback_group or node.default_callback_group
        self._goal_handles: dict[bytes, ServerGoalHandle] = {}
        self._result_waiters: dict[bytes, list] = {}
        self._results: dict[bytes, object] = {}
        node.add_waitable(self)
        node.context.graph.action_servers.append(self)

    @property
    def action_name(self) -> str:
        return self._action_name

    @property
    def action_type(self):
        return self._action_type

    def register_handle_accepted_callback(self, handle_accepted_callback) -> None:
        self._handle_accepted_callback = handle_accepted_callback or default_handle_accepted_callback

    def register_goal_callback(self, goal_callback) -> None:
        self._goal_callback = goal_callback or default_goal_callback

    def register_cancel_callback(self, cancel_callback) -> None:
        self._cancel_callback = cancel_callback or default_cancel_callback

    def register_execute_callback(self, execute_callback) -> None:
        self._execute_callback = execute_callback

    def _alive(self) -> bool:
        return self in self._node.context.graph.action_servers

    def _clients(self):
        return [c for c in self._node.context.graph.action_clients if c._action_name == self._action_name]

    # -- protocol handlers (run when the server node is spun) ---------------------------------------

    def _handle_goal_request(self, client, goal_uuid: bytes, goal, respond) -> bool:
        if not self._alive():
            return False
        if goal_uuid in self._goal_handles:
            self._node.get_logger().warning("Received goal request with an existing goal ID; rejected")
            respond(False, None)
            return True
        response = self._goal_callback(goal)
        if not isinstance(response, GoalResponse):
            raise TypeError(f"goal_callback must return a GoalResponse, got {response!r}")
        if response != GoalResponse.ACCEPT:
            respond(False, None)
            return True
        stamp = Time(nanoseconds=_test_clock.now_ns()).to_msg()
        goal_info = GoalInfo(goal_id=client._uuid_msg(goal_uuid), stamp=stamp)
        goal_handle = ServerGoalHandle(self, goal_info, goal)
        self._goal_handles[goal_uuid] = goal_handle
        respond(True, stamp)
        self._publish_status(goal_handle)
        self._handle_accepted_callback(goal_handle)
        return True

    def _notify_execute(self, goal_handle: ServerGoalHandle, execute_callback) -> None:
        callback = execute_callback or self._execute_callback
        executor = self._node.executor
        if executor is None:
            raise RuntimeError("Failed to execute goal: the action server's node has no executor")
        executor.create_task(self._execute_goal, callback, goal_handle)

    async def _execute_goal(self, execute_callback, goal_handle: ServerGoalHandle):
        goal_uuid = bytes(goal_handle.goal_id.uuid)
        try:
            result = execute_callback(goal_handle)
            if inspect.iscoroutine(result):
                result = await result
        except Exception as exc:  # noqa: BLE001 - rclpy logs it and aborts the goal
            result = self._action_type.Result()
            self._node.get_logger().error(f"Error raised in execute callback: {exc!r}")
        if goal_handle.is_active:
            self._node.get_logger().warning(
                f"Goal state not set, assuming aborted. Goal ID: {list(goal_handle.goal_id.uuid)}")
            goal_handle.abort()
        # rclpy fails here too (the result field's setter asserts the type), out of the spin call.
        assert getattr(result, "__msgtype__", None) == self._action_type.Result.__msgtype__, (
            f"execute callback of {self._action_name} returned {result!r}, "
            f"expected a {self._action_type.Result.__msgtype__}")
        response = self._action_type.Impl.GetResultService.Response(
            status=goal_handle.status, result=_convert(result))
        self._results[goal_uuid] = response
        for respond in self._result_waiters.pop(goal_uuid, []):
            respond(_convert(response))

    def _handle_result_request(self, goal_uuid: bytes, respond) -> bool:
        if not self._alive():
            return False
        if goal_uuid not in self._goal_handles:
            respond(self._action_type.Impl.GetResultService.Response(status=GoalStatus.STATUS_UNKNOWN))
        elif goal_uuid in self._results:
            respond(_convert(self._results[goal_uuid]))
        else:
            self._result_waiters.setdefault(goal_uuid, []).append(respond)
        return True

    def _handle_cancel_request(self, goal_uuid: bytes, respond) -> bool:
        if not self._alive():
            return False
        response = CancelGoal.Response()
        goal_handle = self._goal_handles.get(goal_uuid)
        if goal_handle is None:
            response.return_code = CancelGoal.Response.ERROR_UNKNOWN_GOAL_ID
        elif not goal_handle.is_active:
            response.return_code = CancelGoal.Response.ERROR_GOAL_TERMINATED
        elif goal_handle.is_cancel_requested:
            response.goals_canceling = [copy.deepcopy(goal_handle._goal_info)]
        else:
            decision = self._cancel_callback(goal_handle)
            if decision == CancelResponse.ACCEPT:
                goal_handle._update_state(GoalEvent.CANCEL_GOAL)
                response.goals_canceling = [copy.deepcopy(goal_handle._goal_info)]
            else:
                response.return_code = CancelGoal.Response.ERROR_REJECTED
        respond(response)
        return True

    # -- outgoing traffic ----------------------------------------------------------------------------

    def _publish_feedback(self, message) -> None:
        for client in self._clients():
            client._post_feedback(_convert(message))

    def _publish_status(self, goal_handle: ServerGoalHandle) -> None:
        goal_uuid = bytes(goal_handle.goal_id.uuid)
        for client in self._clients():
            client._post_status(goal_uuid, goal_handle.status)

    def destroy(self) -> None:
        graph = self._node.context.graph
        if self in graph.action_servers:
            graph.action_servers.remove(self)
        self._node.remove_waitable(self)
