"""A test's hands and eyes on another host: a RosHarness in a process of its own, started inside a
network namespace (two_hosts.Host.run), driven over its stdin/stdout one JSON line at a time.

    probe = HostProbe(hosts.workstation.run, env)            # the test's side
    probe.call("collect", topic="/left/joint_states", type="sensor_msgs/msg/JointState")
    goal = probe.call("send_goal", action="/left/prisma/grasp", type="prisma_msgs/action/Grasp",
                      goal={"grasp": "pinch"})               # re-sent while refused for now; {"id", "accepted_ns"}
    probe.call("result", id=goal["id"])                      # {"status": "SUCCEEDED", "result": {...}}
    probe.close()

Requests (`op` and its fields) and what each answers:
- collect(topic, type): start keeping every message of the topic (read back by `stamped`, for
  messages with a header, and `goals`, for an action's status);
- goals(topic, since_ns): [[accepted_ns, last status]] of the goals an action's status topic (collected,
  type action_msgs/msg/GoalStatusArray) listed, accepted after since_ns;
- stamped(topic, since_ns, until_ns): {"messages": [[stamp_ns, fields...]]} of the messages stamped
  after since_ns (JointState: [stamp, velocities, positions], with "names"; DiagnosticArray: [stamp,
  [[name, hardware_id], ...]]; others: [stamp, frame_id, finger (its `finger` field, or "")]), once
  one stamped at or after until_ns (if given) has been received;
- keeping_up(leader, follower, lag_s, checks, timeout_s): answers once the follower topic's newest
  stamp stays within lag_s of the leader's (both collected), an error at the timeout;
- send_goal(action, type, goal, retry_s, wait_s): the goal sent, again while the server refuses it
  not_ready (the graph coming up: up to retry_s); {"id", "accepted_ns" (the server's GoalInfo stamp)} or
  {"accepted": false, "refused"};
- result(id, timeout_s): {"status": SUCCEEDED|ABORTED|CANCELED|..., "result": the result's fields};
- trigger(service, timeout_s): a std_srvs/Trigger call; {"success", "message"};
- set_parameters(node, values): the node's parameters set, as `ros2 param set` does; {"results":
  [[successful, reason], ...]} in the order of `values`;
- logs(name, contains): /rosout messages so far of that logger containing the text;
- ping: {} once the process runs.
An answer that failed is {"error": "..."}. The probe spins its executor between requests (woken by
a message or a request), so collections keep filling while the test does other things.
"""
from __future__ import annotations

import json
import os
import queue
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from prisma_testing.json_line_process import JsonLineProcess

# the longest one wait of the probe's idle loop lasts: a request or a message ends it sooner
IDLE_SPIN_SEC = 1.0


class HostProbe(JsonLineProcess):
    """The test's end: starts the probe (through `run`, e.g. Host.run) and sends it requests (`call`:
    RuntimeError with the probe's output when one fails)."""

    def __init__(self, run: Callable[[Sequence[str]], list[str]], env: dict[str, str] | None = None,
                 start_timeout_s: float = 60.0, rt_priority: int = 0) -> None:
        """rt_priority > 0: the probe runs at that SCHED_FIFO priority where the system permits it (an
        instrument above a graph at real-time priority that fills the machine still sees in time)."""
        full_env = {**os.environ, "PYTHONUNBUFFERED": "1", "RCUTILS_COLORIZED_OUTPUT": "0", **(env or {})}
        argv = [sys.executable, "-m", "prisma_testing.host_probe"]
        if rt_priority > 0:
            argv += ["--rt-priority", str(rt_priority)]
        super().__init__(run(argv), "host probe", full_env)
        self.call("ping", timeout_s=start_timeout_s)


# ---- the probe's end: runs inside the host --------------------------------------------------------
class _Probe:
    def __init__(self) -> None:
        from prisma_testing.ros_harness import RosHarness

        self.ros = RosHarness()
        self.ros.capture_logs()
        self.collected: dict[str, list] = {}
        self.pending: dict[int, Any] = {}
        self.clients: dict[str, Any] = {}

    def collect(self, topic: str, type: str) -> dict:
        from rosidl_runtime_py.utilities import get_message

        if topic not in self.collected:
            self.collected[topic] = self.ros.collect(get_message(type), topic)
        return {}

    def stop_collecting(self, topic: str) -> dict:
        """Stop taking `topic` (and forget what was taken): a probe at real-time priority that
        keeps taking 100 Hz topics nobody reads any more takes that CPU from the graph it observes."""
        self.ros.stop_collecting(self.collected.pop(topic))
        return {}

    def stamped(self, topic: str, since_ns: int = 0, until_ns: int = 0, wait_s: float = 10.0) -> dict:
        from prisma_testing.ros_harness import stamp_ns

        # a probe held up by a busy machine works through its queue first: up to a message stamped at
        # or after until_ns (one that was published by the time the test asked)
        received = self.collected[topic]
        if until_ns and not self.ros.spin_until(lambda: received and stamp_ns(received[-1]) >= until_ns, wait_s):
            return {"error": f"{topic}: no message stamped after {until_ns} within {wait_s} s"}
        rows, names = [], []
        for msg in reversed(self.collected[topic]):
            stamp = stamp_ns(msg)
            if stamp <= since_ns:
                break
            if hasattr(msg, "velocity"):
                names = list(msg.name)
                rows.append([stamp, list(msg.velocity), list(msg.position)])
            elif hasattr(msg, "status"):  # diagnostic_msgs/DiagnosticArray: who reported
                rows.append([stamp, [[status.name, status.hardware_id] for status in msg.status]])
            else:
                rows.append([stamp, msg.header.frame_id, getattr(msg, "finger", "")])
        return {"messages": rows[::-1], "names": names}

    def keeping_up(self, leader: str, follower: str, lag_s: float, checks: int = 10, timeout_s: float = 90.0) -> dict:
        """Once the newest stamp of `follower` is within lag_s of `leader`'s at `checks` checks in a
        row (both collected): a downstream node has warmed up (RosHarness.wait_until_keeping_up)."""
        self.ros.wait_until_keeping_up(self.collected[leader], self.collected[follower], lag_s, checks, timeout_s)
        return {}

    def goals(self, topic: str, since_ns: int = 0) -> dict:
        """The goals an action server's status topic (collected) listed as accepted after since_ns:
        [[accepted_ns, last status]], by acceptance."""
        from prisma_testing.goals import goal_status_name

        goals: dict[bytes, list] = {}
        for msg in self.collected[topic]:
            for s in msg.status_list:
                stamp = s.goal_info.stamp.sec * 1_000_000_000 + s.goal_info.stamp.nanosec
                if stamp > since_ns:
                    goals.setdefault(bytes(s.goal_info.goal_id.uuid), [stamp, 0])[1] = goal_status_name(s.status)
        return {"goals": sorted(goals.values())}

    def send_goal(self, action: str, type: str, goal: dict, retry_s: float = 60.0, wait_s: float = 60.0) -> dict:
        from rosidl_runtime_py.set_message import set_message_fields
        from rosidl_runtime_py.utilities import get_action

        action_type = get_action(type)
        if action not in self.clients:
            self.clients[action] = self.ros.action_client(action_type, action, wait_sec=wait_s)
        message = action_type.Goal()
        set_message_fields(message, goal)
        try:
            # the hand's servers accept every goal and abort one they cannot run yet with not_ready
            handle = self.ros.send_until_started(self.clients[action], message, timeout_sec=retry_s)
        except AssertionError as refused:
            return {"accepted": False, "refused": str(refused)}
        goal_id = len(self.pending) + 1
        self.pending[goal_id] = handle.get_result_async()
        return {"accepted": True, "id": goal_id,
                "accepted_ns": handle.stamp.sec * 1_000_000_000 + handle.stamp.nanosec}

    def result(self, id: int, timeout_s: float = 60.0) -> dict:
        from rosidl_runtime_py.convert import message_to_ordereddict

        from prisma_testing.goals import goal_status_name

        future = self.pending[id]
        if not self.ros.spin_until(future, timeout_s):
            return {"error": f"goal {id}: no result within {timeout_s} s"}
        response = future.result()
        return {"status": goal_status_name(response.status),
                "result": dict(message_to_ordereddict(response.result)), "received_ns": time.time_ns()}

    def trigger(self, service: str, timeout_s: float = 10.0) -> dict:
        from std_srvs.srv import Trigger

        answer = self.ros.call(Trigger, service, Trigger.Request(), timeout_sec=timeout_s)
        return {"success": answer.success, "message": answer.message}

    def set_parameters(self, node: str, values: dict[str, Any]) -> dict:
        return {"results": [[r.successful, r.reason] for r in self.ros.set_parameters(node, **values)]}

    def logs(self, name: str | None = None, contains: str | None = None) -> dict:
        return {"logs": self.ros.logs(name=name, contains=contains)}

    def ping(self) -> dict:
        return {}

    def serve(self) -> None:
        """Answer the requests on stdin until it closes. Between requests the executor waits for
        what the collections take (or a request): polling stdin every few milliseconds instead
        kept an idle probe at 10% of a core, at real-time priority above the graph it observes."""
        requests: queue.SimpleQueue = queue.SimpleQueue()
        wake = self.ros.probe.create_guard_condition(lambda: None)

        def read_requests() -> None:
            for line in sys.stdin:
                requests.put(line)
                wake.trigger()
            requests.put(None)  # the test closed our input: done
            wake.trigger()

        threading.Thread(target=read_requests, name="requests", daemon=True).start()
        while True:
            self.ros.spin_once(timeout_sec=IDLE_SPIN_SEC)
            while not requests.empty():
                line = requests.get()
                if line is None:
                    return
                sys.stdout.write(json.dumps(self._answer(json.loads(line))) + "\n")
                sys.stdout.flush()

    def _answer(self, request: dict) -> dict:
        op = request.pop("op")
        try:
            return getattr(self, op)(**request) if op in _OPS else {"error": f"unknown op {op!r}"}
        except Exception as exc:  # the test shows it: the probe keeps serving
            return {"error": f"{type(exc).__name__}: {exc}"}


_OPS = ("collect", "stop_collecting", "stamped", "keeping_up", "goals", "send_goal", "result", "trigger",
        "set_parameters", "logs", "ping")


def main() -> None:
    if sys.argv[1:2] == ["--rt-priority"]:
        try:  # before rclpy starts its threads: they inherit it
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(sys.argv[2])))
        except OSError as exc:
            print(f"host probe: real-time priority {sys.argv[2]} refused ({exc}): default priority", file=sys.stderr)
    probe = _Probe()
    try:
        probe.serve()
    finally:
        probe.ros.shutdown()


if __name__ == "__main__":
    main()
