"""rclpy.action.client: ActionClient and ClientGoalHandle over the stand-in graph."""
from __future__ import annotations

import copy
import uuid

from action_msgs.msg import GoalInfo, GoalStatus
from action_msgs.srv import CancelGoal
from unique_identifier_msgs.msg import UUID
from ros_standin.messages import convert as _convert

from ..task import Future


class ClientGoalHandle:
    def __init__(self, action_client: "ActionClient", goal_id, goal_response) -> None:
        self._action_client = action_client
        self._goal_id = goal_id
        self._goal_response = goal_response
        self._status = GoalStatus.STATUS_UNKNOWN

    def __eq__(self, other):
        return isinstance(other, ClientGoalHandle) and bytes(self._goal_id.uuid) == bytes(other._goal_id.uuid)

    def __hash__(self):
        return hash(bytes(self._goal_id.uuid))

    def __repr__(self):
        return f"ClientGoalHandle <id={list(self.goal_id.uuid)}, accepted={self.accepted}, status={self.status}>"

    @property
    def goal_id(self):
        return self._goal_id

    @property
    def stamp(self):
        return self._goal_response.stamp

    @property
    def accepted(self) -> bool:
        return self._goal_response.accepted

    @property
    def status(self) -> int:
        return self._status

    def cancel_goal_async(self) -> Future:
        if not self.accepted:
            raise TypeError("Cannot cancel goal that was not accepted")
        return self._action_client._cancel_goal_async(self)

    def get_result_async(self) -> Future:
        if not self.accepted:
            raise TypeError("Cannot get result for goal that was not accepted")
        return self._action_client._get_result_async(self)

    def cancel_goal(self):
        raise RuntimeError("cancel_goal() blocks; use cancel_goal_async() and spin in stand-in tests")

    def get_result(self):
        raise RuntimeError("get_result() blocks; use get_result_async() and spin in stand-in tests")


class ActionClient:
    def __init__(self, node, action_type, action_name: str, *, callback_group=None,
                 goal_service_qos_profile=None, result_service_qos_profile=None,
                 cancel_service_qos_profile=None, feedback_sub_qos_profile=None,
                 status_sub_qos_profile=None) -> None:
        self._node = node
        self._action_type = action_type
        self._action_name = node.resolve_topic_name(action_name)
        self.callback_group = callback_group or node.default_callback_group
        self._feedback_callbacks: dict[bytes, object] = {}
        self._goal_handles: dict[bytes, ClientGoalHandle] = {}
        node.add_waitable(self)
        node.context.graph.action_clients.append(self)

    @property
    def action_name(self) -> str:
        return self._action_name

    @staticmethod
    def _uuid_msg(goal_uuid: bytes):
        return UUID(uuid=list(goal_uuid))

    def _server(self):
        for server in self._node.context.graph.action_servers:
            if (server._action_name == self._action_name
                    and server._action_type.Goal.__msgtype__ == self._action_type.Goal.__msgtype__):
                return server
        return None

    def server_is_ready(self) -> bool:
        return self._server() is not None

    def wait_for_server(self, timeout_sec: float | None = None) -> bool:
        return self.server_is_ready()

    def _post(self, run, label: str) -> None:
        self._node.context.post(self._node, run, label)

    # -- goals --------------------------------------------------------------------------------------

    def send_goal_async(self, goal, feedback_callback=None, goal_uuid=None) -> Future:
        """Request a goal; the Future gives a ClientGoalHandle once both nodes were spun."""
        if getattr(goal, "__msgtype__", None) != self._action_type.Goal.__msgtype__:
            raise TypeError(f"Expected goal of type {self._action_type.Goal}, got {type(goal)}")
        if goal_uuid is None:
            goal_uuid = self._node.context.next_sequence().to_bytes(8, "big") + uuid.uuid4().bytes[:8]
        elif not isinstance(goal_uuid, bytes):
            goal_uuid = bytes(bytearray(goal_uuid.uuid if hasattr(goal_uuid, "uuid") else goal_uuid))
        future = Future()
        if feedback_callback is not None:
            self._feedback_callbacks[goal_uuid] = feedback_callback
        goal = _convert(goal)
        server = self._server()
        if server is None:
            return future  # like a request nobody answers

        def respond(accepted: bool, stamp) -> None:
            response = self._action_type.Impl.SendGoalService.Response(accepted=accepted)
            if stamp is not None:
                response.stamp = copy.deepcopy(stamp)
            self._post(lambda: self._deliver_goal_response(goal_uuid, response, future),
                       f"goal response on {self._action_name}")

        self._node.context.post(server._node, lambda: server._handle_goal_request(self, goal_uuid, goal, respond),
                                f"goal request on {self._action_name}")
        return future

    def send_goal(self, goal, feedback_callback=None, goal_uuid=None):
        raise RuntimeError("send_goal() blocks; use send_goal_async() and spin in stand-in tests")

    def _deliver_goal_response(self, goal_uuid: bytes, response, future: Future) -> bool:
        if future.done():
            return False
        handle = ClientGoalHandle(self, self._uuid_msg(goal_uuid), response)
        if response.accepted:
            handle._status = GoalStatus.STATUS_ACCEPTED
            self._goal_handles[goal_uuid] = handle
        else:
            self._feedback_callbacks.pop(goal_uuid, None)
        future.set_result(handle)
        return True

    def _get_result_async(self, goal_handle: ClientGoalHandle) -> Future:
        future = Future()
        goal_uuid = bytes(goal_handle.goal_id.uuid)
        server = self._server()
        if server is None:
            return future

        def respond(response) -> None:
            self._post(lambda: self._deliver_result(goal_uuid, response, future),
                       f"result on {self._action_name}")

        self._node.context.post(server._node, lambda: server._handle_result_request(goal_uuid, respond),
                                f"result request on {self._action_name}")
        return future

    def _deliver_result(self, goal_uuid: bytes, response, future: Future) -> bool:
        if future.done():
            return False
        handle = self._goal_handles.get(goal_uuid)
        if handle is not None:
            handle._status = response.status
        self._feedback_callbacks.pop(goal_uuid, None)
        future.set_result(response)
        return True

    def _cancel_goal_async(self, goal_handle: ClientGoalHandle) -> Future:
        future = Future()
        goal_uuid = bytes(goal_handle.goal_id.uuid)
        server = self._server()
        if server is None:
            return future

        def respond(response) -> None:
            self._post(lambda: (future.set_result(response), True)[1] if not future.done() else False,
                       f"cancel response on {self._action_name}")

        self._node.context.post(server._node, lambda: server._handle_cancel_request(goal_uuid, respond),
                                f"cancel request on {self._action_name}")
        return future

    # -- topics from the server -----------------------------------------------------------------------

    def _post_feedback(self, message) -> None:
        goal_uuid = bytes(message.goal_id.uuid)
        if goal_uuid not in self._feedback_callbacks:
            return

        def run() -> bool:
            callback = self._feedback_callbacks.get(goal_uuid)
            if callback is None:
                return False
            self._node._run_callback(callback, message)
            return True

        self._post(run, f"feedback on {self._action_name}")

    def _post_status(self, goal_uuid: bytes, status: int) -> None:
        def run() -> bool:
            handle = self._goal_handles.get(goal_uuid)
            if handle is None:
                return False
            handle._status = status
            return True

        self._post(run, f"status on {self._action_name}")

    def destroy(self) -> None:
        graph = self._node.context.graph
        if self in graph.action_clients:
            graph.action_clients.remove(self)
        self._node.remove_waitable(self)
